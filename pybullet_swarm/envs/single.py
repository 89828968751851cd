"""Gymnasium environments for one agent: ``pybullet_swarm/Hover-v0`` and ``pybullet_swarm/Waypoints-v0``.

Both fly one agent of a ``waypoints`` scenario with the swarm environment's observation layout
(own state, the active set-point, range readings when present), actions and rewards; the
action type is an option (``velocity``, ``waypoint`` or ``rotor_speed`` for direct rotor-speed
control). Terminated when the agent has held the last set-point (the task's completion) or
crashed, truncated at the scenario's time limit.

- ``Hover-v0``: take off from the ground and hold 1 m above the start (10 s limit; completed
  after holding within 5 cm for 2 s).
- ``Waypoints-v0``: the bundled ``hover`` scenario: take off, then 0.5 m steps in x, y and z
  on a timed schedule (40 s).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import gymnasium
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from pybullet_swarm.envs.config import EnvConfig, make_config
from pybullet_swarm.envs.episode import SwarmEpisode
from pybullet_swarm.envs.spaces import ObservationLayout
from pybullet_swarm.envs.swarm import RENDER_MODES, SEED_BOUND, check_render_mode, resolve_scenario
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import Scenario, WaypointsTask, load_scenario
from pybullet_swarm.experiment.simulation import Simulation

HOVER_OVERRIDES: dict[str, Any] = {
    "task.time_limit_s": 10.0,
    "task.tolerance_m": 0.05,
    "task.hold_s": 2.0,
    "task.waypoints": [{"t_s": 0.0, "position": [0.0, 0.0, 1.0]}],
}


def hover_scenario(overrides: Mapping[str, Any] | Sequence[str] = ()) -> Scenario:
    """The task of ``Hover-v0``: the bundled ``hover`` scenario holding 1 m above the start."""
    sc = load_scenario("hover", HOVER_OVERRIDES)
    return sc.with_overrides(overrides) if overrides else sc


class SingleAgentEnv(gymnasium.Env[NDArray[np.float32], NDArray[Any]]):
    """One agent of a ``waypoints`` scenario as a Gymnasium environment.

    Args:
        scenario: a one-agent ``waypoints`` scenario (``Scenario``, YAML path or bundled name).
        overrides: ``key.path=value`` scenario overrides.
        config: an ``EnvConfig`` or a mapping of its options.
        render_mode: None or ``"rgb_array"``.
        **options: ``EnvConfig`` options (``action_type``, ``period``, ``normalize_actions``, ``rewards``, ...).

    Raises:
        ConfigError: a bad scenario or option, or a scenario with more than one agent.

    Seeding: ``reset(seed=s)`` runs the scenario with seed ``s`` (as ``pybullet-swarm run --seed s``);
    ``reset()`` draws the next run's seed from ``self.np_random``.
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 10}

    def __init__(
        self,
        scenario: Scenario | str | Path = "hover",
        *,
        overrides: Mapping[str, Any] | Sequence[str] = (),
        config: EnvConfig | Mapping[str, Any] | None = None,
        render_mode: str | None = None,
        **options: Any,
    ) -> None:
        sc = resolve_scenario(scenario, overrides)
        if sc.agents.count != 1:
            raise ConfigError(
                f"must be 1 for a single-agent environment, got {sc.agents.count}",
                source=sc.source,
                field="agents.count",
            )
        if not isinstance(sc.task, WaypointsTask):
            raise ConfigError(
                f"must be 'waypoints' for a single-agent environment, got {sc.task.kind!r}",
                source=sc.source,
                field="task.kind",
            )
        check_render_mode(render_mode, sc.source)
        self.scenario = sc
        self.config = make_config(config, options, source=sc.source)
        self.render_mode = render_mode
        self._episode = SwarmEpisode(sc, self.config)
        ep = self._episode
        self.metadata = {**type(self).metadata, "render_fps": 1.0 / ep.dt}
        self.layout: ObservationLayout = ep.layout
        self.observation_space = spaces.Box(ep.layout.low, ep.layout.high, dtype=np.float32)
        m = ep.mapper
        self.action_space = spaces.Box(m.low, m.high, dtype=m.dtype)

    @property
    def sim(self) -> Simulation:
        """The simulation of the current episode (read its state, events, contacts; do not step it)."""
        return self._episode.sim

    @property
    def dt(self) -> float:
        """Simulated seconds per environment step."""
        return self._episode.dt

    def neutral_action(self) -> NDArray[Any]:
        """The action that holds the agent where it is."""
        return self._episode.mapper.hover_action(self.sim)[0]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """Start an episode; returns the observation and info."""
        super().reset(seed=seed)
        run_seed = int(seed) if seed is not None else int(self.np_random.integers(SEED_BOUND))
        obs = self._episode.reset(run_seed)
        return obs[0], {"collisions": [], "metrics": self._episode.running_metrics()}

    def step(self, action: NDArray[Any]) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        """Advance one period with ``action``."""
        ep = self._episode
        obs, out, terminated, truncated = ep.step(np.asarray(action).reshape(1, -1))
        info: dict[str, Any] = {"collisions": out.collisions[0], "metrics": ep.running_metrics()}
        if out.goal_distance is not None:
            info["goal_distance_m"] = float(out.goal_distance[0])
        if terminated or truncated:
            info["episode"] = {"return": float(ep.returns[0]), "length": ep.steps}
        return obs[0], float(out.rewards[0]), bool(terminated), bool(truncated), info

    def render(self) -> NDArray[np.uint8] | None:  # type: ignore[override]
        """An RGB frame (height, width, 3) uint8 with ``render_mode="rgb_array"`` (DIRECT mode), else None."""
        if self.render_mode is None:
            gymnasium.logger.warn(
                "render() called without a render mode; make the environment with render_mode='rgb_array'"
            )
            return None
        return self._episode.render()

    def close(self) -> None:
        """Release the simulation (idempotent)."""
        self._episode.close()


class HoverEnv(SingleAgentEnv):
    """``pybullet_swarm/Hover-v0``: take off and hold 1 m above the start (see ``hover_scenario``).

    Args:
        scenario: None for the default task, or another one-agent waypoints scenario.
        overrides: scenario overrides (applied to the default task when ``scenario`` is None).
    """

    def __init__(
        self,
        scenario: Scenario | str | Path | None = None,
        *,
        overrides: Mapping[str, Any] | Sequence[str] = (),
        **kwargs: Any,
    ) -> None:
        if scenario is None:
            super().__init__(hover_scenario(overrides), **kwargs)
        else:
            super().__init__(scenario, overrides=overrides, **kwargs)


class WaypointsEnv(SingleAgentEnv):
    """``pybullet_swarm/Waypoints-v0``: follow the timed set-points of the bundled ``hover`` scenario
    (or of another one-agent waypoints scenario)."""

    def __init__(self, scenario: Scenario | str | Path = "hover", **kwargs: Any) -> None:
        super().__init__(scenario, **kwargs)
