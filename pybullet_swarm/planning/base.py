"""The planner protocol: what a planner sees, what it returns, and the decentralisation contract.

A decentralised planner gets one ``Observation`` per agent (own state, neighbours within the
sensing radius, task objects within its view radius, elapsed time) and the shared pheromone
medium, nothing else. A centralised planner (a baseline) declares ``centralized = True`` and
receives a ``WorldView`` with everything; the type it receives is what enforces the difference.
"""
from __future__ import annotations

import dataclasses
import enum
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray


class Action(enum.IntEnum):
    """What an agent asks the task to do with a box."""

    NONE = 0
    GRASP = 1
    RELEASE = 2


class CommandKind(enum.IntEnum):
    """How a command's vector is meant."""

    POSITION = 0   # fly to this position, m
    VELOCITY = 1   # fly with this velocity, m/s
    HOLD = 2       # keep the current reference


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


@dataclasses.dataclass(frozen=True)
class TaskInfo:
    """What every agent knows before the run: the arena and the task's static layout.

    The thesis's agents are told where the boxes start and where the structure goes; what the
    boxes are doing now they only learn by seeing them (``Observation.boxes``).

    Attributes:
        arena_size: (2,) m, the arena is [0, Lx] x [0, Ly].
        n_agents: swarm size.
        agent_radius: m, radius of the circle enclosing an airframe.
        v_max: (3,) m/s per-axis velocity limit.
        a_max: (3,) m/s^2 per-axis acceleration limit.
        depot: (B, 3) m, box start positions (empty when the task has no boxes).
        slots: (S, 3) m, goal slot centres.
        box_size: m, edge of a box (0 when none).
        grasp_height: m, agent centre above a box centre when holding it.
        route: (W, 3) m, waypoints of a route task (empty when none).
        extra: task-specific static data.
    """

    arena_size: NDArray[np.float64]
    n_agents: int
    agent_radius: float
    v_max: NDArray[np.float64]
    a_max: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.full(3, np.inf))
    depot: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    slots: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    box_size: float = 0.0
    grasp_height: float = 0.0
    route: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class Observation:
    """What one agent knows at a planner tick (local information only).

    Attributes:
        agent_id: index of the agent.
        time_s: elapsed simulated time, s.
        position: (3,) m (true or estimated, as the scenario says).
        velocity: (3,) m/s.
        yaw: rad.
        carrying: id of the box held, or -1.
        neighbour_ids: (k,) ids of agents within the sensing radius.
        neighbour_positions: (k, 3) m.
        neighbour_velocities: (k, 3) m/s.
        boxes: (b, 3) m, free boxes within the view radius (not carried, not placed).
        box_ids: (b,) ids of those boxes.
        slots: (s, 3) m, open slots within the view radius (empty and supported).
        slot_ids: (s,) ids of those slots.
        ranges: (r,) m, range readings when the agent has range sensors, else empty.
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
    boxes: NDArray[np.float64]
    box_ids: NDArray[np.int64]
    slots: NDArray[np.float64]
    slot_ids: NDArray[np.int64]
    ranges: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros(0))


@dataclasses.dataclass(frozen=True)
class WorldView:
    """Everything, for centralised planners only.

    Attributes:
        time_s: elapsed simulated time, s.
        positions: (n, 3) m.
        velocities: (n, 3) m/s.
        carrying: (n,) box id held by each agent, or -1.
        box_positions: (B, 3) m, every box now.
        box_state: (B,) 0 free, 1 carried, 2 placed.
        slot_filled: (S,) box id in each slot, or -1.
        slot_open: (S,) True when a slot is empty and supported.
    """

    time_s: float
    positions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    carrying: NDArray[np.int64]
    box_positions: NDArray[np.float64]
    box_state: NDArray[np.int64]
    slot_filled: NDArray[np.int64]
    slot_open: NDArray[np.bool_]


@runtime_checkable
class Planner(Protocol):
    """A decentralised planner: one instance per agent, local information only."""

    name: ClassVar[str]
    centralized: ClassVar[bool]   # False

    def reset(self, agent_id: int, rng: np.random.Generator, info: TaskInfo) -> None:
        """Start a run as agent ``agent_id`` with its own random generator."""

    def plan(self, obs: Observation, medium: Any | None) -> Command:
        """The agent's command for the next planner period."""


@runtime_checkable
class CentralPlanner(Protocol):
    """A centralised planner (a baseline): one instance for the swarm, full information."""

    name: ClassVar[str]
    centralized: ClassVar[bool]   # True

    def reset(self, n: int, rng: np.random.Generator, info: TaskInfo) -> None:
        """Start a run for ``n`` agents."""

    def plan_all(self, view: WorldView) -> list[Command]:
        """One command per agent."""
