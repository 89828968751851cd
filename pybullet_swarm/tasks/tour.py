"""The tour task: visit every inspection point of the arena at least once.

A point counts as visited when the centre of some agent comes within ``visit_radius`` of it.
Between two planner ticks an agent is taken to have flown a straight segment, so a point it
flew through between ticks still counts (a 0.5 m/s agent covers 5 cm per 10 Hz tick). The task
is completed when every point is visited and, with ``return_home``, every agent hovers within
``visit_radius`` of its home point (above its start, at ``home_height``; agents do not land,
because a touch-down would count as a ground contact).

The runtime exposes a :class:`TourBoard` to the planner through ``TaskInfo.extra["tour_board"]``:
the planner publishes the legs it means to fly (:meth:`TourBoard.publish`), the runtime reports
``planned_length_m`` from them and draws them beside the flown paths, and the planner can read
which points the task has already counted (``TourBoard.visited``). Planners use the board by
duck typing; the planning layer does not import this module.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
import pydantic
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.planning.base import TaskView, TourPlan
from pybullet_swarm.planning.views.points import Points
from pybullet_swarm.planning.views.tour import TourLayout
from pybullet_swarm.tasks import register_task
from pybullet_swarm.tasks.base import ScenarioLike, TaskBase, TaskContext
from pybullet_swarm.types import Event, TimeSeries


Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]


class TourTask(pydantic.BaseModel):
    """Scenario section ``task`` of kind ``tour``.

    Attributes:
        kind: ``"tour"``.
        time_limit_s: s, the run ends with TIMEOUT after this.
        points: (W, 3) m, inspection points.
        visit_radius: m, a point is visited when an agent's centre comes this close.
        return_home: also require every agent back above its start at the end.
        home_height: m, altitude of the home points (above each agent's start).
    """

    model_config = pydantic.ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)

    kind: Literal["tour"]
    time_limit_s: float = Field(gt=0.0, le=1e5)
    points: Annotated[list[Vec3], Field(min_length=1, max_length=10_000)]  # m
    visit_radius: float = Field(0.1, gt=0.0, le=10.0)  # m
    return_home: bool = False
    home_height: float = Field(0.3, gt=0.0, le=1e3)  # m

    def check(self, scenario: ScenarioLike, source: str) -> None:
        """Refuse points outside the arena or below the airframe's rest height, and points so
        close together that one visit would count for both."""
        from pybullet_swarm.vehicle import load_vehicle

        vehicle = load_vehicle(scenario.agents.vehicle)
        r = 0.5 * max(vehicle.collision_size[0], vehicle.collision_size[1])  # m, airframe half width
        h = 0.5 * vehicle.collision_size[2]  # m, lowest centre height
        lx, ly = scenario.arena.size
        top = scenario.arena.height
        pts = np.asarray(self.points, dtype=float)
        for i, p in enumerate(pts):
            field = f"task.points[{i}]"
            if not (r - 1e-9 <= p[0] <= lx - r + 1e-9 and r - 1e-9 <= p[1] <= ly - r + 1e-9):
                raise ConfigError(
                    f"point ({p[0]:g}, {p[1]:g}, {p[2]:g}) is outside the arena [0, {lx:g}] x "
                    f"[0, {ly:g}] m (an agent's centre stays {r:g} m inside)",
                    source=source,
                    field=field,
                )
            if p[2] < 0.0:
                raise ConfigError(f"point is below the ground, got z = {p[2]:g}", source=source, field=field)
            if p[2] < h - 1e-9:
                raise ConfigError(
                    f"point must be at least {h:g} m above the ground (an agent's centre cannot "
                    f"go lower), got z = {p[2]:g}",
                    source=source,
                    field=field,
                )
            if top is not None and p[2] > top - h + 1e-9:
                raise ConfigError(
                    f"point is above the ceiling ({top:g} m less {h:g} m), got z = {p[2]:g}", source=source, field=field
                )
        j, k = _first_close_pair(pts, self.visit_radius)
        if j >= 0:
            raise ConfigError(
                f"points {j} and {k} are closer than visit_radius ({self.visit_radius:g} m): one "
                f"visit would count for both",
                source=source,
                field=f"task.points[{k}]",
            )
        if self.return_home:
            if self.home_height < h - 1e-9:
                raise ConfigError(
                    f"must be at least {h:g} m (an agent's centre cannot go lower), got {self.home_height:g}",
                    source=source,
                    field="task.home_height",
                )
            if top is not None and self.home_height > top - h + 1e-9:
                raise ConfigError(
                    f"is above the ceiling ({top:g} m less {h:g} m), got {self.home_height:g}",
                    source=source,
                    field="task.home_height",
                )


def _first_close_pair(pts: NDArray[np.float64], radius: float) -> tuple[int, int]:
    """First pair (j, k), j < k, of points (W, 3) m closer than ``radius`` m; (-1, -1) if none."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(pts).query_pairs(radius * (1.0 - 1e-9))
    if not pairs:
        return -1, -1
    j, k = min(pairs, key=lambda jk: (jk[1], jk[0]))
    return int(j), int(k)


def segment_point_distances(
    a: NDArray[np.float64], b: NDArray[np.float64], points: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Distances (n, W) m from points (W, 3) m to the segments from a (n, 3) to b (n, 3) m."""
    d = (b - a)[:, None, :]  # (n, 1, 3)
    w = points[None, :, :] - a[:, None, :]  # (n, W, 3)
    dd = np.sum(d * d, axis=2)  # (n, 1)
    s = np.where(dd > 0.0, np.sum(w * d, axis=2) / np.where(dd > 0.0, dd, 1.0), 0.0)
    s = np.clip(s, 0.0, 1.0)
    return np.linalg.norm(w - s[:, :, None] * d, axis=2)


class TourRuntime(TaskBase):
    """Which point was visited, by whom and when; completion; tour metrics and figures.

    Args:
        spec: the validated task section.
        starts: (n, 3) m, the agents' start positions.
        a_max: (3,) m/s^2 per-axis acceleration limit (passed on to planners), or None.
        recorder: the run's recorder (flown paths for the figures), or None.
    """

    def __init__(
        self,
        spec: TourTask,
        starts: NDArray[np.float64],
        *,
        a_max: NDArray[np.float64] | None = None,
        arena_size: tuple[float, float] | None = None,
    ) -> None:
        self.spec = spec
        self.points = np.asarray(spec.points, dtype=float)  # (W, 3) m
        self.W = len(self.points)
        self.starts = np.asarray(starts, dtype=float).reshape(-1, 3)
        self.n = len(self.starts)
        self.homes = self.starts.copy()  # (n, 3) m
        self.homes[:, 2] = spec.home_height
        self.visited = np.zeros(self.W, dtype=bool)
        self.visited_by = np.full(self.W, -1, dtype=np.int64)  # agent that visited each point
        self.visited_at = np.full(self.W, np.nan)  # s
        self.a_max = None if a_max is None else np.asarray(a_max, dtype=float).reshape(3)
        self.arena_size = arena_size
        self.completed_at: float | None = None
        self.events: list[Event] = []
        self._prev: NDArray[np.float64] | None = None

    @classmethod
    def build(cls, spec: TourTask, ctx: TaskContext) -> TourRuntime:
        """The runtime factory registered in ``TASK_RUNTIMES``."""
        lx, ly = (float(v) for v in ctx.arena_size)
        return cls(spec, ctx.starts, a_max=ctx.a_max, arena_size=(lx, ly))

    # -------------------------------------------------------------- protocol
    def task_info(self) -> dict[str, Any]:
        """Keyword arguments of ``TaskInfo``: the tour's ``layout`` (points, visit radius, homes)."""
        layout = TourLayout(
            points=self.points.copy(),
            visit_radius=self.spec.visit_radius,
            return_home=self.spec.return_home,
            homes=self.homes.copy(),
            a_max=None if self.a_max is None else self.a_max.copy(),
        )
        return {"layout": layout}

    def observe(self, t: float, positions: NDArray[np.float64]) -> bool:
        """Mark the points agents at ``positions`` (n, 3) m passed since the last call; True once completed."""
        p = np.asarray(positions, dtype=float).reshape(self.n, 3)
        prev = p if self._prev is None else self._prev
        self._prev = p.copy()
        todo = np.flatnonzero(~self.visited)
        if todo.size:
            d = segment_point_distances(prev, p, self.points[todo])  # (n, w)
            agent = np.argmin(d, axis=0)
            best = d[agent, np.arange(todo.size)]
            for j, i, dist in zip(
                todo[best <= self.spec.visit_radius],
                agent[best <= self.spec.visit_radius],
                best[best <= self.spec.visit_radius],
            ):
                self.visited[j] = True
                self.visited_by[j] = i
                self.visited_at[j] = t
                self.events.append(Event(t, "visit", f"agent{i}", f"point{j}", f"{dist * 100:.1f} cm from the point"))
        if self.completed_at is not None:
            return True
        if not self.visited.all():
            return False
        if self.spec.return_home:
            home = np.linalg.norm(p - self.homes, axis=1) <= self.spec.visit_radius
            if not home.all():
                return False
        self.completed_at = t
        self.events.append(Event(t, "tour_complete", "", "", f"{self.W} points visited"))
        return True

    def update(self, t: float, positions: NDArray[np.float64]) -> bool:
        """Planner-tick update from the agents' true positions (n, 3) m; True once completed."""
        return self.observe(t, positions)

    def view(self, t: float) -> TaskView:
        """The points and which of them were visited."""
        return TaskView(t, np.full(self.n, -1, dtype=np.int64), Points(self.points, self.visited.copy()))

    @property
    def points_visited(self) -> int:
        """Number of points visited so far."""
        return int(np.count_nonzero(self.visited))

    def metrics(
        self, timeseries: TimeSeries | None = None, planner_artefacts: dict[str, Any] | None = None
    ) -> dict[str, Any]:
        """Tour metrics (plain JSON data): visits, planned (the planner's published ``tour_plan``) and
        flown lengths, completion time."""
        plan = _plan_of(planner_artefacts)
        flown = None
        flown_per_agent = None
        if timeseries is not None and timeseries.t.size > 1:
            from pybullet_swarm.metrics.flight import path_lengths

            pos = timeseries.positions.astype(float)
            if self.completed_at is not None:
                pos = pos[timeseries.t <= self.completed_at + 1e-6]
            per = path_lengths(pos)
            flown, flown_per_agent = float(per.sum()), [float(x) for x in per]
        times = self.visited_at[self.visited]
        return {
            "points_visited": self.points_visited,
            "points_total": self.W,
            "planned_length_m": plan.length_m if plan is not None else None,
            "planned_time_s": plan.planned_time_s if plan is not None else None,
            "flown_length_m": flown,
            "tour_completion_time_s": self.completed_at,
            "last_visit_s": float(times.max()) if times.size else None,
            "visits_per_agent": [int(np.count_nonzero(self.visited_by == i)) for i in range(self.n)],
            "planned_length_per_agent_m": [float(x) for x in plan.path_lengths_m] if plan is not None else None,
            "flown_length_per_agent_m": flown_per_agent,
        }

    def summary(self, planner_artefacts: dict[str, Any] | None = None) -> dict[str, Any]:
        """Points, plan and visits as plain JSON data (what ``tour.json`` holds)."""
        plan = _plan_of(planner_artefacts)
        return {
            "points": self.points.tolist(),
            "visit_radius": self.spec.visit_radius,
            "starts": self.starts.tolist(),
            "homes": self.homes.tolist() if self.spec.return_home else None,
            "visited_by": self.visited_by.tolist(),
            "visited_at_s": [None if np.isnan(x) else float(x) for x in self.visited_at],
            "plan": None
            if plan is None
            else {
                "metric": plan.metric,
                "tour": plan.tour.tolist(),
                "legs": [leg.tolist() for leg in plan.legs],
                "paths": [p.tolist() for p in plan.paths],
                "planned_time_s": plan.planned_time_s,
            },
        }

    def artefacts(self, planner_artefacts: dict[str, Any]) -> dict[str, Any]:
        """``tour.json``: points, plan and visits (``pybullet-swarm plot`` draws ``plots/tour.png`` from it)."""
        out = self.summary(planner_artefacts)
        out["arena_size"] = list(self.arena_size) if self.arena_size is not None else None
        return {"tour.json": out}


def _plan_of(planner_artefacts: dict[str, Any] | None) -> TourPlan | None:
    plan = (planner_artefacts or {}).get("tour_plan")
    return plan if isinstance(plan, TourPlan) else None


register_task("tour", TourTask, TourRuntime)
