"""Scenario files: schema, loading by path or bundled name, overrides, and semantic checks.

Every problem becomes one ``ConfigError`` line: ``file: field.path: expectation, got value``.
"""
from __future__ import annotations

import copy
import dataclasses
import math
from pathlib import Path
from typing import Annotated, Any, Literal, Mapping, Sequence, Union

import numpy as np
import pydantic
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.resources import bundled_scenarios, scenarios_dir
from pybullet_swarm.validation import _short, check_plain, parse_yaml, read_yaml, validate

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]
PosVec3 = Annotated[list[Annotated[float, Field(gt=0)]], Field(min_length=3, max_length=3)]
PosFloat = Annotated[float, Field(gt=0, le=1e6)]


class _Strict(pydantic.BaseModel):
    # allow_inf_nan=False: .nan/.inf pass no bound check, e.g. a waypoint at [.nan, 0, 1]
    model_config = pydantic.ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


class SimSection(_Strict):
    """Clock and physics options."""

    physics_hz: int = Field(240, ge=60, le=10_000)        # Hz, physics and attitude-loop rate
    control_hz: int = Field(48, ge=1, le=10_000)          # Hz, position-loop and reference rate
    planner_hz: int = Field(10, ge=1, le=10_000)          # Hz, planner and task rate
    record_hz: int = Field(20, ge=1, le=10_000)           # Hz, time-series decimation
    gravity: float = Field(9.81, ge=0.0, le=100.0)        # m/s^2
    drag_coefficient: float = Field(0.0, ge=0.0, le=10.0)  # N/(m/s), linear air drag
    ground_effect: bool = False                            # thrust gain near the ground
    max_tilt_deg: float = Field(35.0, gt=0.0, lt=80.0)     # deg, largest commanded tilt
    crash_speed: float = Field(2.0, gt=0.0, le=100.0)      # m/s, ground impact counted as a crash


class ArenaSection(_Strict):
    """The flight area: x in [0, Lx], y in [0, Ly], ground at z = 0."""

    size: Annotated[list[Annotated[float, Field(gt=0, le=1e4)]], Field(min_length=2, max_length=2)] = [3.0, 1.0]
    height: PosFloat | None = None   # m, ceiling (None: open height)
    walls: bool = False              # add four walls of `wall_height` around the arena
    wall_height: PosFloat = 2.0


class AgentsSection(_Strict):
    """The swarm: how many, which vehicle, where they start."""

    count: int = Field(1, ge=1, le=2000)
    vehicle: str = "quad150"
    start: list[Vec3] | None = None          # m, explicit start positions (count of them)
    layout: Literal["grid", "line"] = "grid"  # used when `start` is not given
    spacing: PosFloat = 0.5                  # m, between neighbours of the layout
    origin: Annotated[list[float], Field(min_length=2, max_length=2)] | None = None  # m, layout centre (default: arena centre)
    sensing_radius: PosFloat = 1.0           # m, neighbours within it are observed
    start_jitter: float = Field(0.0, ge=0.0, le=1.0)  # m, uniform horizontal noise on start positions (per seed)


class LimitsSection(_Strict):
    """Reference-shaping limits, per axis (a number applies to all three axes)."""

    velocity: PosFloat | PosVec3 | None = 0.5   # m/s; None: no shaping (raw steps)
    acceleration: PosFloat | PosVec3 = 1.0      # m/s^2


class Waypoint(_Strict):
    """A timed set-point."""

    t_s: float = Field(ge=0.0, le=1e5)   # s, when it becomes active
    position: Vec3                        # m, relative to the agent's start when `relative`
    yaw_deg: float = Field(0.0, ge=-360.0, le=360.0)


class WaypointsTask(_Strict):
    """Every agent follows a timed list of set-points; completed when all hold the last one."""

    kind: Literal["waypoints"]
    time_limit_s: float = Field(gt=0.0, le=1e5)
    waypoints: Annotated[list[Waypoint], Field(min_length=1)]
    relative: bool = True                 # positions are offsets from each agent's start
    tolerance_m: float = Field(0.05, gt=0.0, le=100.0)
    hold_s: float = Field(1.0, ge=0.0, le=1e4)


TASK_MODELS: dict[str, type[_Strict]] = {"waypoints": WaypointsTask}


class SensingSection(_Strict):
    """What the agents sense: own-state source, onboard sensors and their noise.

    Sub-sections are added by the sensing layer (range sensors; IMU, positioning, estimator).
    """

    # --- own state (estimation) ---
    # --- range sensors ---


class PlannerSection(_Strict):
    """Which planner issues the agents' commands, and its parameters."""

    name: str | None = None
    params: dict[str, Any] = Field(default_factory=dict)


class _ScenarioFile(_Strict):
    name: str = "scenario"
    description: str = ""
    seed: int = Field(0, ge=0, le=2**63 - 1)
    sim: SimSection = SimSection()
    arena: ArenaSection = ArenaSection()
    agents: AgentsSection = AgentsSection()
    limits: LimitsSection = LimitsSection()
    task: dict[str, Any]
    planner: PlannerSection = PlannerSection()
    avoidance: str = "none"
    avoidance_params: dict[str, Any] = Field(default_factory=dict)
    collisions: Literal["physical", "ghost"] = "physical"
    sensing: SensingSection = SensingSection()


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A validated scenario: the sections above plus where it came from.

    Attributes:
        source: file name the scenario came from (for error messages).
        data: the resolved scenario as plain data (what ``scenario.yaml`` of a run holds).
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
        """A new scenario with ``key.path=value`` overrides applied and validated again."""
        data = apply_overrides(copy.deepcopy(dict(self.data)), overrides, source=self.source)
        return build_scenario(data, source=self.source)


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


def apply_overrides(data: dict[str, Any], overrides: Mapping[str, Any] | Sequence[str], *, source: str) -> dict[str, Any]:
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
                raise ConfigError(f"must be a mapping to set {key} inside it, got {_short(nxt)}", source=source,
                                  field=".".join(parts[: depth + 1]))
            node = nxt
        node[parts[-1]] = value
    return data


def _check_rates(sim: SimSection, source: str) -> None:
    for name in ("control_hz", "planner_hz", "record_hz"):
        rate = getattr(sim, name)
        if rate > sim.physics_hz or sim.physics_hz % rate != 0:
            raise ConfigError(f"must divide sim.physics_hz ({sim.physics_hz}) into an integer ratio, got {rate}",
                              source=source, field=f"sim.{name}")


def _check_agents(s: Scenario, source: str) -> None:
    from pybullet_swarm.vehicle import load_vehicle

    try:
        vehicle = load_vehicle(s.agents.vehicle)
    except ConfigError as exc:
        raise ConfigError(exc.detail, source=source, field="agents.vehicle") from None
    except OSError as exc:  # e.g. a name too long for the file system
        raise ConfigError(f"must be a bundled vehicle name or a vehicle .yaml file ({exc.strerror}), "
                          f"got {_short(s.agents.vehicle)}", source=source, field="agents.vehicle") from None
    if s.agents.start is not None and len(s.agents.start) != s.agents.count:
        raise ConfigError(f"must hold agents.count ({s.agents.count}) positions, got {len(s.agents.start)}",
                          source=source, field="agents.start")
    starts = s.start_positions(0.5 * vehicle.collision_size[2] + 1e-3)
    lx, ly = s.arena.size
    r = 0.5 * max(vehicle.collision_size[0], vehicle.collision_size[1])
    for i, p in enumerate(starts):
        if not (r - 1e-9 <= p[0] <= lx - r + 1e-9 and r - 1e-9 <= p[1] <= ly - r + 1e-9):
            field = f"agents.start[{i}]" if s.agents.start is not None else "agents.count"
            raise ConfigError(f"agent {i} starts at ({p[0]:.3g}, {p[1]:.3g}), outside the arena "
                              f"[0, {lx:g}] x [0, {ly:g}] m (with its radius {r:g} m)", source=source, field=field)
        if p[2] < 0.0:
            raise ConfigError(f"agent {i} starts below the ground, got z = {p[2]:g}", source=source,
                              field=f"agents.start[{i}]")
    if s.agents.count > 1:
        from scipy.spatial import cKDTree

        pairs = cKDTree(starts[:, :2]).query_pairs(2 * r * 0.999)
        if pairs:
            i, j = min(pairs)
            field = "agents.start" if s.agents.start is not None else "agents.spacing"
            raise ConfigError(f"agents {i} and {j} start overlapping (closer than {2 * r:.3g} m)",
                              source=source, field=field)


def _check_waypoints(task: WaypointsTask, source: str) -> None:
    times = [w.t_s for w in task.waypoints]
    for i in range(1, len(times)):
        if times[i] < times[i - 1]:
            raise ConfigError(f"waypoint times must not decrease, got {times[i]:g} after {times[i - 1]:g}",
                              source=source, field=f"task.waypoints[{i}].t_s")
    if times[-1] > task.time_limit_s:
        raise ConfigError(f"last waypoint at {times[-1]:g} s is after the time limit {task.time_limit_s:g} s",
                          source=source, field="task.waypoints")


def build_scenario(data: Any, *, source: str) -> Scenario:
    """Validate plain scenario data (as read from YAML) into a ``Scenario``."""
    if not isinstance(data, dict):
        raise ConfigError(f"must be a mapping of scenario sections, got {type(data).__name__}", source=source)
    check_plain(data, source=source)
    f = validate(_ScenarioFile, data, source=source)
    kind = f.task.get("kind")
    from pybullet_swarm import tasks as _tasks  # registry of task models, filled by the tasks layer

    models = {**TASK_MODELS, **_tasks.task_models()}
    if "kind" not in f.task:
        raise ConfigError("is required", source=source, field="task.kind")
    if not isinstance(kind, str) or kind not in models:  # not hashable: a list or a mapping
        raise ConfigError(f"must be one of {', '.join(sorted(models))}, got {_short(kind)}", source=source,
                          field="task.kind")
    task = validate(models[kind], f.task, source=source, prefix="task")
    _check_rates(f.sim, source)
    resolved = f.model_dump(mode="json")
    resolved["task"] = task.model_dump(mode="json")
    s = Scenario(source=source, name=f.name, description=f.description, seed=f.seed, sim=f.sim, arena=f.arena,
                 agents=f.agents, limits=f.limits, task=task, planner=f.planner, avoidance=f.avoidance,
                 collisions=f.collisions, data=resolved, sensing=f.sensing)
    _check_agents(s, source)
    if isinstance(task, WaypointsTask):
        _check_waypoints(task, source)
    check = getattr(task, "check", None)
    if callable(check):
        check(s, source)
    return s


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
    raise ConfigError(f"no scenario file or bundled scenario named {str(path_or_name)!r}; bundled: "
                      f"{', '.join(bundled_scenarios())}", source=str(path_or_name))


def load_scenario(path_or_name: str | Path, overrides: Mapping[str, Any] | Sequence[str] = ()) -> Scenario:
    """Load, override and validate a scenario by path or bundled name.

    Args:
        path_or_name: a YAML file or the name of a bundled scenario (see ``pybullet-swarm list``).
        overrides: ``{'agents.count': 5}`` or ``['agents.count=5']``, applied before validation.

    Raises:
        ConfigError: one line naming the file, the field and what was expected.
    """
    path = resolve_scenario_path(path_or_name)
    data = read_yaml(path)
    if overrides:
        if not isinstance(data, dict):
            raise ConfigError(f"must be a mapping of scenario sections, got {type(data).__name__}", source=path.name)
        data = apply_overrides(data, overrides, source=path.name)
    return build_scenario(data, source=path.name)
