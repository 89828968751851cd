"""The flock task: the swarm flies as a flock inside a bounded arena for the whole run.

Nothing is to be reached: the run lasts ``time_limit_s`` and is judged by the order parameters
of Vásárhelyi et al. (2018) and SwarmLab (``pybullet_swarm.metrics.flock``), time-averaged over
the samples after ``warmup_s`` (take-off and the first sorting out of the flock). The arena is
the scenario's ``arena.size`` (give it ``arena.walls: true`` for physical walls); pillars are the
scenario's ``arena.obstacles``.

Agents are told (``TaskInfo.layout``, a ``FlockLayout``): ``altitude`` (m), ``v_flock`` (m/s, the
preferred speed every flocking planner flies at unless its own parameter says otherwise), ``r_coll``
(m) and ``connection_range_m`` (m). Its ``route`` is a circuit: laps of a circle around the
arena's centre at the flight altitude, which planners with a migratory urge (``reynolds``) follow
and ``olfati_saber``'s virtual leader flies; ``vasarhelyi`` is self-propelled and ignores it.

Metrics (``metrics.json``): ``flock`` with exactly the keys of ``FLOCK_KEYS``, and
``flock_min_distance_m``: the closest any pair came after the warm-up, m.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar, Literal

import numpy as np
import pydantic
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.metrics.flock import FLOCK_KEYS, FitnessTolerances, flock_metrics, order_series
from pybullet_swarm.planning.base import TaskView
from pybullet_swarm.planning.views.route import FlockLayout
from pybullet_swarm.tasks import register_task
from pybullet_swarm.tasks.base import ScenarioLike, TaskBase, TaskContext
from pybullet_swarm.types import Event, TimeSeries

#: waypoints per lap of the circuit the task publishes as the route of its ``FlockLayout``
CIRCUIT_POINTS = 8
#: m, a waypoint of the circuit counts as reached this close (``FlockLayout.pass_radius``)
CIRCUIT_PASS_RADIUS = 1.0


class FlockTask(pydantic.BaseModel):
    """Scenario section ``task`` of kind ``flock``.

    Attributes:
        kind: ``"flock"``.
        time_limit_s: s, the run lasts this long (it ends with TIMEOUT, the expected outcome).
        warmup_s: s, samples before this are left out of the time averages.
        altitude: m, the flock flies at this height.
        v_flock: m/s, the preferred flocking speed (planners' default, the fitness's speed target).
        r_coll: m, two agents' centres closer than this count as a collision.
        connection_range_m: m, agents this close are connected (clusters, neighbours of the metrics).
        v_tol: m/s, width of the speed factor of the fitness.
        r_tol: m, width of the wall factor of the fitness.
        a_tol: collision ratio at which the collision factor of the fitness is 1/4.
    """

    model_config = pydantic.ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)

    #: what a tuning study of this task optimises by default: (objective, direction, penalty of a run that does
    #: not complete; a flock never completes, so none)
    TUNE_OBJECTIVE: ClassVar[tuple[str, str, float]] = ("flock.fitness", "maximize", 0.0)

    kind: Literal["flock"]
    time_limit_s: float = Field(gt=0.0, le=1e5)
    warmup_s: float = Field(30.0, ge=0.0, le=1e5)
    altitude: float = Field(1.0, gt=0.0, le=1e3)
    v_flock: float = Field(0.6, gt=0.0, le=100.0)
    r_coll: float = Field(0.3, gt=0.0, le=100.0)
    connection_range_m: float = Field(8.0, gt=0.0, le=1e4)
    v_tol: float = Field(0.15, gt=0.0, le=100.0)
    r_tol: float = Field(0.15, gt=0.0, le=1e3)
    a_tol: float = Field(3e-5, gt=0.0, le=1.0)

    def check(self, scenario: ScenarioLike, source: str) -> None:
        """Refuse a warm-up as long as the run, a flight altitude above the walls or the ceiling."""
        if self.warmup_s >= self.time_limit_s:
            raise ConfigError(
                f"must be shorter than task.time_limit_s ({self.time_limit_s:g} s), got {self.warmup_s:g}",
                source=source,
                field="task.warmup_s",
            )
        arena = scenario.arena
        if arena.height is not None and self.altitude >= arena.height:
            raise ConfigError(
                f"must be below the ceiling arena.height ({arena.height:g} m), got {self.altitude:g}",
                source=source,
                field="task.altitude",
            )
        if arena.walls and self.altitude >= arena.wall_height:
            raise ConfigError(
                f"must be below the walls (arena.wall_height {arena.wall_height:g} m), got {self.altitude:g}",
                source=source,
                field="task.altitude",
            )

    def tolerances(self) -> FitnessTolerances:
        """The fitness's targets and tolerances."""
        return FitnessTolerances(v_flock=self.v_flock, v_tol=self.v_tol, r_tol=self.r_tol, a_tol=self.a_tol)


class FlockRuntime(TaskBase):
    """Publishes the flight conditions of the flock and scores the run's order parameters.

    Args:
        spec: the validated task section.
        n: number of agents.
        arena_size: (2,) m.
    """

    def __init__(self, spec: FlockTask, n: int, arena_size: NDArray[np.float64]) -> None:
        self.spec = spec
        self.n = int(n)
        self.arena_size = np.asarray(arena_size, dtype=float).reshape(2)
        self.completed_at: float | None = None
        self.events: list[Event] = []

    @classmethod
    def build(cls, spec: FlockTask, ctx: TaskContext) -> FlockRuntime:
        """The runtime factory registered in ``TASK_RUNTIMES``."""
        return cls(spec, ctx.n, ctx.arena_size)

    def circuit_radius(self) -> float:
        """m, radius of the circuit: a quarter of the arena's smaller side."""
        return 0.25 * float(self.arena_size.min())

    def circuit(self) -> NDArray[np.float64]:
        """(W, 3) m: laps of a circle around the arena's centre (radius a quarter of its smaller side, at the
        flight altitude), enough for the whole run at v_flock; planners with a migratory urge follow it."""
        s = self.spec
        centre = 0.5 * self.arena_size
        radius = self.circuit_radius()
        laps = max(1, math.ceil(s.v_flock * s.time_limit_s / (2.0 * math.pi * radius)) + 1)
        a = 2.0 * math.pi * np.arange(laps * CIRCUIT_POINTS) / CIRCUIT_POINTS
        return np.column_stack(
            [centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a), np.full(a.size, s.altitude)]
        )

    def task_info(self) -> dict[str, Any]:
        """The circuit as the route of a ``FlockLayout``, with the flight altitude, speed, collision distance and
        connection range."""
        s = self.spec
        centre = 0.5 * self.arena_size
        layout = FlockLayout(
            route=self.circuit(),
            pass_radius=CIRCUIT_PASS_RADIUS,
            circuit=(float(centre[0]), float(centre[1]), self.circuit_radius()),
            altitude=s.altitude,
            v_flock=s.v_flock,
            r_coll=s.r_coll,
            connection_range_m=s.connection_range_m,
        )
        return {"layout": layout}

    def update(self, t: float, positions: NDArray[np.float64]) -> bool:
        """Never completed: the flock flies until the time limit."""
        return False

    def view(self, t: float) -> TaskView:
        """Nothing to show beyond the time."""
        return TaskView(t, np.full(self.n, -1, dtype=np.int64))

    def series(self, ts: TimeSeries) -> dict[str, NDArray[np.float64]]:
        """Every order parameter per recorded sample (see ``order_series``)."""
        s = self.spec
        return order_series(
            ts.positions,
            ts.velocities,
            arena_size=self.arena_size,
            r_coll=s.r_coll,
            connection_range=s.connection_range_m,
        )

    def metrics(self, timeseries: TimeSeries | None, planner_artefacts: dict[str, Any] | None = None) -> dict[str, Any]:
        """``flock`` (the time averages after the warm-up and the fitness) and ``flock_min_distance_m``."""
        if timeseries is None or timeseries.t.size == 0:
            return {"flock": {k: None for k in FLOCK_KEYS}, "flock_min_distance_m": None}
        s = self.series(timeseries)
        keep = np.asarray(timeseries.t, dtype=float) >= self.spec.warmup_s - 1e-9
        closest = float(np.min(s["min_distance_m"][keep])) if np.any(keep) and self.n > 1 else None
        return {
            "flock": flock_metrics(s, timeseries.t, self.spec.warmup_s, self.n, self.spec.tolerances()),
            "flock_min_distance_m": closest,
        }


register_task("flock", FlockTask, FlockRuntime)
