"""Scenario files: schema, loading by path or bundled name, overrides, and semantic checks.

Every problem becomes one ``ConfigError`` line: ``file: field.path: expectation, got value``.
"""

from __future__ import annotations

import copy
import dataclasses
import enum
import math
import numbers
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, Mapping, Sequence

import numpy as np
import pydantic
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.errors import ConfigError, LayoutNeedError
from pybullet_swarm.planning.base import Obstacles
from pybullet_swarm.planning.params import NoParams, ParamInfo, ParamRuleError, Params, PlanContext
from pybullet_swarm.planning.params import field_info as describe_field
from pybullet_swarm.resources import bundled_scenarios, scenarios_dir
from pybullet_swarm.tasks.waypoints import WaypointsTask
from pybullet_swarm.validation import _short, check_drawable_text, check_plain, parse_yaml, read_yaml, validate

if TYPE_CHECKING:  # pragma: no cover
    from pybullet_swarm.vehicle import VehicleParams

MAX_COORD = 1e5  # m, largest coordinate accepted anywhere (the largest arena is 1e4 m)
WALL_THICKNESS = 0.02  # m, of the arena's walls (``arena.walls``)
Coord = Annotated[float, Field(ge=-MAX_COORD, le=MAX_COORD)]
Vec3 = Annotated[list[Coord], Field(min_length=3, max_length=3)]
PosFloat = Annotated[float, Field(gt=0, le=1e6)]
# reference-shaping limits: at least 1 mm/s (mm/s^2), below which the shaper's times overflow
Limit = Annotated[float, Field(ge=1e-3, le=1e6)]
LimitVec3 = Annotated[list[Limit], Field(min_length=3, max_length=3)]


class _Strict(pydantic.BaseModel):
    # allow_inf_nan=False: .nan/.inf pass no bound check, e.g. a waypoint at [.nan, 0, 1]
    model_config = pydantic.ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


class SimSection(_Strict):
    """Clock and physics options."""

    physics_hz: int = Field(240, ge=60, le=10_000)  # Hz, physics and attitude-loop rate
    control_hz: int = Field(48, ge=1, le=10_000)  # Hz, position-loop and reference rate
    planner_hz: int = Field(10, ge=1, le=10_000)  # Hz, planner and task rate
    record_hz: int = Field(20, ge=1, le=10_000)  # Hz, time-series decimation
    # Hz, contact and overlap reads for collision counting (None: every physics step); at most one debounce
    # interval (0.1 s) apart. Coarser reads miss contacts shorter than their period and time contacts in
    # whole periods
    contact_hz: int | None = Field(None, ge=10, le=10_000)
    gravity: float = Field(9.81, ge=0.0, le=100.0)  # m/s^2
    drag_coefficient: float = Field(0.0, ge=0.0, le=10.0)  # N/(m/s), linear air drag
    ground_effect: bool = False  # thrust gain near the ground
    downwash: bool = True  # a vehicle's rotor wake pushes vehicles below it down (pybullet_swarm.vehicle.downwash)
    max_tilt_deg: float = Field(35.0, gt=0.0, lt=80.0)  # deg, largest commanded tilt
    crash_speed: float = Field(2.0, gt=0.0, le=100.0)  # m/s, ground impact counted as a crash
    # m, velocity commands: the position reference is kept within this of the agent's position per axis (None:
    # it integrates the command whatever the agent does; held back by a wake or a contact, an agent then
    # flew twice the commanded speed to catch up, into what the avoidance layer had planned round). Off by
    # default: at 0.03 on the construction holdout, agent-agent contacts doubled (docs/results/construction.md)
    reference_leash: float | None = Field(None, gt=0.0, le=10.0)


class ObstacleShape(str, enum.Enum):
    """Shape of a static obstacle."""

    CYLINDER = "cylinder"  # vertical pillar: size [radius, height] m
    BOX = "box"  # size [x, y, z] m, turned by yaw_deg about the vertical


class Obstacle(_Strict):
    """A static obstacle standing in the arena (its collisions count as ``agent_obstacle``).

    ``position`` is [x, y] (standing on the ground) or [x, y, z] (centre) in m.
    """

    shape: Literal["cylinder", "box"]  # an ObstacleShape value
    size: Annotated[
        list[Annotated[float, Field(gt=0, le=1e4)]], Field(min_length=2, max_length=3)
    ]  # m, [r, h] | [x, y, z]
    position: Annotated[list[Coord], Field(min_length=2, max_length=3)]  # m, centre [x, y] (on the ground) or [x, y, z]
    yaw_deg: float = Field(0.0, ge=-360.0, le=360.0)  # deg, about z

    def center(self) -> NDArray[np.float64]:
        """Centre (3,) m (a 2-D position stands the obstacle on the ground)."""
        h = self.size[1] if self.shape == ObstacleShape.CYLINDER else self.size[2]
        z = self.position[2] if len(self.position) == 3 else 0.5 * h
        return np.array([self.position[0], self.position[1], z], dtype=float)

    def half_extents_xy(self) -> tuple[float, float]:
        """Half extents m of the world-axis box around the horizontal footprint."""
        if self.shape == ObstacleShape.CYLINDER:
            return float(self.size[0]), float(self.size[0])
        c, s = abs(math.cos(math.radians(self.yaw_deg))), abs(math.sin(math.radians(self.yaw_deg)))
        return 0.5 * (c * self.size[0] + s * self.size[1]), 0.5 * (s * self.size[0] + c * self.size[1])

    def bounding_box(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(centre (3,) m, half extents (3,) m) of the world-axis box around the obstacle."""
        h = self.size[1] if self.shape == ObstacleShape.CYLINDER else self.size[2]
        return self.center(), np.array([*self.half_extents_xy(), 0.5 * h], dtype=float)

    def horizontal_distance(self, xy: NDArray[np.float64]) -> NDArray[np.float64]:
        """Horizontal distance (k,) m from points xy (k, 2) m to the footprint (0 inside)."""
        d = np.asarray(xy, dtype=float).reshape(-1, 2) - self.center()[:2]
        if self.shape == ObstacleShape.CYLINDER:
            return np.maximum(np.linalg.norm(d, axis=1) - self.size[0], 0.0)
        c, s = math.cos(math.radians(self.yaw_deg)), math.sin(math.radians(self.yaw_deg))
        local = np.abs(np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]]))
        return np.linalg.norm(np.maximum(local - 0.5 * np.asarray(self.size[:2]), 0.0), axis=1)


class ArenaSection(_Strict):
    """The flight area: x in [0, Lx], y in [0, Ly], ground at z = 0."""

    size: Annotated[list[Annotated[float, Field(gt=0, le=1e4)]], Field(min_length=2, max_length=2)] = [
        3.0,
        1.0,
    ]  # m, [Lx, Ly]: x in [0, Lx], y in [0, Ly]
    height: PosFloat | None = None  # m, ceiling (None: open height)
    walls: bool = False  # add four walls of `wall_height` around the arena
    wall_height: PosFloat = 2.0  # m
    obstacles: list[Obstacle] = Field(default_factory=list)  # static pillars and boxes

    def pillars(self) -> NDArray[np.float64]:
        """(K, 3) [x, y, radius] m of every obstacle as a round pillar: a cylinder as it is, a box as the
        circle around its footprint (what flocking models avoid)."""
        rows = [
            [
                *ob.center()[:2],
                float(ob.size[0]) if ob.shape == "cylinder" else 0.5 * math.hypot(ob.size[0], ob.size[1]),
            ]
            for ob in self.obstacles
        ]
        return np.asarray(rows, dtype=float).reshape(-1, 3)

    def obstacle_boxes(self) -> Obstacles:
        """The walls (when ``walls``) and every obstacle as world-axis boxes, for avoidance layers."""
        centres, halves = [], []
        if self.walls:
            lx, ly = self.size
            t, h = WALL_THICKNESS, self.wall_height
            for x, y, sx, sy in (
                (lx / 2, -t / 2, lx + 2 * t, t),
                (lx / 2, ly + t / 2, lx + 2 * t, t),
                (-t / 2, ly / 2, t, ly),
                (lx + t / 2, ly / 2, t, ly),
            ):
                centres.append([x, y, h / 2])
                halves.append([sx / 2, sy / 2, h / 2])
        for ob in self.obstacles:
            centre, half = ob.bounding_box()
            centres.append(centre.tolist())
            halves.append(half.tolist())
        k = len(centres)
        return Obstacles(
            np.asarray(centres, dtype=float).reshape(k, 3),
            np.asarray(halves, dtype=float).reshape(k, 3),
            np.full(k, -1, dtype=np.int64),
        )


class AgentsSection(_Strict):
    """The swarm: how many, which vehicle, where they start."""

    count: int = Field(1, ge=1, le=2000)  # number of agents
    vehicle: str = "quad150"  # a bundled vehicle (quad150, cf2x) or the path of a vehicle YAML beside its URDF
    start: list[Vec3] | None = None  # m, explicit start positions (count of them)
    layout: Literal["grid", "line"] = "grid"  # used when `start` is not given
    spacing: PosFloat = 0.5  # m, between neighbours of the layout
    origin: Annotated[list[Coord], Field(min_length=2, max_length=2)] | None = (
        None  # m, layout centre (default: arena centre)
    )
    sensing_radius: PosFloat = 1.0  # m, neighbours within it are observed
    start_jitter: float = Field(0.0, ge=0.0, le=1.0)  # m, uniform horizontal noise on start positions (per seed)


class LimitsSection(_Strict):
    """Reference-shaping limits, per axis (a number applies to all three axes)."""

    velocity: Limit | LimitVec3 | None = 0.5  # m/s; None: no shaping (raw steps)
    acceleration: Limit | LimitVec3 = 1.0  # m/s^2


TASK_MODELS: dict[str, type[pydantic.BaseModel]] = {"waypoints": WaypointsTask}


class RangeSensing(_Strict):
    """A fan of horizontal range rays per agent (proximity sensors), cast once per planner tick.

    Rays start at the airframe's enclosing radius and are levelled (they turn with the agent's
    yaw only); a reading is the free distance m along a ray, ``range_m`` when nothing is hit.
    """

    enabled: bool = False  # cast and observe (braitenberg turns it on)
    rays: int = Field(8, ge=1, le=360)  # rays per agent
    range_m: float = Field(0.5, gt=0.0, le=100.0)  # m, longest reading
    noise_std_m: float = Field(0.005, ge=0.0, le=10.0)  # m, Gaussian noise on a hit
    fov_deg: float = Field(360.0, gt=0.0, le=360.0)  # deg, spread of the fan, centred on body x


class OwnState(str, enum.Enum):
    """Where the position loop and the planners take an agent's own state from."""

    TRUE = "true"  # the simulator's true state
    ESTIMATED = "estimated"  # the onboard estimate (IMU + positioning, Kalman fusion)


class ImuSensing(_Strict):
    """Accelerometer and gyroscope noise, sampled at sim.control_hz (defaults: Crazyflie 2.x class,
    Bosch BMI088 data sheet typical figures; see ``pybullet_swarm/sensing/imu.py``)."""

    accel_noise_density: float = Field(1.716e-3, ge=0.0, le=100.0)  # m/s^2/sqrt(Hz) (175 ug/sqrt(Hz))
    gyro_noise_density: float = Field(2.443e-4, ge=0.0, le=100.0)  # rad/s/sqrt(Hz) (0.014 deg/s/sqrt(Hz))
    accel_bias_std: float = Field(0.196, ge=0.0, le=100.0)  # m/s^2 per axis, drawn per agent (20 mg)
    gyro_bias_std: float = Field(0.01745, ge=0.0, le=100.0)  # rad/s per axis, drawn per agent (1 deg/s)
    accel_bias: Vec3 | None = None  # m/s^2, one constant bias for every agent instead of drawn ones
    gyro_bias: Vec3 | None = None  # rad/s, likewise


class PositioningSensing(_Strict):
    """Absolute positioning fixes (GPS, motion capture): rate, noise, dropouts (defaults: indoor
    positioning, 1 cm per axis at 10 Hz; see ``pybullet_swarm/sensing/positioning.py``)."""

    rate_hz: int = Field(10, ge=1, le=10_000)  # Hz; divides sim.physics_hz, at most sim.control_hz
    noise_std: float = Field(0.01, ge=0.0, le=100.0)  # m per axis
    heading_noise_std: float | None = Field(0.01, ge=0.0, le=10.0)  # rad; null: fixes carry no heading
    dropout_probability: float = Field(0.0, ge=0.0, lt=1.0)  # chance that an agent's fix is lost
    outages: list[Annotated[list[Annotated[float, Field(ge=0.0, le=1e6)]], Field(min_length=2, max_length=2)]] = Field(
        default_factory=list
    )  # [start_s, end_s] intervals without fixes


class EstimatorSensing(_Strict):
    """Calibration and filter settings of the onboard estimator (``pybullet_swarm/sensing/estimator.py``)."""

    calibration_s: float = Field(2.0, ge=0.0, le=600.0)  # s at rest before take-off (bias calibration)
    tilt_gain: float = Field(0.5, ge=0.0, le=100.0)  # 1/s, accelerometer correction of roll and pitch
    heading_gain: float = Field(0.3, ge=0.0, le=1.0)  # fraction of the heading error removed per fix
    accel_process_std: float = Field(0.03, gt=0.0, le=100.0)  # m/s^2, acceleration input error per IMU sample
    estimate_bias: bool = True  # world-frame acceleration bias in the Kalman state
    bias_walk: float = Field(0.003, ge=0.0, le=100.0)  # m/s^2/sqrt(s), random walk of that bias
    initial_bias_std: float = Field(0.05, gt=0.0, le=100.0)  # m/s^2
    initial_velocity_std: float = Field(0.01, gt=0.0, le=100.0)  # m/s


class SensingSection(_Strict):
    """What the agents sense: own-state source, onboard sensors and their noise.

    Sub-sections are added by the sensing layer (range sensors; IMU, positioning, estimator).
    """

    # --- own state (estimation) ---
    state: OwnState = OwnState.TRUE  # true | estimated: what the position loop and the planners use
    run_estimator: bool = False  # run sensors and estimator (and report them) on true state too
    imu: ImuSensing = ImuSensing()
    positioning: PositioningSensing = PositioningSensing()
    estimator: EstimatorSensing = EstimatorSensing()

    @pydantic.field_validator("state", mode="before")
    @classmethod
    def _own_state(cls, value: Any) -> OwnState:
        # YAML reads a bare `true` as a boolean, `--set sensing.state=estimated` gives a string
        if value is True or value == "true" or value is OwnState.TRUE:
            return OwnState.TRUE
        if value == "estimated" or value is OwnState.ESTIMATED:
            return OwnState.ESTIMATED
        raise ValueError("must be true or estimated")

    @property
    def estimating(self) -> bool:
        """True when the sensors and the estimator run (flying on the estimate, or evaluating it)."""
        return self.state is OwnState.ESTIMATED or self.run_estimator

    # --- range sensors ---
    range: RangeSensing = RangeSensing()  # fan of horizontal range rays per agent


class CommSection(_Strict):
    """Flight condition: what agents learn of their neighbours comes by radio (``pybullet_swarm.sensing.comm``).

    Off by default (every field at its default: neighbours are perceived directly, at once, exactly).
    """

    radio_range_m: PosFloat | None = None  # m, messages reach only this far (None: agents.sensing_radius alone)
    delay_s: float = Field(0.0, ge=0.0, le=60.0)  # s, a message is received this long after it was sent
    packet_loss: float = Field(0.0, ge=0.0, lt=1.0)  # chance that one message to one neighbour is lost
    gps_rate_hz: float | None = Field(
        None, gt=0.0, le=1000.0
    )  # Hz, rate of the broadcast position fixes (None: every tick)
    gps_noise_std_m: float = Field(0.0, ge=0.0, le=100.0)  # m per axis, noise of a broadcast position fix
    gps_velocity_noise_std: float = Field(0.0, ge=0.0, le=100.0)  # m/s per axis, noise of a broadcast velocity

    @property
    def enabled(self) -> bool:
        """True when any field differs from its default."""
        return self != CommSection()


class WindSection(_Strict):
    """Flight condition: wind as aerodynamic drag on every vehicle and box (``pybullet_swarm.vehicle.wind``).

    Off by default (no wind, no gusts).
    """

    velocity: Annotated[list[Annotated[float, Field(ge=-100.0, le=100.0)]], Field(min_length=3, max_length=3)] = [
        0.0,
        0.0,
        0.0,
    ]  # m/s, steady wind (world frame)
    turbulence: float = Field(0.0, ge=0.0, le=50.0)  # m/s, standard deviation of the Dryden gusts per axis
    length_scale_m: float = Field(8.0, gt=0.0, le=1e4)  # m, Dryden scale length of the gusts

    @property
    def enabled(self) -> bool:
        """True when there is any wind or gust."""
        return any(v != 0.0 for v in self.velocity) or self.turbulence > 0.0


class PlannerSection(_Strict):
    """Which planner issues the agents' commands, and its parameters.

    In a file ``name`` may be left out (the task kind's default planner) and ``params`` may name
    only some parameters; a loaded scenario holds the resolved name and every parameter with its
    value (validated against the planner's parameter model).
    """

    name: str | None = None  # a registered planner (default: the task kind's)
    params: dict[str, Any] = Field(default_factory=dict)  # the planner's parameters (its parameter model)


class _ScenarioFile(_Strict):
    name: str = "scenario"  # names the run and its directory, shown in figures
    description: str = ""  # one line, shown by `list`
    seed: int = Field(0, ge=0, le=2**63 - 1)  # every random stream of the run derives from it
    sim: SimSection = SimSection()
    arena: ArenaSection = ArenaSection()
    agents: AgentsSection = AgentsSection()
    limits: LimitsSection = LimitsSection()
    task: dict[str, Any]  # the task section; `kind` chooses its model (below)
    planner: PlannerSection = PlannerSection()
    avoidance: str = "none"  # a registered avoidance layer
    avoidance_params: dict[str, Any] = Field(default_factory=dict)  # the layer's parameters (its parameter model)
    # ghost: agents and carried boxes pass through each other, their overlaps still counted as contacts
    collisions: Literal["physical", "ghost"] = "physical"
    sensing: SensingSection = SensingSection()
    comm: CommSection = CommSection()
    wind: WindSection = WindSection()


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A validated scenario: the sections above plus where it came from.

    Attributes:
        source: file name the scenario came from (for error messages).
        data: the resolved scenario as plain data (what ``scenario.yaml`` of a run holds): the
            planner's name, the avoidance layer and every parameter of both with its value.
        planner: the resolved planner section (name and every parameter, plain data).
        planner_params: the planner's validated parameter model.
        avoidance_params: the avoidance layer's validated parameter model.
    """

    source: str
    name: str
    description: str
    seed: int
    sim: SimSection
    arena: ArenaSection
    agents: AgentsSection
    limits: LimitsSection
    task: Any
    planner: PlannerSection
    avoidance: str
    collisions: str
    data: Mapping[str, Any]
    sensing: SensingSection = SensingSection()
    planner_params: Params = NoParams()
    avoidance_params: Params = NoParams()
    comm: CommSection = CommSection()
    wind: WindSection = WindSection()

    def start_positions(self, rest_height: float) -> NDArray[np.float64]:
        """Start positions (n, 3) m; layouts rest on the ground at ``rest_height`` m."""
        a = self.agents
        if a.start is not None:
            return np.asarray(a.start, dtype=float)
        return layout_positions(a.count, a.layout, a.spacing, self.layout_origin(), rest_height)

    def layout_origin(self) -> tuple[float, float]:
        """Centre of the start layout, m."""
        if self.agents.origin is not None:
            return float(self.agents.origin[0]), float(self.agents.origin[1])
        return 0.5 * self.arena.size[0], 0.5 * self.arena.size[1]

    def velocity_limits(self) -> NDArray[np.float64] | None:
        """Per-axis velocity limit (3,) m/s, or None when references are not shaped."""
        v = self.limits.velocity
        return None if v is None else np.broadcast_to(np.asarray(v, dtype=float), (3,)).copy()

    def acceleration_limits(self) -> NDArray[np.float64]:
        """Per-axis acceleration limit (3,) m/s^2."""
        return np.broadcast_to(np.asarray(self.limits.acceleration, dtype=float), (3,)).copy()

    def with_overrides(self, overrides: Mapping[str, Any] | Sequence[str]) -> Scenario:
        """A new scenario with ``key.path=value`` overrides applied and validated again.

        A scenario holds every parameter of its planner and avoidance layer, so ``planner.name``
        and ``avoidance`` overrides are taken as choices (``with_choices``): another planner or
        layer starts from its own defaults.
        """
        items = (
            overrides.items()
            if isinstance(overrides, Mapping)
            else (parse_override(o, source=self.source) if isinstance(o, str) else tuple(o) for o in overrides)
        )
        choices: dict[str, Any] = {}
        rest: dict[str, Any] = {}
        for key, value in items:
            if key in ("planner.name", "avoidance") and isinstance(value, str):
                choices["planner" if key == "planner.name" else "avoidance"] = value
            else:
                rest[key] = value
        return self.with_choices(**choices, overrides=rest)

    def with_choices(
        self,
        *,
        planner: str | None = None,
        avoidance: str | None = None,
        seed: int | None = None,
        overrides: Mapping[str, Any] | Sequence[str] = (),
    ) -> Scenario:
        """A new scenario with another planner, avoidance layer or seed (see ``apply_choices``), then
        ``overrides``, validated again; the same scenario when nothing changes."""
        seed = None if seed is None else _seed(seed, self.source)
        if (
            planner in (None, self.planner.name)
            and avoidance in (None, self.avoidance)
            and not overrides
            and seed in (None, self.seed)
        ):
            return self
        if planner in (None, self.planner.name) and avoidance in (None, self.avoidance) and not overrides:
            assert seed is not None  # only the seed changes: nothing else to validate again
            return dataclasses.replace(self, seed=seed, data={**self.data, "seed": seed})
        data = apply_choices(
            copy.deepcopy(dict(self.data)), planner=planner, avoidance=avoidance, seed=seed, source=self.source
        )
        return build_scenario(apply_overrides(data, overrides, source=self.source), source=self.source)


def layout_positions(n: int, layout: str, spacing: float, origin: tuple[float, float], z: float) -> NDArray[np.float64]:
    """Start positions (n, 3) m on a centred square grid or a line along x."""
    if layout == "line":
        xs = (np.arange(n) - (n - 1) / 2.0) * spacing
        return np.column_stack([origin[0] + xs, np.full(n, origin[1]), np.full(n, z)])
    cols = int(math.ceil(math.sqrt(n)))
    rows = int(math.ceil(n / cols))
    idx = np.arange(n)
    gx = (idx % cols - (cols - 1) / 2.0) * spacing
    gy = (idx // cols - (rows - 1) / 2.0) * spacing
    return np.column_stack([origin[0] + gx, origin[1] + gy, np.full(n, z)])


def parse_override(text: str, *, source: str = "--set") -> tuple[str, Any]:
    """Split ``key.path=value``; the value is parsed as YAML (numbers, lists, null...)."""
    if "=" not in text:
        raise ConfigError(f"expected key.path=value, got {text!r}", source=source)
    key, _, raw = text.partition("=")
    key = key.strip()
    if not key or any(not part for part in key.split(".")):
        raise ConfigError(f"expected key.path=value, got {text!r}", source=source)
    try:
        value = parse_yaml(raw, source=source) if raw.strip() else None
    except ConfigError:
        raise ConfigError(f"value is not valid YAML, got {raw!r}", source=source, field=key) from None
    return key, value


def apply_overrides(
    data: dict[str, Any], overrides: Mapping[str, Any] | Sequence[str], *, source: str
) -> dict[str, Any]:
    """Set nested keys of ``data`` from ``{'a.b': v}`` or ``['a.b=v', ...]``; returns ``data``."""
    items = overrides.items() if isinstance(overrides, Mapping) else (parse_override(s) for s in overrides)
    for key, value in items:
        if not isinstance(key, str) or not key or any(not part for part in key.split(".")):
            raise ConfigError(f"expected a key.path, got {_short(key)}", source=source)
        node = data
        parts = key.split(".")
        for depth, part in enumerate(parts[:-1]):
            nxt = node.get(part) if isinstance(node, dict) else None
            if nxt is None:
                nxt = {}
                node[part] = nxt
            elif not isinstance(nxt, dict):
                raise ConfigError(
                    f"must be a mapping to set {key} inside it, got {_short(nxt)}",
                    source=source,
                    field=".".join(parts[: depth + 1]),
                )
            node = nxt
        node[parts[-1]] = value
    return data


def apply_choices(
    data: dict[str, Any],
    *,
    planner: str | None = None,
    avoidance: str | None = None,
    seed: int | None = None,
    source: str,
) -> dict[str, Any]:
    """Apply a run's choices (``--planner``, ``--avoidance``, ``--seed``) to scenario data before it
    is validated; returns ``data``.

    Switching to another planner than the one the data name drops the data's ``planner.params``
    (they were for the other planner); data that name no planner keep theirs (they are for
    whichever planner runs). Likewise switching to another avoidance layer drops ``avoidance_params``.
    """
    if planner is not None:
        section = data.get("planner")
        section = {} if section is None else section
        if not isinstance(section, dict):
            raise ConfigError(
                f"must be a mapping of name and params, got {_short(section)}", source=source, field="planner"
            )
        if section.get("name") not in (None, planner):
            section = {k: v for k, v in section.items() if k != "params"}
        data["planner"] = {**section, "name": planner}
    if avoidance is not None:
        if data.get("avoidance", "none") != avoidance:
            data.pop("avoidance_params", None)
        data["avoidance"] = avoidance
    if seed is not None:
        data["seed"] = seed
    return data


def _seed(seed: Any, source: str) -> int:
    """A run's seed as an int (numpy integers too), refused outside [0, 2**63 - 1]."""
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, numbers.Integral) or not 0 <= int(seed) <= 2**63 - 1:
        raise ConfigError(f"must be an integer in [0, 2**63 - 1], got {_short(seed)}", source=source, field="seed")
    return int(seed)


def _resolve_plugins(f: _ScenarioFile, task: Any, source: str) -> tuple[str, Params, Params]:
    """The planner's name and the validated parameter models of the planner and the avoidance layer.

    The planner is ``planner.name`` or the task kind's default; it must solve the task kind.
    ``planner.params`` and ``avoidance_params`` are validated against the plug-ins' models, then
    checked against the scenario (``Params.check_for``).
    """
    from pybullet_swarm.planning.registry import avoidance_layers, default_planner, planners

    kind = task.kind
    registry = planners()
    name = f.planner.name if f.planner.name is not None else default_planner(kind)
    if name is None:
        raise ConfigError(
            f"is required: task kind {kind!r} has no default planner", source=source, field="planner.name"
        )
    if name not in registry:
        from pybullet_swarm.planning.registry import refused

        if f"planner {name}" in refused():  # an installed plug-in that did not satisfy its protocol
            raise ConfigError(str(refused()[f"planner {name}"]), source=source, field="planner.name")
        raise ConfigError(
            f"must be one of {', '.join(sorted(registry))}, got {_short(name)}", source=source, field="planner.name"
        )
    entry = registry[name]
    if kind not in entry.tasks:
        raise ConfigError(
            f"planner {name!r} does not solve {kind!r} tasks (it solves {', '.join(entry.tasks)})",
            source=source,
            field="planner.name",
        )
    if entry.check_task is not None:  # what a planner needs of its task (a formation ...)
        try:
            entry.check_task(task)
        except ConfigError as exc:
            raise exc.with_source(source) from None
    layers = avoidance_layers()
    if f.avoidance not in layers:
        raise ConfigError(
            f"must be one of {', '.join(sorted(layers))}, got {_short(f.avoidance)}", source=source, field="avoidance"
        )
    params = validate(entry.params, f.planner.params, source=source, prefix="planner.params")
    avoidance = validate(layers[f.avoidance].params, f.avoidance_params, source=source, prefix="avoidance_params")
    from pybullet_swarm.memory import memory_budget

    context = PlanContext(
        arena_size=(float(f.arena.size[0]), float(f.arena.size[1])),
        n_agents=f.agents.count,
        time_limit_s=float(task.time_limit_s),
        planner_hz=f.sim.planner_hz,
        range_rays=f.sensing.range.rays,
        memory_budget=memory_budget(),
    )
    for model, prefix in ((params, "planner.params"), (avoidance, "avoidance_params")):
        try:
            model.check_for(context)
        except ParamRuleError as exc:
            raise ConfigError(str(exc), source=source, field=f"{prefix}.{exc.field}") from None
    return name, params, avoidance


def _check_rates(sim: SimSection, source: str) -> None:
    for name in ("control_hz", "planner_hz", "record_hz", "contact_hz"):
        rate = getattr(sim, name)
        if rate is None:
            continue
        if rate > sim.physics_hz or sim.physics_hz % rate != 0:
            raise ConfigError(
                f"must divide sim.physics_hz ({sim.physics_hz}) into an integer ratio, got {rate}",
                source=source,
                field=f"sim.{name}",
            )


def _check_sensing(sim: SimSection, sensing: SensingSection, source: str) -> None:
    """Positioning fixes at an integer division of the physics rate, at most one per control period."""
    rate = sensing.positioning.rate_hz
    if sim.physics_hz % rate != 0 or rate > sim.control_hz:
        raise ConfigError(
            f"must divide sim.physics_hz ({sim.physics_hz}) into an integer ratio and be at most "
            f"sim.control_hz ({sim.control_hz}), got {rate}",
            source=source,
            field="sensing.positioning.rate_hz",
        )
    for i, (start, end) in enumerate(sensing.positioning.outages):
        if end <= start:
            raise ConfigError(
                f"must be [start_s, end_s] with end_s > start_s, got [{start:g}, {end:g}]",
                source=source,
                field=f"sensing.positioning.outages[{i}]",
            )


def _check_conditions(s: Scenario, source: str) -> None:
    """Flight conditions that cannot work: wind beside the controller's linear drag (the air would be counted
    twice), position fixes broadcast faster than the planner ticks that send them."""
    if s.wind.enabled and s.sim.drag_coefficient > 0.0:
        raise ConfigError(
            f"must be 0 with wind (the vehicle file's drag coefficients act in the wind), got {s.sim.drag_coefficient:g}",
            source=source,
            field="sim.drag_coefficient",
        )
    rate = s.comm.gps_rate_hz
    if rate is not None and rate > s.sim.planner_hz:
        raise ConfigError(
            f"must be at most sim.planner_hz ({s.sim.planner_hz}): fixes are broadcast at planner ticks, got {rate:g}",
            source=source,
            field="comm.gps_rate_hz",
        )


def _load_vehicle(s: Scenario, source: str) -> VehicleParams:
    """The scenario's vehicle; a bad vehicle file is refused naming the scenario field and the vehicle file's field."""
    from pybullet_swarm.vehicle import load_vehicle

    try:
        return load_vehicle(s.agents.vehicle)
    except ConfigError as exc:  # str(exc) names the vehicle file and its field, when it has them
        raise ConfigError(str(exc), source=source, field="agents.vehicle") from None
    except OSError as exc:  # e.g. a name too long for the file system
        raise ConfigError(
            f"must be a bundled vehicle name or a vehicle .yaml file ({exc.strerror}), got {_short(s.agents.vehicle)}",
            source=source,
            field="agents.vehicle",
        ) from None


def _check_agents(s: Scenario, vehicle: VehicleParams, source: str) -> None:
    if s.agents.start is not None and len(s.agents.start) != s.agents.count:
        raise ConfigError(
            f"must hold agents.count ({s.agents.count}) positions, got {len(s.agents.start)}",
            source=source,
            field="agents.start",
        )
    half_h = 0.5 * vehicle.collision_size[2]
    starts = s.start_positions(half_h + 1e-3)
    lx, ly = s.arena.size
    r = 0.5 * max(vehicle.collision_size[0], vehicle.collision_size[1])

    def inside(x: float, y: float) -> bool:
        return r - 1e-9 <= x <= lx - r + 1e-9 and r - 1e-9 <= y <= ly - r + 1e-9

    if s.agents.start is None and s.agents.origin is not None and not inside(*s.layout_origin()):
        ox, oy = s.layout_origin()
        raise ConfigError(
            f"layout centre ({ox:.3g}, {oy:.3g}) is outside the arena [0, {lx:g}] x [0, {ly:g}] m "
            f"(with the agents' radius {r:g} m)",
            source=source,
            field="agents.origin",
        )
    top = s.arena.height
    for i, p in enumerate(starts):
        if not inside(p[0], p[1]):
            field = f"agents.start[{i}]" if s.agents.start is not None else "agents.count"
            raise ConfigError(
                f"agent {i} starts at ({p[0]:.3g}, {p[1]:.3g}), outside the arena "
                f"[0, {lx:g}] x [0, {ly:g}] m (with its radius {r:g} m)",
                source=source,
                field=field,
            )
        if p[2] < 0.0:
            raise ConfigError(
                f"agent {i} starts below the ground, got z = {p[2]:g}", source=source, field=f"agents.start[{i}]"
            )
        if top is not None and p[2] + half_h > top + 1e-9:
            field = f"agents.start[{i}]" if s.agents.start is not None else "arena.height"
            raise ConfigError(
                f"agent {i} starts above the ceiling (arena.height {top:g} m less the airframe's half "
                f"height {half_h:g} m), got z = {p[2]:g}",
                source=source,
                field=field,
            )
    if s.agents.count > 1:
        from scipy.spatial import cKDTree

        pairs = cKDTree(starts[:, :2]).query_pairs(2 * r * 0.999)
        if pairs:
            i, j = min(pairs)
            field = "agents.start" if s.agents.start is not None else "agents.spacing"
            raise ConfigError(
                f"agents {i} and {j} start overlapping (closer than {2 * r:.3g} m)", source=source, field=field
            )


def _check_obstacles(s: Scenario, vehicle: VehicleParams, source: str) -> None:
    """Obstacles: sizes that fit their shape, footprints inside the arena, no agent starting inside one.

    An agent starts inside an obstacle when its footprint (the airframe's enclosing circle, moved by
    at most the start jitter) reaches the obstacle's and its vertical extent overlaps the obstacle's:
    an agent may start on top of a box or under a raised one, never within it.
    """
    lx, ly = s.arena.size
    half_h = 0.5 * vehicle.collision_size[2]
    starts = s.start_positions(half_h + 1e-3)
    clearance = float(vehicle.radius) + math.sqrt(2.0) * s.agents.start_jitter
    for i, ob in enumerate(s.arena.obstacles):
        field = f"arena.obstacles[{i}]"
        want = 2 if ob.shape == ObstacleShape.CYLINDER else 3
        if len(ob.size) != want:
            what = "[radius, height]" if want == 2 else "[x, y, z]"
            raise ConfigError(
                f"a {ob.shape} needs size {what} m, got {len(ob.size)} numbers", source=source, field=f"{field}.size"
            )
        c, (hx, hy) = ob.center(), ob.half_extents_xy()
        if not (hx - 1e-9 <= c[0] <= lx - hx + 1e-9 and hy - 1e-9 <= c[1] <= ly - hy + 1e-9):
            raise ConfigError(
                f"obstacle at ({c[0]:g}, {c[1]:g}) reaching {hx:.3g} m x {hy:.3g} m from its centre is "
                f"not inside the arena [0, {lx:g}] x [0, {ly:g}] m",
                source=source,
                field=f"{field}.position",
            )
        h = ob.size[1] if ob.shape == ObstacleShape.CYLINDER else ob.size[2]
        bottom, top = c[2] - 0.5 * h, c[2] + 0.5 * h
        if bottom < -1e-9:
            raise ConfigError(
                f"obstacle reaches below the ground (centre z {c[2]:g} m, height {h:g} m)",
                source=source,
                field=f"{field}.position",
            )
        near = ob.horizontal_distance(starts[:, :2]) < clearance
        level = (starts[:, 2] + half_h > bottom + 1e-9) & (starts[:, 2] - half_h < top - 1e-9)
        inside = np.flatnonzero(near & level)
        if inside.size:
            k = int(inside[0])
            raise ConfigError(
                f"agent {k} starts inside this obstacle (within {clearance:.3g} m of its footprint, "
                f"at z = {starts[k, 2]:.3g} m between its bottom {bottom:.3g} m and top {top:.3g} m)",
                source=source,
                field=field,
            )


def _check_waypoints(s: Scenario, task: WaypointsTask, vehicle: VehicleParams, source: str) -> None:
    times = [w.t_s for w in task.waypoints]
    for i in range(1, len(times)):
        if times[i] < times[i - 1]:
            raise ConfigError(
                f"waypoint times must not decrease, got {times[i]:g} after {times[i - 1]:g}",
                source=source,
                field=f"task.waypoints[{i}].t_s",
            )
    if times[-1] > task.time_limit_s:
        raise ConfigError(
            f"last waypoint at {times[-1]:g} s is after the time limit {task.time_limit_s:g} s",
            source=source,
            field="task.waypoints",
        )
    top = s.arena.height
    if top is None:
        return
    half_h = 0.5 * vehicle.collision_size[2]
    base = s.start_positions(half_h + 1e-3)[:, 2] if task.relative else np.zeros(1)
    for i, w in enumerate(task.waypoints):
        z = float(np.max(base)) + w.position[2]
        if z + half_h > top + 1e-9:
            where = " (relative to the highest start)" if task.relative else ""
            raise ConfigError(
                f"set-point above the ceiling (arena.height {top:g} m less the airframe's half height "
                f"{half_h:g} m): z = {z:.3g} m{where}",
                source=source,
                field=f"task.waypoints[{i}].position",
            )


def _check_layout(s: Scenario, vehicle: VehicleParams, source: str) -> None:
    """The planner's and the avoidance layer's ``check_layout`` on the layout the agents will be told (a task
    model with ``plan_info(vehicle)``): what the planners would refuse when the run starts is refused here."""
    from pybullet_swarm.tasks import task_entries

    if not task_entries()[s.task.kind].publishes_plan_info:
        return
    from pybullet_swarm.planning.base import TaskInfo

    v = s.velocity_limits()
    info = TaskInfo(
        arena_size=np.asarray(s.arena.size, dtype=float),
        n_agents=s.agents.count,
        agent_radius=float(vehicle.radius),
        v_max=np.full(3, np.inf) if v is None else v,
        a_max=s.acceleration_limits(),
        **s.task.plan_info(vehicle),
    )
    for model in (s.planner_params, s.avoidance_params):
        try:
            model.check_layout(info)
        except ConfigError as exc:
            raise (exc.with_source(source) if exc.source is None else exc) from None


MIN_GRAVITY = 0.1  # m/s^2: the hover controller carries m g and limits its tilt relative to g


def _check_flight(s: Scenario, vehicle: VehicleParams, source: str) -> None:
    """Gravity the hover controller can fly in, a controller design that finds gains, and
    reference limits the designed controller follows without saturating a rotor.

    The position loop feeds the weight forward and limits the commanded tilt relative to g: with
    no gravity it has nothing to hold (zero-g flight is out of scope, refused); with more gravity
    than the rotors can lift the vehicle cannot take off (refused).
    """
    g = s.sim.gravity
    if g < MIN_GRAVITY:
        raise ConfigError(
            f"must be >= {MIN_GRAVITY:g} m/s^2 (the hover controller carries the weight m g and "
            f"limits its tilt relative to g), got {g:g}",
            source=source,
            field="sim.gravity",
        )
    if vehicle.thrust_to_weight(g) < 1.0:
        raise ConfigError(
            f"{vehicle.name} cannot lift its own weight at {g:g} m/s^2 (thrust-to-weight "
            f"{vehicle.thrust_to_weight(g):.3g} < 1)",
            source=source,
            field="sim.gravity",
        )
    from pybullet_swarm.control.design import ReferenceStep, design_controller

    # what the simulation's controller does when it is built: design (no gains for a loop is an
    # error naming the vehicle file and the loop), then the scenario's reference step must not
    # saturate a rotor
    try:
        design = design_controller(vehicle, physics_hz=s.sim.physics_hz, position_hz=s.sim.control_hz, gravity=g)
    except ConfigError as exc:
        raise ConfigError(
            f"{exc} (with sim.gravity {g:g} m/s^2, sim.physics_hz {s.sim.physics_hz}, sim.control_hz "
            f"{s.sim.control_hz})",
            source=source,
            field="agents.vehicle",
        ) from None
    try:
        design.check_step(ReferenceStep.from_limits(s.velocity_limits(), s.acceleration_limits()))
    except ConfigError as exc:
        field = "limits.acceleration" if s.limits.velocity is not None else "limits.velocity"
        raise ConfigError(str(exc), source=source, field=field) from None


def _check_budgets(s: Scenario) -> None:
    """Refuse a scenario whose arrays would not fit the memory budget (``pybullet_swarm.memory``).

    Estimated here: the recorder's buffers (time limit x record rate x agents), the tour task's
    per-tick distances (agents x points) and the ant colony of ``aco_tour`` (points squared,
    ``iterations``, ``ants``). The plug-ins' own arrays (a pheromone grid, a memory of echoes) are
    checked by their parameter models (``Params.check_for``) against the same budget.

    Raises:
        ConfigError: one line naming the field whose value sets the size, and the bytes it would need.
    """
    from pybullet_swarm import memory

    src, n = s.source, s.agents.count
    samples = math.ceil(s.task.time_limit_s * s.sim.record_hz) + 2
    channels = 20 + (30 if s.sensing.estimating else 0)
    memory.check_budget(
        memory.recorder_bytes(samples, n, channels),
        f"recording {samples} samples of {n} agents (task.time_limit_s x sim.record_hz)",
        source=src,
        field="sim.record_hz",
    )
    from pybullet_swarm.planning.aco_tour import AcoTourParams
    from pybullet_swarm.tasks.tour import TourTask

    if not isinstance(s.task, TourTask):
        return
    w = len(s.task.points)
    memory.check_budget(
        8.0 * 3 * 4 * n * w, f"the tour task's distances of {n} agents to {w} points", source=src, field="task.points"
    )
    p = s.planner_params
    if isinstance(p, AcoTourParams):
        ants, iterations, cand = int(p.ants), int(p.iterations), p.candidates
        matrices = 8.0 * 16 * w * w  # the (W, W, 3) differences of the cost matrix and their temporaries
        colony = memory.colony_bytes(
            w, ants=ants, iterations=iterations, candidates=None if cand is None else int(cand)
        )
        field = (
            "planner.params.iterations"
            if iterations > 16 * w * w
            else "planner.params.ants"
            if 3 * ants * w > 16 * w * w
            else "task.points"
        )
        memory.check_budget(
            max(matrices, colony),
            f"an ant colony on {w} points ({ants} ants, {iterations} iterations)",
            source=src,
            field=field,
        )


def _check_text(f: _ScenarioFile, source: str) -> None:
    """The scenario's name and description are drawn in figure titles and printed by ``list``."""
    for field, text in (("name", f.name), ("description", f.description)):
        check_drawable_text(text, source=source, field=field)


MAX_DERIVATIONS = 4
"""Most times one build derives a field a layout check needs (each derivation validates again)."""


def build_scenario(data: Any, *, source: str) -> Scenario:
    """Validate plain scenario data (as read from YAML) into a ``Scenario``.

    A task field the file leaves unset (null) and that a planner's or avoidance layer's layout check
    finds insufficient (``LayoutNeedError``: e.g. ``task.view_radius``, so that every slot is in an
    agent's view) is derived from the layout: the least value that passes is written into the
    scenario, which is validated again (the resolved scenario holds it, so a run reproduces it). A
    value the user set is refused instead, with the least value that would work.
    """
    derived: set[str] = set()
    for _ in range(MAX_DERIVATIONS):
        try:
            return _build_scenario(data, source=source)
        except LayoutNeedError as need:
            fixed = _derive(data, need, derived)
            if fixed is None:
                raise
            data = fixed
    return _build_scenario(data, source=source)


def _derive(data: Any, need: LayoutNeedError, derived: set[str]) -> dict[str, Any] | None:
    """``data`` with the task field ``need`` names set to its least working value (recorded in ``derived``),
    or None when the user set that field (their value stands and is refused) or it is no task field."""
    section, _, key = (need.field or "").partition(".")
    task = data.get("task") if isinstance(data, dict) else None
    if section != "task" or not key or "." in key or not isinstance(task, dict):
        return None
    was = task.get(key)
    if was is not None and (key not in derived or need.least <= float(was)):
        return None  # the user's value, or no progress: refused rather than looped
    derived.add(key)
    return {**data, "task": {**task, key: need.least}}


def _build_scenario(data: Any, *, source: str) -> Scenario:
    """``build_scenario`` without deriving fields."""
    if not isinstance(data, dict):
        raise ConfigError(f"must be a mapping of scenario sections, got {type(data).__name__}", source=source)
    check_plain(data, source=source)
    f = validate(_ScenarioFile, data, source=source)
    _check_text(f, source)
    kind = f.task.get("kind")
    from pybullet_swarm import tasks as _tasks  # registry of task models, filled by the tasks layer

    models = {**TASK_MODELS, **_tasks.task_models()}
    if "kind" not in f.task:
        raise ConfigError("is required", source=source, field="task.kind")
    if not isinstance(kind, str) or kind not in models:  # not hashable: a list or a mapping
        raise ConfigError(
            f"must be one of {', '.join(sorted(models))}, got {_short(kind)}", source=source, field="task.kind"
        )
    task = validate(models[kind], f.task, source=source, prefix="task")
    _check_rates(f.sim, source)
    _check_sensing(f.sim, f.sensing, source)
    planner_name, planner_params, avoidance_params = _resolve_plugins(f, task, source)
    planner = PlannerSection(name=planner_name, params=planner_params.model_dump(mode="json"))
    resolved = f.model_dump(mode="json")
    resolved["task"] = task.model_dump(mode="json")
    resolved["planner"] = planner.model_dump(mode="json")
    resolved["avoidance_params"] = avoidance_params.model_dump(mode="json")
    s = Scenario(
        source=source,
        name=f.name,
        description=f.description,
        seed=f.seed,
        sim=f.sim,
        arena=f.arena,
        agents=f.agents,
        limits=f.limits,
        task=task,
        planner=planner,
        avoidance=f.avoidance,
        collisions=f.collisions,
        data=resolved,
        sensing=f.sensing,
        planner_params=planner_params,
        avoidance_params=avoidance_params,
        comm=f.comm,
        wind=f.wind,
    )
    _check_conditions(s, source)
    vehicle = _load_vehicle(s, source)
    with np.errstate(all="ignore"):  # huge finite values may overflow in the geometry: refused, never warned
        _check_agents(s, vehicle, source)
        _check_obstacles(s, vehicle, source)
        if isinstance(task, WaypointsTask):
            _check_waypoints(s, task, vehicle, source)
        if _tasks.task_entries()[kind].checks_scenario:
            task.check(s, source)
        _check_layout(s, vehicle, source)
    _check_flight(s, vehicle, source)
    _check_budgets(s)
    return s


def check_saved_scenario(data: Any, *, source: str) -> None:
    """Refuse a run's saved ``scenario.yaml`` whose sections the figures read are not valid.

    The schema of every section, the task model of its kind and the vehicle are checked; the
    semantic checks of ``build_scenario`` (and the controller design) are not repeated for a
    scenario that already ran.

    Raises:
        ConfigError: one line naming ``source`` and the field.
    """
    if not isinstance(data, dict):
        raise ConfigError(f"must be a mapping of scenario sections, got {type(data).__name__}", source=source)
    check_plain(data, source=source)
    f = validate(_ScenarioFile, data, source=source)
    _check_text(f, source)
    from pybullet_swarm import tasks as _tasks
    from pybullet_swarm.vehicle import load_vehicle

    models = {**TASK_MODELS, **_tasks.task_models()}
    kind = f.task.get("kind")
    if not isinstance(kind, str) or kind not in models:
        raise ConfigError(
            f"must be one of {', '.join(sorted(models))}, got {_short(kind)}", source=source, field="task.kind"
        )
    validate(models[kind], f.task, source=source, prefix="task")
    try:
        load_vehicle(f.agents.vehicle)
    except (ConfigError, OSError) as exc:
        raise ConfigError(str(exc), source=source, field="agents.vehicle") from None


def field_info(scenario: Scenario, key: str) -> ParamInfo | None:
    """Type, default, range and description of the scenario field ``key`` (a ``--set`` path such as
    ``limits.velocity``, ``task.time_limit_s``, ``planner.params.fatigue`` or
    ``avoidance_params.time_horizon``), read from the models; None when ``key`` names no field
    (or a whole section). ``planner.params`` and ``avoidance_params`` are read from the models of
    the scenario's planner and avoidance layer."""
    parts = key.split(".")
    model: type[pydantic.BaseModel]
    if parts[:2] == ["planner", "params"]:
        model, parts = type(scenario.planner_params), parts[2:]
    elif parts[0] == "avoidance_params":
        model, parts = type(scenario.avoidance_params), parts[1:]
    elif parts[0] == "task":
        model, parts = type(scenario.task), parts[1:]
    else:
        model = _ScenarioFile
    if not parts:
        return None
    for part in parts[:-1]:
        f = model.model_fields.get(part)
        inner = f.annotation if f is not None else None
        if not (isinstance(inner, type) and issubclass(inner, pydantic.BaseModel)):
            return None
        model = inner
    f = model.model_fields.get(parts[-1])
    if f is None or (isinstance(f.annotation, type) and issubclass(f.annotation, pydantic.BaseModel)):
        return None
    default = f.get_default(call_default_factory=True)
    return describe_field(
        parts[-1],
        f.annotation,
        f.metadata,
        default=default.value if isinstance(default, enum.Enum) else default,
        description=f.description or "",
    )


def _is_file(p: Path) -> bool:
    """``p.is_file()``, False also for names the file system refuses (too long, ...)."""
    try:
        return p.is_file()
    except OSError:
        return False


def resolve_scenario_path(path_or_name: str | Path) -> Path:
    """A scenario file from a path or a bundled name ('hover', 'construction')."""
    p = Path(path_or_name)
    if _is_file(p):
        return p
    candidate = scenarios_dir() / f"{path_or_name}.yaml"
    if p.suffix == "" and _is_file(candidate):
        return candidate
    if p.suffix in (".yaml", ".yml"):
        bundled = scenarios_dir() / p.name
        if p.parent == Path(".") and _is_file(bundled):
            return bundled
        raise ConfigError("file not found", source=str(p))
    raise ConfigError(
        f"no scenario file or bundled scenario named {str(path_or_name)!r}; bundled: {', '.join(bundled_scenarios())}",
        source=str(path_or_name),
    )


def load_scenario(
    path_or_name: str | Path,
    overrides: Mapping[str, Any] | Sequence[str] = (),
    *,
    planner: str | None = None,
    avoidance: str | None = None,
    seed: int | None = None,
) -> Scenario:
    """Load, override and validate a scenario by path or bundled name.

    Args:
        path_or_name: a YAML file or the name of a bundled scenario (see ``pybullet-swarm list``).
        overrides: ``{'agents.count': 5}`` or ``['agents.count=5']``, applied before validation.
        planner: run this planner (``--planner``; see ``apply_choices``), applied before ``overrides``.
        avoidance: run this avoidance layer (``--avoidance``), likewise.
        seed: the run's seed (``--seed``), likewise.

    Raises:
        ConfigError: one line naming the file, the field and what was expected.
    """
    path = resolve_scenario_path(path_or_name)
    data = read_yaml(path)
    if overrides or planner is not None or avoidance is not None or seed is not None:
        if not isinstance(data, dict):
            raise ConfigError(f"must be a mapping of scenario sections, got {type(data).__name__}", source=path.name)
        data = apply_choices(
            data,
            planner=planner,
            avoidance=avoidance,
            seed=None if seed is None else _seed(seed, path.name),
            source=path.name,
        )
        data = apply_overrides(data, overrides, source=path.name)
    return build_scenario(data, source=path.name)
