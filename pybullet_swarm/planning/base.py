"""The planner protocol: what a planner sees, what it returns, and the decentralisation contract.

A decentralised planner gets one ``Observation`` per agent (own state, neighbours within the
sensing radius, elapsed time, and what it sees of the task: ``seen``, of the task's own local view
type, e.g. ``planning.views.construction.ConstructionLocalView``) and the shared pheromone medium,
nothing else. A centralised planner (a baseline) declares ``centralized = True`` and
receives a ``WorldView`` with everything; the type it receives is what enforces the difference.
"""

from __future__ import annotations

import dataclasses
import enum
from typing import Any, ClassVar, Generic, Protocol, TypeVar, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.types import Perception
from pybullet_swarm.vehicle.downwash import DownwashParams


#: what an agent sees of its task (a task kind's local view type; None for a task without objects)
V = TypeVar("V")


class Action(enum.IntEnum):
    """What an agent asks the task to do with a box."""

    NONE = 0
    GRASP = 1
    RELEASE = 2


class CommandKind(enum.IntEnum):
    """How a command's vector is meant."""

    POSITION = 0  # fly to this position, m
    VELOCITY = 1  # fly with this velocity, m/s
    HOLD = 2  # keep the current reference


def view_distance(rel: NDArray[np.float64], norm: str) -> NDArray[np.float64]:
    """Distance (...,) m of vectors ``rel`` (..., 3) m in a view norm: "chebyshev" (largest per-axis
    difference, as the thesis measures it) or "euclidean"."""
    if norm == "chebyshev":
        return np.max(np.abs(rel), axis=-1)
    return np.linalg.norm(rel, axis=-1)


@dataclasses.dataclass(frozen=True)
class Command:
    """One agent's command for the next planner period.

    Attributes:
        kind: how ``vector`` is meant.
        vector: (3,) target position m or velocity m/s.
        yaw: desired heading, rad.
        action: GRASP / RELEASE / NONE.
    """

    kind: CommandKind
    vector: NDArray[np.float64]
    yaw: float = 0.0
    action: Action = Action.NONE

    @staticmethod
    def goto(p: NDArray[np.float64] | list[float], action: Action = Action.NONE, yaw: float = 0.0) -> Command:
        """Fly to position ``p`` (3,) m."""
        return Command(CommandKind.POSITION, np.asarray(p, dtype=float), yaw, action)

    @staticmethod
    def velocity(v: NDArray[np.float64] | list[float], action: Action = Action.NONE, yaw: float = 0.0) -> Command:
        """Fly with velocity ``v`` (3,) m/s."""
        return Command(CommandKind.VELOCITY, np.asarray(v, dtype=float), yaw, action)

    @staticmethod
    def hold(action: Action = Action.NONE) -> Command:
        """Keep the current reference."""
        return Command(CommandKind.HOLD, np.zeros(3), 0.0, action)


#: a task kind's own static layout (e.g. ``planning.views.construction.ConstructionLayout``)
L = TypeVar("L")


@dataclasses.dataclass(frozen=True)
class TaskInfo(Generic[L]):
    """What every agent knows before the run: the arena, the limits and the task's static layout.

    The core is the same for every task; what only one task kind has is its ``layout``, of the
    task's own type (``TaskInfo[ConstructionLayout]`` in a construction run; None when the task
    publishes none).

    Attributes:
        arena_size: (2,) m, the arena is [0, Lx] x [0, Ly].
        n_agents: swarm size.
        agent_radius: m, radius of the circle enclosing an airframe.
        v_max: (3,) m/s per-axis velocity limit.
        a_max: (3,) m/s^2 per-axis acceleration limit.
        layout: the task's own static layout.
        extra: task-specific static data.
    """

    arena_size: NDArray[np.float64]
    n_agents: int
    agent_radius: float
    v_max: NDArray[np.float64]
    a_max: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.full(3, np.inf))
    layout: L = None  # type: ignore[assignment]  # None: the task publishes no layout of its own
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class Payload:
    """What an agent of a task may carry under it, told to the clock and the avoidance layers without naming
    the task (a cube hanging below its carrier).

    Attributes:
        edge: m, edge of the cube.
        hang: m, the carrier's centre above the cube's centre while it holds it.
        mass: kg.
    """

    edge: float
    hang: float
    mass: float


@runtime_checkable
class CarriesPayload(Protocol):
    """A task layout whose agents carry a payload (``TaskInfo.layout`` of such a task)."""

    @property
    def payload(self) -> Payload:
        """The payload an agent carries."""


@dataclasses.dataclass(frozen=True)
class Observation(Generic[V]):
    """What one agent knows at a planner tick (local information only).

    The core is the same for every task; what the agent sees of the task is ``seen``, of the task's
    own type (``Observation[ConstructionLocalView]`` in a construction run; None when the task has
    no objects to see).

    Attributes:
        agent_id: index of the agent.
        time_s: elapsed simulated time, s.
        position: (3,) m (true or estimated, as the scenario says).
        velocity: (3,) m/s.
        yaw: rad.
        carrying: id of the object held, or -1.
        neighbour_ids: (k,) ids of agents within the sensing radius.
        neighbour_positions: (k, 3) m.
        neighbour_velocities: (k, 3) m/s.
        seen: the task's objects within the agent's view, in its own frame (the task's local view).
        ranges: (r,) m, range readings when the agent has range sensors, else empty.
        neighbour_carrying: (k,) True where the neighbour carries an object (a box hanging under a
            vehicle is seen with it); empty when the perception does not say.
    """

    agent_id: int
    time_s: float
    position: NDArray[np.float64]
    velocity: NDArray[np.float64]
    yaw: float
    carrying: int
    neighbour_ids: NDArray[np.int64]
    neighbour_positions: NDArray[np.float64]
    neighbour_velocities: NDArray[np.float64]
    seen: V
    ranges: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros(0))
    neighbour_carrying: NDArray[np.bool_] = dataclasses.field(default_factory=lambda: np.zeros(0, dtype=np.bool_))


@dataclasses.dataclass(frozen=True)
class Obstacles:
    """Static obstacles as axis-aligned boxes in the world frame: what stands still while agents fly past it.

    A pillar is given as the box around it (its square footprint, conservative by up to
    (sqrt(2) - 1) r at the corners), a turned box as the world-axis box around its footprint.

    Attributes:
        centres: (K, 3) m.
        half_extents: (K, 3) m.
        objects: (K,) the task object each box is (an index into the objects of the task's view, e.g. ``ConstructionState.objects``), -1 for the arena's.
    """

    centres: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    half_extents: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    objects: NDArray[np.int64] = dataclasses.field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self) -> None:
        k = len(self.centres)
        if np.shape(self.centres) != (k, 3) or np.shape(self.half_extents) != (k, 3) or np.shape(self.objects) != (k,):
            raise ValueError(
                f"obstacles need centres (K, 3), half_extents (K, 3) and objects (K,), got "
                f"{np.shape(self.centres)}, {np.shape(self.half_extents)} and {np.shape(self.objects)}"
            )

    def __len__(self) -> int:
        return len(self.centres)

    def __add__(self, other: Obstacles) -> Obstacles:
        """Both sets of boxes, these first."""
        if not len(other):
            return self
        if not len(self):
            return other
        return Obstacles(
            np.concatenate([self.centres, other.centres]),
            np.concatenate([self.half_extents, other.half_extents]),
            np.concatenate([self.objects, other.objects]),
        )


#: a task kind's own public state (e.g. ``planning.views.construction.ConstructionState``)
S = TypeVar("S")


@dataclasses.dataclass(frozen=True)
class TaskView(Generic[S]):
    """What the task shows at one planner tick: public progress of the task (world frame, SI units).

    The core is the same for every task; what only one task kind shows is its ``state``, of the
    task's own type (``TaskView[ConstructionState]`` in a construction run: boxes and slots;
    ``SetPoints`` of a waypoints run; ``Points`` of a route or a tour; None when there is nothing
    more). Decentralised planners see objects only through their ``Observation``; the whole view
    goes to centralised baselines, avoidance layers (which need to know who carries what) and the
    learning environments.

    Attributes:
        time_s: simulated time, s.
        carrying: (n,) id of the object each agent holds, or -1.
        state: the task's own public state.
        obstacles: the task's objects that stand still now (free and placed boxes, not carried ones),
            as avoidance layers keep clear of them (the arena's own are in ``AvoidanceSetup.obstacles``).
    """

    time_s: float
    carrying: NDArray[np.int64]
    state: S = None  # type: ignore[assignment]  # None: the task shows nothing of its own
    obstacles: Obstacles = dataclasses.field(default_factory=Obstacles)


@dataclasses.dataclass(frozen=True)
class WorldView(Generic[S]):
    """Everything, for centralised planners only.

    Attributes:
        time_s: elapsed simulated time, s.
        positions: (n, 3) m.
        velocities: (n, 3) m/s.
        carrying: (n,) id of the object held by each agent, or -1.
        task: the task's whole view (its state: boxes and slots, set-points, points done ...).
    """

    time_s: float
    positions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    carrying: NDArray[np.int64]
    task: TaskView[S]

    @staticmethod
    def of(perception: Perception, task: TaskView[S]) -> WorldView[S]:
        """The view of a centralised planner from the swarm's ``Perception`` and the task's view."""
        return WorldView(task.time_s, perception.positions, perception.velocities, task.carrying, task)


@dataclasses.dataclass(frozen=True)
class AvoidanceSetup:
    """What an avoidance layer is told once, before a run (static: no access to the simulation).

    Attributes:
        n: number of agents.
        info: the task's static layout (boxes, slots, agent radius, limits, extras).
        agent_radius: m, radius of the circle enclosing an airframe.
        collision_size: (3,) m, the airframe's collision box.
        v_max: (3,) m/s per-axis velocity limit, or None when references are not shaped.
        a_max: (3,) m/s^2 per-axis acceleration limit.
        control_dt: s, period of the position loop and reference shaper.
        planner_dt: s, period of the planner ticks (and of ``filter`` calls).
        sensing_radius: m, neighbours within it are perceived.
        range_angles: (r,) rad, bearings of the range rays in the body frame (empty without rays).
        range_m: m, longest range reading.
        range_offset: m, rays start this far from the agent centre.
        obstacles: the arena's static obstacles (pillars, boxes, walls), for the whole run.
        downwash: True when the simulation models the rotor wake of each vehicle pushing down those
            below it (``sim.downwash``).
        downwash_model: the airframe's downwash constants (what the simulation applies when ``downwash``).
        mass: kg, the airframe's mass (with ``downwash_model``: the wake's strength against the weight).
        payload: what an agent of the task may carry under it (None: nothing): a carrier's shape is its
            airframe and the payload, and a laden agent's wake is the stronger.
    """

    n: int
    info: TaskInfo
    agent_radius: float
    collision_size: NDArray[np.float64]
    v_max: NDArray[np.float64] | None
    a_max: NDArray[np.float64]
    control_dt: float
    planner_dt: float
    sensing_radius: float
    range_angles: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros(0))
    range_m: float = 0.0
    range_offset: float = 0.0
    obstacles: Obstacles = dataclasses.field(default_factory=Obstacles)
    downwash: bool = False
    downwash_model: DownwashParams | None = None
    mass: float = 0.0
    payload: Payload | None = None

    @property
    def load_mass(self) -> float:
        """kg, the payload's mass (0 without one)."""
        return 0.0 if self.payload is None else float(self.payload.mass)


@runtime_checkable
class AvoidanceLayer(Protocol):
    """A local avoidance layer between the planners and the flight controllers.

    Built once as ``Layer(setup, **params)``; a layer that reads range sensors declares
    ``needs_range_sensors = True`` and the clock gives every agent its fan of rays.
    """

    needs_range_sensors: ClassVar[bool]

    def filter(self, commands: list[Command], perception: Perception, task: TaskView) -> list[Command]:
        """Safe commands for this planner tick, from the perception snapshot and the task's view only."""

    def metrics(self) -> dict[str, Any]:
        """The layer's counters of the run (merged into metrics.json)."""


@dataclasses.dataclass(frozen=True)
class TourPlan:
    """The order in which a planner means to visit the points, as a planner publishes it (``artefacts()["tour_plan"]``).

    Attributes:
        tour: (W,) point indices of the closed tour the legs were cut from (empty if none).
        legs: per agent, (m_i,) point indices in flight order.
        paths: per agent, (p_i, 3) m, the planned polyline from the agent's start through its
            via points (climbs to a safe altitude) and its points (and home, if required).
        planned_time_s: s, the planner's estimate of the slowest agent's flight time, or None.
        metric: what the planner optimised ('time', 'length', ...).
    """

    tour: NDArray[np.int64]
    legs: tuple[NDArray[np.int64], ...]
    paths: tuple[NDArray[np.float64], ...]
    planned_time_s: float | None = None
    metric: str = ""

    @property
    def path_lengths_m(self) -> NDArray[np.float64]:
        """(n,) m, Euclidean length of each planned path."""
        return np.array([polyline_length(p) for p in self.paths])

    @property
    def length_m(self) -> float:
        """m, total Euclidean length of the planned paths (approaches included)."""
        return float(self.path_lengths_m.sum())


def polyline_length(path: NDArray[np.float64]) -> float:
    """Length m of a polyline (p, 3) m."""
    p = np.asarray(path, dtype=float).reshape(-1, 3)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) if len(p) > 1 else 0.0


@runtime_checkable
class Planner(Protocol):
    """A decentralised planner: one instance per agent, local information only."""

    name: ClassVar[str]
    centralized: ClassVar[bool]  # False

    def reset(self, agent_id: int, rng: np.random.Generator, info: TaskInfo) -> None:
        """Start a run as agent ``agent_id`` with its own random generator."""

    def plan(self, obs: Observation, medium: Any | None) -> Command:
        """The agent's command for the next planner period."""


@runtime_checkable
class CentralPlanner(Protocol):
    """A centralised planner (a baseline): one instance for the swarm, full information."""

    name: ClassVar[str]
    centralized: ClassVar[bool]  # True

    def reset(self, n: int, rng: np.random.Generator, info: TaskInfo) -> None:
        """Start a run for ``n`` agents."""

    def plan_all(self, view: WorldView) -> list[Command]:
        """One command per agent."""
