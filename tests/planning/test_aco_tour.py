"""Tests of pybullet_swarm/planning/aco_tour.py: cost model, split into legs, flying the legs."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.planning.aco_tour import (
    VIA,
    AcoTour,
    AcoTourParams,
    CostModel,
    Metric,
    axis_time,
    bottleneck_assignment,
    split_tour,
)
from pybullet_swarm.planning.base import CommandKind, TaskInfo, TaskView, WorldView
from pybullet_swarm.planning.registry import default_planner
from pybullet_swarm.tasks.tour import TourRuntime, TourTask

V = np.full(3, 0.5)  # m/s
A = np.full(3, 1.0)  # m/s^2


def _is_contiguous_piece(leg: np.ndarray, tour: np.ndarray) -> bool:
    """True when ``leg`` is a run of consecutive cities of the closed ``tour``, in either direction."""
    if len(leg) == 0:
        return True
    W = len(tour)
    pos = {int(c): i for i, c in enumerate(tour)}
    steps = {(pos[int(b)] - pos[int(a)]) % W for a, b in zip(leg[:-1], leg[1:])}
    return steps <= {1} or steps <= {W - 1}


def _instance(W: int, k: int, seed: int):
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(0.2, 3.8, (W, 2)), rng.uniform(0.5, 2.0, W)])
    starts = np.column_stack([rng.uniform(0.2, 3.8, (k, 2)), np.full(k, 0.011)])
    return pts, starts


def test_axis_time_is_the_trapezoid_and_triangle_profile():
    # 2 m at 0.5 m/s, 1 m/s^2: 0.5 s ramps each way (0.125 m each), 1.75 m cruise = 3.5 s -> 4.5 s
    assert axis_time(np.array(2.0), 0.5, 1.0) == pytest.approx(4.5)
    # 0.1 m never reaches 0.5 m/s (the knee is 0.25 m): bang-bang 2 sqrt(0.1 / 1)
    assert axis_time(np.array(0.1), 0.5, 1.0) == pytest.approx(2.0 * np.sqrt(0.1))
    assert axis_time(np.array(0.25), 0.5, 1.0) == pytest.approx(1.0)  # continuous at the knee
    assert axis_time(np.array(-3.0), 0.5, np.inf) == pytest.approx(6.0)  # no acceleration limit: x / v
    assert axis_time(np.array(0.0), 0.5, 1.0) == 0.0


def test_time_metric_is_the_slowest_axis_and_climbs_to_the_safe_altitude():
    cm = CostModel(Metric.TIME, 0.3, V, A)
    # a diagonal costs what its longest axis costs
    assert cm.move(np.zeros(3) + [0, 0, 1], np.array([2.0, 1.0, 1.5])) == pytest.approx(4.5)
    ground, point = np.array([1.0, 1.0, 0.011]), np.array([3.0, 1.0, 1.0])
    ways = cm.waypoints(ground, point)
    assert [w.tolist() for w in ways] == [[1.0, 1.0, 0.3], [3.0, 1.0, 1.0]]  # straight up first
    up = axis_time(np.array(0.289), 0.5, 1.0)
    across = max(axis_time(np.array(2.0), 0.5, 1.0), axis_time(np.array(0.7), 0.5, 1.0))
    assert cm.move(ground, point) == pytest.approx(up + across)
    assert cm.move(point, ground) == pytest.approx(cm.move(ground, point))  # symmetric, as the TSP needs
    # straight above: no via point; both high: no via point
    assert len(cm.waypoints(ground, np.array([1.0, 1.0, 1.0]))) == 1
    assert len(cm.waypoints(point, np.array([2.0, 2.0, 0.5]))) == 1
    length = CostModel(Metric.LENGTH, 0.3, V, A)
    assert length.move(point, np.array([2.0, 2.0, 1.0])) == pytest.approx(np.sqrt(2.0))
    assert CostModel(Metric.TIME, 0.3, np.full(3, np.inf), None).metric is Metric.LENGTH  # no limits: no time


def test_bottleneck_assignment_minimises_the_largest_then_the_total_cost():
    rng = np.random.default_rng(1)
    for _ in range(30):
        k = int(rng.integers(1, 6))
        cost = rng.integers(0, 20, (k, k)).astype(float)
        cols, worst, total = bottleneck_assignment(cost)
        assert sorted(cols.tolist()) == list(range(k))
        best = min(
            (max(cost[i, p[i]] for i in range(k)), sum(cost[i, p[i]] for i in range(k)))
            for p in itertools.permutations(range(k))
        )
        assert (worst, total) == best
        assert cost[np.arange(k), cols].max() == worst


@pytest.mark.parametrize(("W", "k"), [(27, 3), (12, 1), (9, 4), (3, 5), (1, 2), (40, 7)])
def test_legs_cover_every_point_once_as_contiguous_pieces_of_the_tour(W, k):
    pts, starts = _instance(W, k, seed=W * 10 + k)
    cm = CostModel(Metric.TIME, 0.3, V, A)
    rng = np.random.default_rng(0)
    tour = rng.permutation(W)
    legs, worst = split_tour(tour, cm.matrix(pts, pts), cm.matrix(starts, pts))
    assert len(legs) == k
    assert sorted(int(j) for leg in legs for j in leg) == list(range(W))
    assert all(_is_contiguous_piece(leg, tour) for leg in legs)
    if W >= k:
        assert all(len(leg) > 0 for leg in legs)  # nobody idles while there is work
    costs = []
    for i, leg in enumerate(legs):
        c = cm.move(starts[i], pts[leg[0]]) if len(leg) else 0.0
        c += sum(cm.move(pts[a], pts[b]) for a, b in zip(leg[:-1], leg[1:]))
        costs.append(float(c))
    assert max(costs) == pytest.approx(worst)


def _brute_force_makespan(tour, P, approach) -> float:
    """Best makespan over every way to cut ``tour`` into k contiguous legs, assignments and directions."""
    W, k = len(tour), approach.shape[0]
    best = np.inf
    for cuts in itertools.combinations(range(W), k):
        pieces = [np.concatenate([tour, tour])[cuts[j] : (cuts[j + 1] if j + 1 < k else cuts[0] + W)] for j in range(k)]
        for perm in itertools.permutations(range(k)):
            worst = 0.0
            for i, j in enumerate(perm):
                q = pieces[j]
                inner = sum(P[a, b] for a, b in zip(q[:-1], q[1:]))
                worst = max(worst, inner + min(approach[i, q[0]], approach[i, q[-1]]))
            best = min(best, worst)
    return best


@pytest.mark.parametrize("seed", range(6))
def test_split_finds_the_best_contiguous_split_of_small_tours(seed):
    W, k = 8, 2 + seed % 2
    pts, starts = _instance(W, k, seed)
    cm = CostModel(Metric.TIME, 0.3, V, A)
    P, approach = cm.matrix(pts, pts), cm.matrix(starts, pts)
    tour = np.random.default_rng(seed).permutation(W)
    _, worst = split_tour(tour, P, approach)
    assert worst == pytest.approx(_brute_force_makespan(tour, P, approach))


def test_return_home_is_part_of_each_agents_cost():
    pts = np.array([[1.0, 1.0, 1.0], [1.5, 1.0, 1.0], [2.0, 1.0, 1.0], [2.5, 1.0, 1.0]])
    starts = np.array([[0.5, 1.0, 0.011], [3.0, 1.0, 0.011]])
    cm = CostModel(Metric.LENGTH, 0.3, V, A)
    homes = starts.copy()
    homes[:, 2] = 0.3
    legs, _ = split_tour(
        np.arange(4), cm.matrix(pts, pts), cm.matrix(starts, pts), cm.matrix(homes, pts), cm.move(starts, homes)
    )
    assert [leg.tolist() for leg in legs] == [[0, 1], [3, 2]]  # each takes the near half, nearest end first


def _flyable(points, n=3, return_home=False, seed=0, **params):
    spec = TourTask.model_validate(
        {
            "kind": "tour",
            "time_limit_s": 100.0,
            "points": np.asarray(points).tolist(),
            "visit_radius": 0.1,
            "return_home": return_home,
        }
    )
    starts = np.array([[0.6, 0.2, 0.011], [2.0, 0.2, 0.011], [3.4, 0.2, 0.011]])[:n]
    rt = TourRuntime(spec, starts, a_max=A)
    kw = rt.task_info()
    info = TaskInfo(arena_size=np.array([4.0, 4.0]), n_agents=n, agent_radius=0.1, v_max=V, **kw)
    planner = AcoTour(AcoTourParams(iterations=50, **params))
    planner.reset(n, np.random.default_rng(seed), info)
    return rt, planner, starts


def _view(t, positions, rt=None):
    n = len(positions)
    return WorldView(
        t,
        positions.copy(),
        np.zeros((n, 3)),
        np.full(n, -1),
        TaskView(t, np.full(n, -1)) if rt is None else rt.view(t),
    )


def test_agents_climb_first_then_visit_their_legs_in_order_and_publish_the_plan():
    pts = _instance(15, 3, seed=4)[0]
    rt, planner, starts = _flyable(pts)
    pos = starts.copy()
    first = planner.plan_all(_view(0.0, pos))
    assert all(c.kind == CommandKind.POSITION for c in first)
    assert [c.vector.tolist() for c in first] == [[*s[:2], 0.3] for s in starts]  # straight up to safe altitude
    plan = planner.artefacts()["tour_plan"]
    assert plan is not None and plan.metric == "time"
    assert [leg.tolist() for leg in plan.legs] == [leg.tolist() for leg in planner.legs]
    assert all(np.array_equal(p[0], s) for p, s in zip(plan.paths, starts))
    assert all(_is_contiguous_piece(leg, planner.tour) for leg in plan.legs)
    assert rt.metrics(None, planner.artefacts())["planned_length_m"] == pytest.approx(plan.length_m)
    assert plan.planned_time_s > 0
    # perfect tracking: every agent is where it was told to go at the next tick
    t = 0.0
    while not rt.observe(t, pos):
        pos = np.array([c.vector for c in planner.plan_all(_view(t, pos))])
        t += 0.1
        assert t < 20.0
    for i, leg in enumerate(plan.legs):
        mine = [int(e.b[5:]) for e in rt.events if e.kind == "visit" and e.a == f"agent{i}"]
        assert mine == leg.tolist()


def test_points_the_task_already_counted_are_skipped():
    pts = _instance(10, 1, seed=2)[0]
    rt, planner, starts = _flyable(pts, n=1)
    planner.plan_all(_view(0.0, starts))
    leg = planner.legs[0]
    rt.observe(0.0, pts[leg[0]][None, :])  # the task saw point leg[0] visited already
    route = planner.route[0]
    assert route[0][1] == VIA
    assert planner.plan_all(_view(0.1, starts, rt))[0].vector.tolist() == route[0][0].tolist()  # still climbing
    planner.plan_all(_view(0.2, route[0][0][None, :], rt))
    cmd = planner.plan_all(_view(0.3, route[0][0][None, :], rt))[0]
    assert cmd.vector.tolist() == pts[leg[1]].tolist()


def test_return_home_routes_end_at_home_and_complete_there():
    pts = _instance(8, 2, seed=5)[0]
    rt, planner, starts = _flyable(pts, n=2, return_home=True)
    pos = starts.copy()
    t = 0.0
    while not rt.observe(t, pos):
        pos = np.array([c.vector for c in planner.plan_all(_view(t, pos))])
        t += 0.1
        assert t < 20.0
    assert np.allclose(pos, rt.homes)
    assert all(np.allclose(p[-1], h) for p, h in zip(planner.artefacts()["tour_plan"].paths, rt.homes))


def test_same_seed_same_tour_and_legs_different_params_refused():
    pts = _instance(20, 3, seed=7)[0]
    a = _flyable(pts, seed=11)[1]
    b = _flyable(pts, seed=11)[1]
    starts = np.array([[0.6, 0.2, 0.011], [2.0, 0.2, 0.011], [3.4, 0.2, 0.011]])
    assert np.array_equal(a.tour, b.tour)
    assert [x.tolist() for x in a.plan_legs(starts)] == [x.tolist() for x in b.plan_legs(starts)]
    for bad in (
        {"metric": "fastest"},
        {"split": "round-robin"},
        {"ants": 0},
        {"safe_altitude": -1.0},
        {"colour": "red"},
        {"iterations": 10**9},
    ):
        with pytest.raises(ConfigError) as err:
            load_scenario("tour", {f"planner.params.{k}": v for k, v in bad.items()})
        assert err.value.field == f"planner.params.{next(iter(bad))}" and str(err.value).startswith("tour.yaml: ")
    assert default_planner("tour") == "aco_tour"
