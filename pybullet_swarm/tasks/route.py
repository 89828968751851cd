"""The route task: the swarm migrates through an ordered list of waypoints, as a flock or a formation.

Passing. Waypoint k counts as passed when, after waypoints 0..k-1, the swarm's centroid comes
within ``pass_radius`` (horizontal distance, m) of it (``criterion: centroid``, the course
report's supervisor), or when every agent has passed it itself in order (``every_agent``). The
task is completed when the last waypoint is passed; ``route_time_s`` is that moment.

Formation. With a ``formation`` section the swarm must also hold a shape: each agent has a slot
(an offset, m, from the formation's reference point). The default is the five-robot formation
of the course report (a leader and four robots at 0.15 m / 0.3 m offsets), scaled by ``scale``
from its 7 cm robots to our airframes (2: a 15 cm quadrotor). The slots reach planners through
``RouteLayout.formation_slots`` (``TaskInfo.layout``, centred on their mean).

Metrics (``metrics.json``): ``route_time_s``, ``waypoints_passed``, ``waypoints_total``,
``waypoint_times_s``, ``agents_passed_all`` (agents that passed every waypoint themselves),
``fitness`` (the time average up to completion of the flocking fitness, or of the formation
fitness when a formation is required), ``flocking`` {o, d, v, fitness} and, with a formation,
``formation`` {distance, velocity, error_m, fitness} (all time averages); see
``pybullet_swarm.metrics.flocking``. Collisions with obstacles and between agents are the
simulation's ``collisions.agent_obstacle`` and ``collisions.agent_agent``.
"""

from __future__ import annotations

import enum
from typing import Annotated, Any, Literal

import numpy as np
import pydantic
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.metrics.flocking import route_fitness_series, time_average
from pybullet_swarm.planning.base import TaskView
from pybullet_swarm.planning.views.route import RouteLayout
from pybullet_swarm.planning.views.points import Points
from pybullet_swarm.tasks import register_task
from pybullet_swarm.tasks.base import ScenarioLike, TaskBase, TaskContext
from pybullet_swarm.types import Event, TimeSeries

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]

#: slots (5, 2) m of the course report's formation: robot 0 leads, 1-4 sit at 0.15 m / 0.3 m offsets
SEED_FORMATION = np.array([[0.15, 0.0], [0.0, 0.15], [0.0, -0.15], [0.3, 0.15], [0.3, -0.15]])


class Criterion(str, enum.Enum):
    """When a waypoint counts as passed."""

    CENTROID = "centroid"  # the swarm's centroid comes within pass_radius
    EVERY_AGENT = "every_agent"  # every agent comes within pass_radius itself


class _Model(pydantic.BaseModel):
    model_config = pydantic.ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


class FormationSpec(_Model):
    """Section ``task.formation``: the shape the swarm keeps.

    Attributes:
        slots: (n, 2) or (n, 3) m, each agent's offset from the formation's reference point
            (None: the course report's five-robot formation, for 5 agents).
        scale: the slots are multiplied by this.
    """

    slots: list[Annotated[list[float], Field(min_length=2, max_length=3)]] | None = None
    scale: float = Field(2.0, gt=0.0, le=1e3)

    def slot_array(self) -> NDArray[np.float64]:
        """Slots (n, 3) m, scaled (z 0 when given in 2-D)."""
        raw = SEED_FORMATION if self.slots is None else self.slots
        rows = [list(map(float, r)) + [0.0] * (3 - len(r)) for r in raw]
        return self.scale * np.asarray(rows, dtype=float).reshape(-1, 3)


class RouteTask(_Model):
    """Scenario section ``task`` of kind ``route``.

    Attributes:
        kind: ``"route"``.
        time_limit_s: s, the run ends with TIMEOUT after this.
        waypoints: (W, 3) m, in order; z is the altitude to fly them at.
        pass_radius: m, horizontal distance that counts as passing a waypoint.
        criterion: ``centroid`` or ``every_agent``.
        formation: the shape to keep (None: a flock, no shape).
    """

    kind: Literal["route"]
    time_limit_s: float = Field(gt=0.0, le=1e5)
    waypoints: Annotated[list[Vec3], Field(min_length=1, max_length=10_000)]
    pass_radius: float = Field(0.3, gt=0.0, le=100.0)
    criterion: Literal["centroid", "every_agent"] = "centroid"
    formation: FormationSpec | None = None

    def check(self, scenario: ScenarioLike, source: str) -> None:
        """Refuse waypoints outside the arena, too low or inside an obstacle, and formations that do
        not have one slot per agent or put two agents in one place."""
        from pybullet_swarm.vehicle import load_vehicle

        vehicle = load_vehicle(scenario.agents.vehicle)
        r = float(vehicle.radius)
        h = 0.5 * vehicle.collision_size[2]
        lx, ly = scenario.arena.size
        for i, w in enumerate(self.waypoints):
            field = f"task.waypoints[{i}]"
            if not (0.0 <= w[0] <= lx and 0.0 <= w[1] <= ly):
                raise ConfigError(
                    f"waypoint ({w[0]:g}, {w[1]:g}) is outside the arena [0, {lx:g}] x [0, {ly:g}] m",
                    source=source,
                    field=field,
                )
            if w[2] < h:
                raise ConfigError(
                    f"waypoint must be at least {h:g} m above the ground, got z = {w[2]:g}", source=source, field=field
                )
            if scenario.arena.height is not None and w[2] > scenario.arena.height - h:
                raise ConfigError(
                    f"waypoint is above the ceiling ({scenario.arena.height:g} m), got z = {w[2]:g}",
                    source=source,
                    field=field,
                )
            for k, ob in enumerate(scenario.arena.obstacles):
                if float(ob.horizontal_distance(np.array([w[:2]]))[0]) < r:
                    raise ConfigError(
                        f"waypoint is inside obstacle {k} (closer than {r:.3g} m to it)", source=source, field=field
                    )
        if self.formation is not None:
            slots = self.formation.slot_array()
            n = scenario.agents.count
            if len(slots) != n:
                what = "slots" if self.formation.slots is not None else "default five-robot formation"
                raise ConfigError(
                    f"the {what} hold {len(slots)} agents, the scenario has agents.count = {n}; "
                    f"give one slot per agent",
                    source=source,
                    field="task.formation.slots",
                )
            if n > 1:
                from scipy.spatial import cKDTree

                pairs = cKDTree(slots).query_pairs(2.0 * r)
                if pairs:
                    i, j = min(pairs)
                    raise ConfigError(
                        f"slots {i} and {j} are closer than an airframe's width ({2 * r:.3g} m)",
                        source=source,
                        field="task.formation.slots",
                    )


class RouteRuntime(TaskBase):
    """Which waypoint was passed and when; completion; fitness metrics.

    Args:
        spec: the validated task section.
        n: number of agents.
        v_axis: (3,) m/s per-axis velocity limit (None: unlimited; the velocity metric is then
            normalised by the fastest centroid speed recorded).
    """

    def __init__(self, spec: RouteTask, n: int, v_axis: NDArray[np.float64] | None = None) -> None:
        self.spec = spec
        self.n = int(n)
        self.route = np.asarray(spec.waypoints, dtype=float).reshape(-1, 3)  # (W, 3) m
        self.W = len(self.route)
        self.criterion = Criterion(spec.criterion)
        self.v_axis = None if v_axis is None else np.asarray(v_axis, dtype=float).reshape(3)
        self.slots = spec.formation.slot_array() if spec.formation is not None else None  # (n, 3) m
        self.next = 0  # first waypoint not passed by the swarm
        self.pass_times = np.full(self.W, np.nan)  # s
        self.agent_next = np.zeros(self.n, dtype=np.int64)  # per agent, first waypoint it has not passed
        self.completed_at: float | None = None
        self.events: list[Event] = []

    @classmethod
    def build(cls, spec: RouteTask, ctx: TaskContext) -> RouteRuntime:
        """The runtime factory registered in ``TASK_RUNTIMES``."""
        return cls(spec, ctx.n, ctx.v_max)

    def task_info(self) -> dict[str, Any]:
        """Keyword arguments of ``TaskInfo``: the waypoints as ``route``; pass radius and slots as extras."""
        slots = None if self.slots is None else self.slots - self.slots.mean(axis=0)
        return {"layout": RouteLayout(self.route.copy(), self.spec.pass_radius, slots)}

    def observe(self, t: float, positions: NDArray[np.float64]) -> bool:
        """Advance the waypoints passed by agents at ``positions`` (n, 3) m; True once completed."""
        p = np.asarray(positions, dtype=float).reshape(self.n, 3)
        r = self.spec.pass_radius
        for i in range(self.n):  # per agent, in order (cheap: n scalars per tick)
            while self.agent_next[i] < self.W and np.hypot(*(p[i, :2] - self.route[self.agent_next[i], :2])) <= r:
                self.agent_next[i] += 1
        c = p.mean(axis=0)
        while self.next < self.W:
            if self.criterion is Criterion.CENTROID:
                ok = np.hypot(*(c[:2] - self.route[self.next, :2])) <= r
            else:
                ok = bool(np.all(self.agent_next > self.next))
            if not ok:
                break
            self.pass_times[self.next] = t
            self.events.append(
                Event(t, "waypoint", "", f"waypoint{self.next}", f"{self.criterion.value} within {r:g} m")
            )
            self.next += 1
        if self.next >= self.W and self.completed_at is None:
            self.completed_at = t
            self.events.append(Event(t, "route_complete", "", "", f"{self.W} waypoints passed"))
        return self.completed_at is not None

    def update(self, t: float, positions: NDArray[np.float64]) -> bool:
        """Planner-tick update from the agents' true positions (n, 3) m; True once completed."""
        return self.observe(t, positions)

    def view(self, t: float) -> TaskView:
        """The waypoints and which of them the swarm has passed."""
        return TaskView(t, np.full(self.n, -1, dtype=np.int64), Points(self.route, np.arange(self.W) < self.next))

    def series(self, ts: TimeSeries) -> dict[str, Any]:
        """Per-step fitness series of a recorded run (see ``route_fitness_series``)."""
        return route_fitness_series(
            ts.t,
            ts.positions,
            ts.velocities,
            self.route,
            [None if np.isnan(x) else float(x) for x in self.pass_times],
            self._v_axis(ts),
            self.slots,
        )

    def _v_axis(self, ts: TimeSeries) -> NDArray[np.float64]:
        if self.v_axis is not None:
            return self.v_axis
        vc = np.abs(np.asarray(ts.velocities, dtype=float).mean(axis=1))
        return np.maximum(vc.max(axis=0), 1e-9) if vc.size else np.ones(3)

    def metrics(
        self, timeseries: TimeSeries | None = None, planner_artefacts: dict[str, Any] | None = None
    ) -> dict[str, Any]:
        """Route and fitness metrics (plain JSON data)."""
        out: dict[str, Any] = {
            "route_time_s": self.completed_at,
            "waypoints_passed": int(self.next),
            "waypoints_total": self.W,
            "waypoint_times_s": [None if np.isnan(x) else float(x) for x in self.pass_times],
            "agents_passed_all": int(np.count_nonzero(self.agent_next >= self.W)),
            "fitness": None,
            "flocking": None,
        }
        if self.slots is not None:
            out["formation"] = None
        if timeseries is None or timeseries.t.size == 0:
            return out
        s = self.series(timeseries)
        end = self.completed_at
        avg = {k: time_average(s["t"], x, end) for k, x in s["flocking"].items()}
        out["flocking"] = avg
        out["fitness"] = avg["fitness"]
        if s["formation"] is not None:
            f = {k: time_average(s["t"], x, end) for k, x in s["formation"].items()}
            out["formation"] = {
                "distance": f["distance"],
                "velocity": f["velocity"],
                "error_m": f["error"],
                "fitness": f["fitness"],
            }
            out["fitness"] = f["fitness"]
        return out


register_task("route", RouteTask, RouteRuntime)
