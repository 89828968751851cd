"""The task protocol: one ``TaskRuntime`` per task kind, built from the scenario, found by kind.

The simulation is a clock that names no task. At the start of a run it builds the task's runtime
with ``TASK_RUNTIMES[kind](spec, context)``; then, every planner tick, it asks the runtime to
``update`` (progress and completion), publishes its ``view`` and the agents' ``local_views`` to the
perception of the planners, and hands the agents' task actions to ``apply``. A run whose task
``progress`` count has not changed for the task's ``stall_time_s`` ends as stalled. At the end it merges
the runtime's ``metrics`` into ``metrics.json`` and writes its ``artefacts`` (plain data) into the
run directory. The learning environments call the same methods.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, Callable, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.base import Action, TaskView
from pybullet_swarm.types import Event, TimeSeries
from pybullet_swarm.world import World


@dataclasses.dataclass(frozen=True)
class TaskContext:
    """What a task runtime is given when it is built.

    Attributes:
        world: the physics world, to add the task's bodies (boxes) and read or constrain them.
        n: number of agents.
        starts: (n, 3) m, the agents' start positions.
        agent_radius: m, radius of the circle enclosing an airframe.
        collision_size: (3,) m, the airframe's collision box.
        arena_size: (2,) m, the arena is [0, Lx] x [0, Ly].
        arena_height: m, the ceiling, or None.
        v_max: (3,) m/s per-axis velocity limit, or None when references are not shaped.
        a_max: (3,) m/s^2 per-axis acceleration limit.
        ghost: agents pass through each other (contacts disabled, overlaps counted).
        position_std: m, per-axis standard deviation of an agent's own position estimate (0 on true state).
        rng: the task's own random generator (derived from the run's seed by name).
    """

    world: World
    n: int
    starts: NDArray[np.float64]
    agent_radius: float
    collision_size: NDArray[np.float64]
    arena_size: NDArray[np.float64]
    arena_height: float | None
    v_max: NDArray[np.float64] | None
    a_max: NDArray[np.float64]
    ghost: bool
    position_std: float
    rng: np.random.Generator


class ScenarioLike(Protocol):
    """The parts of a loaded scenario a task model's ``check(scenario, source)`` may read."""

    @property
    def arena(self) -> Any:
        """The arena section (size, height, obstacles)."""

    @property
    def agents(self) -> Any:
        """The agents section (count, vehicle, starts)."""

    def start_positions(self, rest_height: float) -> NDArray[np.float64]:
        """Start positions (n, 3) m."""


@runtime_checkable
class ChecksScenario(Protocol):
    """A task model that refuses, at load, layouts that cannot work (boxes outside the arena ...)."""

    def check(self, scenario: ScenarioLike, source: str) -> None:
        """Raise ``ConfigError`` naming ``source`` and the field."""


@runtime_checkable
class PublishesPlanInfo(Protocol):
    """A task model that tells, before a run, the static layout the planners will be told."""

    def plan_info(self, vehicle: Any) -> dict[str, Any]:
        """Keyword arguments of ``TaskInfo`` (``depot``, ``slots``, ...) for the vehicle flown."""


#: what ``contact_class`` returns for a body the task does not own
NOT_MINE = "not_mine"


@dataclasses.dataclass(frozen=True)
class Framing:
    """How pictures of the task frame and annotate it (the GUI, a run's video, an environment's render).

    Attributes:
        height: m, height of the working volume a camera frames, None to frame the agents' starts.
        bodies: Bullet body ids of the task's movable objects, in the order of the objects its view shows
            (the GUI colours them by their state (``ConstructionState.object_state``) and who carries them).
        status: one line of the task's progress for a heads-up display ('' when none).
    """

    height: float | None = None
    bodies: tuple[int, ...] = ()
    status: str = ""


@runtime_checkable
class TaskRuntime(Protocol):
    """The runtime of one task kind.

    Attributes:
        completed_at: s, when the task was completed, or None.
        events: task events (grasps, placements, waypoints passed ...), in time order.
        stall_time_s: s, a run whose ``progress`` has not changed for this long ends as stalled (None: never).
    """

    completed_at: float | None
    events: list[Event]
    stall_time_s: float | None

    def task_info(self) -> dict[str, Any]:
        """Keyword arguments of ``TaskInfo``: the task's static layout (``depot``, ``slots``, ``box_size``,
        ``grasp_height``, ``route``, ``extra``) that every agent knows before the run."""

    def update(self, t: float, positions: NDArray[np.float64]) -> bool:
        """Progress at time ``t`` s from the agents' true positions (n, 3) m; True once completed
        (idempotent: calling it twice at one instant judges the same)."""

    def view(self, t: float) -> TaskView:
        """What the task shows at time ``t``."""

    def progress(self) -> int:
        """A count that changes whenever the task advances (as judged by the last ``update``); the clock
        ends a run whose count has not changed for ``stall_time_s``."""

    def refresh(self) -> None:
        """Read the task's bodies now without judging progress (between planner ticks, e.g. for a
        learning environment's observation)."""

    def local_views(
        self, true_positions: NDArray[np.float64], sensed_positions: NDArray[np.float64]
    ) -> Sequence[Any] | None:
        """The objects each agent sees (one of the task's own local view type per agent, ``Observation.seen``) (seen from where its airframe truly is, expressed in the agent's
        own, possibly estimated, frame), or None when the task has no objects to see."""

    def apply(self, agent: int, action: Action, t: float, position: NDArray[np.float64]) -> float | None:
        """Carry out an agent's task action at its true position (3,) m; returns the agent's new payload
        mass kg when it changed (a grasp or a release), else None."""

    def contact_class(self, agent: int, body: int) -> str | None:
        """The collision class (a ``CollisionClass`` value) of a contact between ``agent`` and the task's
        body ``body``, None when it does not count (a carried load and its carrier), ``NOT_MINE`` for a
        body the task does not own."""

    def body_contact_class(self, a: int, b: int) -> str | None:
        """The collision class of a contact between two bodies neither of which is an agent (e.g. a carried
        load touching the structure), None when it does not count or the task does not own them."""

    def sample(self) -> dict[str, NDArray[np.float64]]:
        """Channels to record at the recording rate (e.g. box positions), by name."""

    def metrics(self, series: TimeSeries | None, planner_artefacts: dict[str, Any]) -> dict[str, Any]:
        """The task's metrics of the run (plain JSON data), given the recorded series and what the planner
        published (e.g. a tour planner's ``tour_plan``)."""

    def artefacts(self, planner_artefacts: dict[str, Any]) -> dict[str, Any]:
        """Files the run directory gets, as data by file name (``.json``: plain data, ``.npz``: arrays)."""

    def framing(self) -> Framing:
        """How pictures frame the task now: the camera's height, the bodies to colour, a status line."""


class TaskBase:
    """Defaults for the optional parts of the protocol (a task without objects, actions or files)."""

    completed_at: float | None = None
    stall_time_s: float | None = None

    def task_info(self) -> dict[str, Any]:
        """No static layout beyond the arena."""
        return {}

    def local_views(
        self, true_positions: NDArray[np.float64], sensed_positions: NDArray[np.float64]
    ) -> Sequence[Any] | None:
        """No objects to see (``Observation.seen`` is None)."""
        return None

    def refresh(self) -> None:
        """No bodies to read."""

    def progress(self) -> int:
        """No progress counted (a task without ``stall_time_s`` is never judged stalled)."""
        return 0

    def apply(self, agent: int, action: Action, t: float, position: NDArray[np.float64]) -> float | None:
        """No task actions."""
        return None

    def contact_class(self, agent: int, body: int) -> str | None:
        """The task owns no bodies."""
        return NOT_MINE

    def body_contact_class(self, a: int, b: int) -> str | None:
        """No contact between bodies that are not agents counts."""
        return None

    def sample(self) -> dict[str, NDArray[np.float64]]:
        """Nothing extra to record."""
        return {}

    def artefacts(self, planner_artefacts: dict[str, Any]) -> dict[str, Any]:
        """No files."""
        return {}

    def framing(self) -> Framing:
        """Frame the agents' starts; no bodies, no status."""
        return Framing()


TaskFactory = Callable[[Any, TaskContext], TaskRuntime]
