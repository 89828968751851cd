"""Options of the learning environments: action type, step period, observation sizes, reward weights.

Every option is validated when an environment is built; bad values are one-line ``ConfigError``s
naming the scenario file and the option (``hover.yaml: env.action_type: ...``).
"""

from __future__ import annotations

import enum
from typing import Annotated, Any, Mapping

import pydantic
from pydantic import Field

from pybullet_swarm.validation import validate


class ActionType(str, enum.Enum):
    """What an agent's action commands."""

    VELOCITY = "velocity"  # (vx, vy, vz) m/s set-point through the reference shaper and the cascade
    WAYPOINT = "waypoint"  # (x, y, z) m target position through the reference shaper and the cascade
    ROTOR_SPEED = "rotor_speed"  # (w0, w1, w2, w3) rad/s, open loop: the designed controller is bypassed

    def __str__(self) -> str:
        return self.value


class StepPeriod(str, enum.Enum):
    """How much simulated time one environment step covers."""

    PLANNER = "planner"  # one planner period (1 / sim.planner_hz), what the swarm planners use
    CONTROL = "control"  # one position-loop period (1 / sim.control_hz)
    PHYSICS = "physics"  # one physics step (1 / sim.physics_hz)

    def __str__(self) -> str:
        return self.value


class _Options(pydantic.BaseModel):
    model_config = pydantic.ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


Weight = Annotated[float, Field(ge=0.0, le=1e6)]


class RewardWeights(_Options):
    """Weights of the reward terms (all >= 0; penalties are subtracted).

    Task progress is shared by every agent (the swarm solves the task together); collision and
    crash penalties go to the agents involved.
    """

    box_placed: Weight = 10.0  # per box that fills a slot (a box knocked out of its slot costs as much)
    box_to_goal: Weight = 1.0  # per m the total box-to-goal distance shrinks (optimal box-slot matching)
    goal_progress: Weight = 1.0  # per m an agent gets closer to its active set-point (waypoint tasks)
    point_visited: Weight = 1.0  # per tour point visited
    completion: Weight = 10.0  # once, when the task is completed
    collision_penalty: Weight = 1.0  # per contact event (onset) the agent is part of
    crash_penalty: Weight = 10.0  # to the agent that crashed (hard ground impact, flip) or diverged
    time_penalty: Weight = 0.0  # per simulated second, every agent


class EnvConfig(_Options):
    """Options of ``SwarmParallelEnv`` and the single-agent environments.

    Attributes:
        action_type: velocity set-points (default), waypoints, or raw rotor speeds.
        period: simulated time of one environment step (default: the planner period; the control
            period for rotor-speed actions).
        normalize_actions: actions in [-1, 1] (float32), mapped onto the physical ranges; False:
            actions in SI units (float64), passed through unchanged (exact set-points).
        neighbours: k nearest neighbours within the sensing radius in each observation.
        boxes: nearest visible free boxes in each observation (construction tasks).
        slots: nearest visible open slots in each observation (construction tasks).
        points: nearest unvisited tour points in each observation (tour tasks).
        velocity_scale: m/s, velocity range per axis when the scenario sets no velocity limit.
        rotor_span: normalised rotor action a maps to w_hover * (1 + rotor_span * a).
        waypoint_ceiling: m, top of the waypoint range (default: the arena height, else 2 m).
        record: keep the time series (needed for the flight metrics at the episode end).
        render_size: (width, height) px of ``render()`` frames.
        rewards: reward weights.
    """

    action_type: Annotated[ActionType, Field(strict=False)] = ActionType.VELOCITY
    period: Annotated[StepPeriod, Field(strict=False)] = StepPeriod.PLANNER
    normalize_actions: bool = True
    neighbours: int = Field(6, ge=0, le=64)
    boxes: int = Field(3, ge=0, le=64)
    slots: int = Field(3, ge=0, le=64)
    points: int = Field(3, ge=0, le=64)
    velocity_scale: float = Field(1.0, gt=0.0, le=100.0)
    rotor_span: float = Field(0.25, gt=0.0, le=1.0)
    waypoint_ceiling: float | None = Field(None, gt=0.0, le=1e4)
    record: bool = True
    render_size: Annotated[list[Annotated[int, Field(ge=16, le=4096)]], Field(min_length=2, max_length=2)] = [480, 270]
    rewards: RewardWeights = RewardWeights()


def make_config(
    config: EnvConfig | Mapping[str, Any] | None, options: Mapping[str, Any], *, source: str | None
) -> EnvConfig:
    """Merge ``config`` (an ``EnvConfig`` or a mapping) with keyword ``options`` and validate.

    Raises:
        ConfigError: one line naming ``source``, the option (``env.<name>``) and the expectation.
    """
    if isinstance(config, EnvConfig):
        data: dict[str, Any] = config.model_dump(exclude_unset=True)
    elif config is None:
        data = {}
    else:
        data = dict(config)
    data.update(options)
    rewards = data.get("rewards")
    if isinstance(rewards, RewardWeights):
        data["rewards"] = rewards.model_dump()
    for key in ("action_type", "period"):
        if isinstance(data.get(key), enum.Enum):
            data[key] = data[key].value
    if "period" not in data and data.get("action_type") in (ActionType.ROTOR_SPEED, ActionType.ROTOR_SPEED.value):
        data["period"] = StepPeriod.CONTROL.value  # rotor speeds want a fast loop: default to the control period
    if isinstance(data.get("render_size"), tuple):
        data["render_size"] = list(data["render_size"])
    return validate(EnvConfig, data, source=source, prefix="env")
