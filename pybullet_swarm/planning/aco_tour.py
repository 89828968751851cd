"""ACO tour: an ant colony orders the inspection points, k agents fly contiguous legs of the tour.

Planning happens once. At ``reset`` the colony (:func:`~pybullet_swarm.planning.aco.solve_tsp`,
seeded from the run's generator) finds a short closed tour through the points of
``TourLayout.points`` (``TaskInfo.layout``). At the first tick, when the agents' start positions are known, the tour is
cut into k contiguous legs, one per agent (:func:`split_tour`): the cuts and the assignment of
agents to legs minimise the slowest agent's cost, approach from its start (and return home, if
the task asks for it) included. Then every agent flies its leg point by point with position
commands through the usual reference shaper and controller; a point is done when the agent's
centre is within the task's ``visit_radius`` (or when the task has already counted it).

Cost metric. The reference shaper limits each axis separately (velocity ``v_k``, acceleration
``a_k``) and every target is approached with a braking curve, so flying a displacement ``d``
from rest to rest takes ``max_k tau(|d_k|; v_k, a_k)`` with the trapezoid-profile time
``tau(x) = x / v + v / a`` (``2 sqrt(x / a)`` below ``v^2 / a``): a Chebyshev-like metric, not
Euclidean length. The default ``metric: time`` plans on that time, because completion time is
what a tour is judged by and a diagonal costs no more than its longest axis; the path an agent
flies is then a "dog-leg" (the short axes finish first), so flown length exceeds the Euclidean
plan. ``metric: length`` plans on 3-D Euclidean length instead. Either way the split balances
the same metric, and ``planned_length_m`` is the Euclidean length of the planned polylines.

Safe altitude. Horizontal flight happens at or above ``safe_altitude``: a move whose start or
end lies lower (take-off from the ground, a low point) first climbs vertically, crosses, then
descends vertically. These via points are part of the plan, its cost and its published paths.
"""

from __future__ import annotations

import enum
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import Field
from scipy.optimize import linear_sum_assignment

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.planning.aco import ACOParams, solve_tsp
from pybullet_swarm.planning.base import Command, TourPlan, WorldView
from pybullet_swarm.planning.views.points import Points
from pybullet_swarm.planning.views.tour import TourInfo, TourLayout

VIA = -1  # waypoint tag: a climb/descent point, not an inspection point
HOME = -2  # waypoint tag: the agent's home point


class Metric(enum.Enum):
    """What the colony and the split minimise."""

    TIME = "time"  # rest-to-rest flight time under the per-axis limits, s
    LENGTH = "length"  # Euclidean length, m


class Split(enum.Enum):
    """How the tour is shared among the agents."""

    CONTIGUOUS = "contiguous"  # k contiguous legs of one closed tour


def axis_time(x: NDArray[np.float64], v_max: float, a_max: float) -> NDArray[np.float64]:
    """Rest-to-rest time s to travel distances x (...) m along one axis with a trapezoid profile.

    ``v_max`` m/s and ``a_max`` m/s^2 may be infinite (no limit), not both.
    """
    x = np.abs(np.asarray(x, dtype=float))
    if not np.isfinite(a_max):
        return x / v_max
    if not np.isfinite(v_max):
        return 2.0 * np.sqrt(x / a_max)
    knee = v_max * v_max / a_max  # m, shortest distance that reaches v_max
    return np.where(x >= knee, x / v_max + v_max / a_max, 2.0 * np.sqrt(x / a_max))


class CostModel:
    """Cost of moves between 3-D positions: time or length, with climbs to a safe altitude.

    Args:
        metric: what a move costs.
        safe_altitude: m, horizontal moves happen at or above it.
        v_max: (3,) m/s per-axis velocity limit (inf: none).
        a_max: (3,) m/s^2 per-axis acceleration limit (inf or None: none).
    """

    def __init__(
        self, metric: Metric, safe_altitude: float, v_max: NDArray[np.float64], a_max: NDArray[np.float64] | None
    ) -> None:
        self.v = np.broadcast_to(np.asarray(v_max, dtype=float), (3,)).copy()
        self.a = np.full(3, np.inf) if a_max is None else np.broadcast_to(np.asarray(a_max, dtype=float), (3,)).copy()
        self.time_defined = bool(np.all(np.isfinite(self.v) | np.isfinite(self.a)))
        if metric is Metric.TIME and not self.time_defined:
            metric = Metric.LENGTH  # no limits: flight time is not defined by the shaper
        self.metric = metric
        self.h = float(safe_altitude)

    def segment(self, d: NDArray[np.float64], metric: Metric | None = None) -> NDArray[np.float64]:
        """Cost (...) of straight moves by displacements d (..., 3) m."""
        metric = self.metric if metric is None else metric
        if metric is Metric.LENGTH:
            return np.linalg.norm(d, axis=-1)
        t = [axis_time(d[..., k], self.v[k], self.a[k]) for k in range(3)]
        return np.maximum(np.maximum(t[0], t[1]), t[2])

    def _raised(
        self, a: NDArray[np.float64], b: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Via points (..., 3) above a and b: at the safe altitude when a move must climb first."""
        horizontal = np.linalg.norm(b[..., :2] - a[..., :2], axis=-1) > 1e-9
        a2, b2 = a.copy(), b.copy()
        a2[..., 2] = np.where(horizontal, np.maximum(a[..., 2], self.h), a[..., 2])
        b2[..., 2] = np.where(horizontal, np.maximum(b[..., 2], self.h), b[..., 2])
        return a2, b2

    def move(self, a: NDArray[np.float64], b: NDArray[np.float64], metric: Metric | None = None) -> NDArray[np.float64]:
        """Cost (...) of moves from a (..., 3) to b (..., 3) m, climbs included (broadcasts)."""
        a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
        a2, b2 = self._raised(a, b)
        return self.segment(a2 - a, metric) + self.segment(b2 - a2, metric) + self.segment(b - b2, metric)

    def matrix(
        self, p: NDArray[np.float64], q: NDArray[np.float64], metric: Metric | None = None
    ) -> NDArray[np.float64]:
        """(len(p), len(q)) costs of moves from each of p (P, 3) to each of q (Q, 3) m."""
        return self.move(p[:, None, :], q[None, :, :], metric)

    def waypoints(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """The positions (3,) m to fly through from a to b: the via points that differ, then b."""
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        a2, b2 = self._raised(a, b)
        out = []
        if np.linalg.norm(a2 - a) > 1e-9:
            out.append(a2)  # climb above a
        if np.linalg.norm(b2 - b) > 1e-9:
            out.append(b2)  # cross above b, then descend
        return [*out, b]


def bottleneck_assignment(cost: NDArray[np.float64]) -> tuple[NDArray[np.int64], float, float]:
    """Assign row i to column ``cols[i]`` minimising the largest cost, then the sum.

    Args:
        cost: (k, k) costs.

    Returns:
        cols (k,), the largest assigned cost and the sum of the assigned costs.
    """
    values = np.unique(cost)
    lo, hi = 0, len(values) - 1
    while lo < hi:  # smallest threshold that still admits a perfect matching
        mid = (lo + hi) // 2
        over = cost > values[mid]
        r, c = linear_sum_assignment(over)
        if over[r, c].any():
            lo = mid + 1
        else:
            hi = mid
    limit = values[lo]
    capped = np.where(cost <= limit, cost, np.inf)
    capped[np.isinf(capped)] = 1.0 + 2.0 * float(np.abs(cost).sum())
    r, c = linear_sum_assignment(capped)
    cols = np.empty(len(r), dtype=np.int64)
    cols[r] = c
    return cols, float(limit), float(cost[r, c].sum())


class _LegCosts:
    """Costs of contiguous pieces of a closed tour for each agent (prefix sums on the tour)."""

    def __init__(
        self,
        tour: NDArray[np.int64],
        point_cost: NDArray[np.float64],
        approach: NDArray[np.float64],
        home: NDArray[np.float64],
        idle: NDArray[np.float64],
    ) -> None:
        self.W = len(tour)
        self.tour2 = np.concatenate([tour, tour]).astype(np.int64)  # unrolled twice
        edges = point_cost[self.tour2[:-1], self.tour2[1:]]
        self.prefix = np.concatenate([[0.0], np.cumsum(edges)])  # cost from position 0 to t
        self.approach, self.home, self.idle = approach, home, idle

    def matrix(self, cuts: NDArray[np.int64]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """(agents, pieces) costs and whether each is flown backwards, for pieces [c_j, c_j+1)."""
        k = len(cuts)
        ends = np.append(cuts[1:], cuts[0] + self.W)
        cost = np.empty((self.approach.shape[0], k))
        backwards = np.zeros_like(cost, dtype=bool)
        for j, (u, v) in enumerate(zip(cuts, ends)):
            if v <= u:
                cost[:, j] = self.idle
                continue
            first, last = self.tour2[u], self.tour2[v - 1]
            inner = self.prefix[v - 1] - self.prefix[u]
            fwd = self.approach[:, first] + inner + self.home[:, last]
            bwd = self.approach[:, last] + inner + self.home[:, first]
            cost[:, j] = np.minimum(fwd, bwd)
            backwards[:, j] = bwd < fwd
        return cost, backwards

    def score(self, cuts: NDArray[np.int64]) -> tuple[float, float]:
        """(makespan, total) of the best assignment for these cuts."""
        cost, _ = self.matrix(cuts)
        _, worst, total = bottleneck_assignment(cost)
        return worst, total


def _equal_cuts(W: int, k: int, start: int, prefix: NDArray[np.float64] | None) -> NDArray[np.int64]:
    """k cut positions from ``start``: equal numbers of points, or equal inner cost along ``prefix``."""
    if prefix is None:
        sizes = np.full(k, W // k)
        sizes[: W % k] += 1
        return start + np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    seg = prefix[start : start + W] - prefix[start]
    goals = seg[-1] * np.arange(1, k) / k
    inner = np.searchsorted(seg, goals, side="left")
    return np.concatenate([[start], start + np.maximum.accumulate(np.clip(inner, 0, W))]).astype(np.int64)


def split_tour(
    tour: NDArray[np.int64],
    point_cost: NDArray[np.float64],
    approach: NDArray[np.float64],
    home: NDArray[np.float64] | None = None,
    idle: NDArray[np.float64] | None = None,
    *,
    restarts: int = 4,
    max_moves: int = 10_000,
) -> tuple[list[NDArray[np.int64]], float]:
    """Cut a closed tour into one contiguous leg per agent, balancing the agents' costs.

    An agent's cost is its approach from its start to the first point of its leg, the leg itself,
    and (with ``home``) the way home from the leg's last point; each leg may be flown in either
    direction. Cuts start from equal splits at every rotation of the tour; the best ``restarts``
    are improved by moving single cuts one position at a time while the largest agent cost (then
    the sum) decreases. Agents are assigned to legs by bottleneck assignment. Deterministic.

    Args:
        tour: (W,) point indices of a closed tour.
        point_cost: (W, W) cost of moving between points.
        approach: (k, W) cost of agent i reaching point j from its start.
        home: (k, W) cost from point j to agent i's home (None: agents stay at their last point).
        idle: (k,) cost of an agent without points (None: 0).
        restarts: how many starting splits are improved.
        max_moves: bound on improving moves per restart.

    Returns:
        Per agent, (m_i,) point indices in flight order (empty when it has no points); and the
        largest agent cost.
    """
    tour = np.asarray(tour, dtype=np.int64).reshape(-1)
    k, W = approach.shape[0], len(tour)
    home = np.zeros_like(approach) if home is None else home
    idle = np.zeros(k) if idle is None else np.asarray(idle, dtype=float)
    legs = _LegCosts(tour, point_cost, approach, home, idle)
    seen: dict[tuple[int, ...], tuple[float, float]] = {}

    def score(c: NDArray[np.int64]) -> tuple[float, float]:
        key = tuple(int(x) for x in c)
        if key not in seen:
            seen[key] = legs.score(c)
        return seen[key]

    starts = [_equal_cuts(W, k, r, p) for r in range(W) for p in (None, legs.prefix)]
    starts.sort(key=lambda c: (*score(c), tuple(c)))
    eps = 1e-9 * max(1.0, float(np.max(point_cost, initial=0.0)))
    best_cuts, best = starts[0], score(starts[0])
    for cuts in starts[:restarts]:
        cur = score(cuts)
        for _ in range(max_moves):
            moved = False
            for j in range(k):
                for step in (-1, 1):
                    c = cuts.copy()
                    c[j] += step
                    ends = np.append(c[1:], c[0] + W)
                    lows = np.concatenate([[c[-1] - W], c[:-1]])
                    if np.any(c > ends) or np.any(c < lows):
                        continue
                    c -= W * (c[0] // W)  # keep the first cut in [0, W)
                    s = score(c)
                    if s[0] < cur[0] - eps or (s[0] <= cur[0] + eps and s[1] < cur[1] - eps):
                        cuts, cur, moved = c, s, True
            if not moved:
                break
        if cur[0] < best[0] - eps or (cur[0] <= best[0] + eps and cur[1] < best[1] - eps):
            best_cuts, best = cuts, cur
    cost, backwards = legs.matrix(best_cuts)
    cols, worst, _ = bottleneck_assignment(cost)
    ends = np.append(best_cuts[1:], best_cuts[0] + W)
    out = []
    for i in range(k):
        j = cols[i]
        seq = legs.tour2[best_cuts[j] : ends[j]].copy()
        out.append(seq[::-1].copy() if backwards[i, j] else seq)
    return out, worst


class AcoTourParams(ACOParams):
    """Parameters of the ``aco_tour`` planner: the tour's cost and split, and the colony's settings
    (those of :class:`~pybullet_swarm.planning.aco.ACOParams`)."""

    metric: Metric = Field(
        Metric.TIME,
        strict=False,
        description="what the colony and the split minimise: time (rest-to-rest flight time "
        "under the per-axis limits) or length (Euclidean)",
    )
    split: Split = Field(
        Split.CONTIGUOUS, strict=False, description="how agents share the tour: contiguous (one leg of the tour each)"
    )
    safe_altitude: float = Field(
        0.3, ge=0.0, le=1e4, description="m, horizontal moves happen at or above it (take-off climbs to it first)"
    )
    via_tolerance: float = Field(
        0.05, ge=1e-6, le=10.0, description="m, distance at which a climb/descent point counts as reached"
    )


class AcoTour:
    """Centralised tour planner: ACO order, contiguous legs per agent, fly them point by point.

    Args:
        params: validated ``AcoTourParams`` (default: the defaults).
    """

    name: ClassVar[str] = "aco_tour"
    centralized: ClassVar[bool] = True
    Params: ClassVar[type[AcoTourParams]] = AcoTourParams

    def __init__(self, params: AcoTourParams | None = None) -> None:
        self.params = params if params is not None else AcoTourParams()
        self.metric = self.params.metric
        self.split = self.params.split
        self.safe_altitude = float(self.params.safe_altitude)
        self.via_tolerance = float(self.params.via_tolerance)
        self.aco = ACOParams(**{k: getattr(self.params, k) for k in ACOParams.model_fields})

    def reset(self, n: int, rng: np.random.Generator, info: TourInfo) -> None:
        """Order the points of the tour (``info.layout.points``) with the colony (legs are cut at the first tick)."""
        tour = info.layout
        pts = np.asarray(tour.points, dtype=float).reshape(-1, 3) if isinstance(tour, TourLayout) else np.zeros((0, 3))
        if len(pts) == 0:
            raise ConfigError("the aco_tour planner needs points to visit (a tour task's layout)", field="task")
        self.n = n
        self.points = pts  # (W, 3) m
        self.radius = float(tour.visit_radius)  # m
        self.plan: TourPlan | None = None  # published once the legs are cut
        self.points_done = np.zeros(len(pts), dtype=bool)  # what the task counts as visited
        self.return_home = bool(tour.return_home)
        self.homes = tour.homes  # (n, 3) m
        self.costs = CostModel(self.metric, self.safe_altitude, info.v_max, tour.a_max)
        self.point_cost = self.costs.matrix(pts, pts)  # (W, W)
        self.result = solve_tsp(self.point_cost, self.aco, rng=rng)
        self.tour = self.result.tour  # (W,) closed tour
        self.starts: NDArray[np.float64] | None = None  # (n, 3) m, positions at the first tick
        self.legs: list[NDArray[np.int64]] | None = None
        self.route: list[list[tuple[NDArray[np.float64], int]]] = []  # per agent: (position, tag) to fly
        self.cursor = np.zeros(n, dtype=np.int64)
        self.done = np.zeros(len(pts), dtype=bool)  # points this planner saw reached
        self.planned_makespan: float | None = None

    # ---------------------------------------------------------------- planning
    def plan_legs(self, starts: NDArray[np.float64]) -> list[NDArray[np.int64]]:
        """Cut the tour into one leg per agent for agents starting at ``starts`` (n, 3) m; publish the plan."""
        starts = np.asarray(starts, dtype=float).reshape(self.n, 3)
        approach = self.costs.matrix(starts, self.points)
        home = idle = None
        homes = None
        if self.return_home:
            homes = np.asarray(self.homes if self.homes is not None else starts, dtype=float).reshape(self.n, 3)
            home = self.costs.matrix(homes, self.points)  # symmetric: point -> home
            idle = self.costs.move(starts, homes)
        self.legs, _ = split_tour(self.tour, self.point_cost, approach, home, idle)
        self.route = [self._route(starts[i], self.legs[i], None if homes is None else homes[i]) for i in range(self.n)]
        paths = [np.vstack([starts[i], *[p for p, _ in self.route[i]]]) for i in range(self.n)]
        if self.costs.time_defined:
            self.planned_makespan = max(float(self.costs.segment(np.diff(p, axis=0), Metric.TIME).sum()) for p in paths)
        self.plan = TourPlan(
            np.asarray(self.tour, dtype=np.int64).reshape(-1),
            tuple(np.asarray(leg, dtype=np.int64).reshape(-1) for leg in self.legs),
            tuple(np.asarray(p, dtype=float).reshape(-1, 3) for p in paths),
            None if self.planned_makespan is None else float(self.planned_makespan),
            self.costs.metric.value,
        )
        return self.legs

    def _route(
        self, start: NDArray[np.float64], leg: NDArray[np.int64], home: NDArray[np.float64] | None
    ) -> list[tuple[NDArray[np.float64], int]]:
        """Positions to fly through (3,) m with their tags: point index, VIA or HOME."""
        out: list[tuple[NDArray[np.float64], int]] = []
        here = start
        for j in leg:
            ways = self.costs.waypoints(here, self.points[j])
            out += [(w, VIA) for w in ways[:-1]] + [(ways[-1], int(j))]
            here = self.points[j]
        if home is not None:
            ways = self.costs.waypoints(here, home)
            out += [(w, VIA) for w in ways[:-1]] + [(ways[-1], HOME)]
        return out

    # ------------------------------------------------------------------ flying
    def _reached(self, tag: int, target: NDArray[np.float64], p: NDArray[np.float64]) -> bool:
        if tag == HOME:
            return False  # hold it; the task judges completion
        if tag == VIA:
            return bool(np.linalg.norm(p - target) <= self.via_tolerance)
        counted = bool(self.points_done[tag])
        if counted or np.linalg.norm(p - target) <= self.radius:
            self.done[tag] = True
        return bool(self.done[tag])

    def _command(self, i: int, p: NDArray[np.float64], start: NDArray[np.float64]) -> Command:
        route = self.route[i]
        while self.cursor[i] < len(route) and self._reached(route[self.cursor[i]][1], route[self.cursor[i]][0], p):
            self.cursor[i] += 1
        if self.cursor[i] < len(route):
            return Command.goto(route[self.cursor[i]][0])
        return Command.goto(route[-1][0] if route else start)

    def plan_all(self, view: WorldView) -> list[Command]:
        """One position command per agent."""
        shown = view.task.state
        if isinstance(shown, Points) and shown.points_done.shape == self.points_done.shape:
            self.points_done = shown.points_done
        if self.starts is None:
            self.starts = view.positions.copy()
            self.plan_legs(self.starts)
        return [self._command(i, view.positions[i], self.starts[i]) for i in range(self.n)]

    def artefacts(self) -> dict[str, Any]:
        """The published plan (``tour_plan``: legs, paths, planned time), once the legs are cut."""
        return {} if self.plan is None else {"tour_plan": self.plan}


from pybullet_swarm.planning.registry import register_planner  # noqa: E402

register_planner(
    "aco_tour",
    AcoTour,
    "centralised: ant colony orders the tour points, k agents fly contiguous legs of it",
    ("tour",),
    default_for=("tour",),
)
