"""The tour task: visits, completion, validation, the bundled scenario flown end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest

import pybullet_swarm
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.tasks.tour import TourRuntime, TourTask, segment_point_distances
from pybullet_swarm.types import ExitStatus

POINTS = [[1.0, 1.0, 1.0], [2.0, 1.0, 1.5], [2.0, 2.0, 0.5]]


def _runtime(**kw) -> TourRuntime:
    spec = TourTask.model_validate({"kind": "tour", "time_limit_s": 60.0, "points": POINTS, "visit_radius": 0.1, **kw})
    return TourRuntime(spec, np.array([[0.5, 0.5, 0.011], [3.0, 0.5, 0.011]]))


def test_runtime_marks_visits_by_agent_and_time_and_completes_on_the_last_one():
    rt = _runtime()
    far = np.array([[0.5, 0.5, 0.011], [3.0, 0.5, 0.011]])
    assert not rt.observe(0.0, far)
    assert not rt.observe(0.1, [[1.05, 1.0, 1.0], [3.0, 0.5, 0.5]])  # agent 0 at point 0 (5 cm)
    assert not rt.observe(0.2, [[1.5, 1.5, 1.0], [2.0, 1.0, 1.58]])  # agent 1 at point 1 (8 cm)
    assert not rt.observe(0.3, [[2.0, 2.0, 0.75], [2.0, 1.0, 1.5]])  # 25 cm from point 2: not yet
    assert rt.observe(0.4, [[2.0, 2.0, 0.55], [2.0, 1.0, 1.5]])
    assert rt.completed_at == pytest.approx(0.4)
    assert rt.visited_by.tolist() == [0, 1, 0]
    assert rt.visited_at.tolist() == pytest.approx([0.1, 0.2, 0.4])
    visits = [(e.time_s, e.a, e.b) for e in rt.events if e.kind == "visit"]
    assert visits == [(0.1, "agent0", "point0"), (0.2, "agent1", "point1"), (0.4, "agent0", "point2")]
    assert rt.observe(0.5, far)  # stays completed
    m = rt.metrics()
    assert (m["points_visited"], m["points_total"]) == (3, 3)
    assert m["tour_completion_time_s"] == pytest.approx(0.4)
    assert m["visits_per_agent"] == [2, 1]
    assert m["planned_length_m"] is None  # no planner published a plan


def test_a_point_flown_through_between_two_ticks_counts():
    rt = _runtime()
    rt.observe(0.0, [[0.6, 1.0, 1.0], [3.0, 0.5, 0.011]])
    rt.observe(0.1, [[1.4, 1.0, 1.0], [3.0, 0.5, 0.011]])  # passed straight over point 0
    assert rt.visited.tolist() == [True, False, False]
    d = segment_point_distances(
        np.array([[0.0, 0.0, 0.0]]),
        np.array([[2.0, 0.0, 0.0]]),
        np.array([[1.0, 0.3, 0.0], [3.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]),
    )
    assert d[0].tolist() == pytest.approx([0.3, 1.0, 1.0])


def test_return_home_completes_only_with_every_agent_above_its_start():
    rt = _runtime(return_home=True, home_height=0.4)
    rt.observe(0.0, [[1.0, 1.0, 1.0], [2.0, 1.0, 1.5]])
    assert not rt.observe(0.1, [[2.0, 2.0, 0.5], [2.0, 1.0, 1.5]])  # all visited, nobody home
    assert rt.visited.all()
    assert not rt.observe(0.2, [[0.5, 0.5, 0.4], [2.0, 1.0, 1.5]])  # agent 1 still away
    assert rt.observe(0.3, [[0.5, 0.5, 0.42], [3.0, 0.55, 0.4]])
    assert rt.completed_at == pytest.approx(0.3)
    assert rt.task_info()["layout"].homes.tolist() == [[0.5, 0.5, 0.4], [3.0, 0.5, 0.4]]


@pytest.mark.parametrize(
    ("points", "index", "text"),
    [
        ([[1.0, 1.0, 1.0], [4.2, 1.0, 1.0]], 1, "outside the arena"),
        (
            [[1.0, 1.0, 1.0], [1.0, 0.05, 1.0]],
            1,
            "outside the arena",
        ),  # inside, but closer than the airframe's half width
        ([[1.0, 1.0, 1.0], [2.0, 2.0, 1.0], [3.0, 3.0, -0.3]], 2, "below the ground"),
        ([[1.0, 1.0, 0.005]], 0, "above the ground"),  # an agent's centre cannot get that low
        ([[1.0, 1.0, 1.0], [2.0, 2.0, 1.0], [2.05, 2.0, 1.0]], 2, "closer than visit_radius"),
    ],
)
def test_bad_tour_points_are_refused_naming_the_point(points, index, text):
    with pytest.raises(ConfigError) as err:
        load_scenario("tour", {"task.points": points})
    assert err.value.field == f"task.points[{index}]"
    assert text in str(err.value)
    assert "\n" not in str(err.value)
    assert str(err.value).startswith("tour.yaml: ")


def test_points_above_the_ceiling_and_unknown_fields_are_refused():
    with pytest.raises(ConfigError) as err:
        load_scenario("tour", {"arena.height": 1.5})
    assert err.value.field is not None and err.value.field.startswith("task.points[")
    assert "ceiling" in str(err.value)
    with pytest.raises(ConfigError) as err:
        load_scenario("tour", {"task.visit_radius": 0.0})
    assert err.value.field == "task.visit_radius"
    with pytest.raises(ConfigError) as err:
        load_scenario("tour", {"task.speed": 1.0})
    assert err.value.field == "task.speed"


def test_bundled_tour_scenario_has_enough_3d_points_inside_the_arena():
    sc = load_scenario("tour")
    pts = np.asarray(sc.task.points)
    assert len(pts) >= 20
    assert pts[:, 2].min() >= 0.5 and pts[:, 2].max() <= 2.0 and np.ptp(pts[:, 2]) > 1.0
    assert sc.agents.count == 3


def test_tour_is_flown_to_completion_with_plan_metrics_and_figure(tmp_path):
    r = pybullet_swarm.run("tour", out=tmp_path / "run")
    m = r.metrics
    assert r.exit_status is ExitStatus.COMPLETED
    assert m["points_visited"] == m["points_total"] == 27
    assert m["completion_time_s"] == m["tour_completion_time_s"] < 60.0
    assert m["collisions"]["agent_agent"] == 0 and m["collisions"]["agent_ground"] == 0
    # agents only need to come within visit_radius of each point: the flown path may cut each corner
    # by up to 2 visit radii; it is in fact longer (the shaper limits each axis separately)
    radius = r.scenario.task.visit_radius
    assert m["flown_length_m"] >= m["planned_length_m"] - 2 * radius * m["points_total"]
    assert m["flown_length_m"] >= m["planned_length_m"]
    assert m["flown_length_m"] == pytest.approx(m["path_length_m"]["total"])
    assert 0.5 * m["planned_time_s"] < m["tour_completion_time_s"] < 2.0 * m["planned_time_s"]
    assert sum(m["visits_per_agent"]) == 27 and min(m["visits_per_agent"]) > 0
    assert [e.kind for e in r.events].count("visit") == 27
    summary = json.loads((tmp_path / "run" / "tour.json").read_text())
    legs = summary["plan"]["legs"]
    assert sorted(j for leg in legs for j in leg) == list(range(27))
    # each agent visited the points of its own leg (no point was taken by another agent on the way)
    for i, leg in enumerate(legs):
        assert all(summary["visited_by"][j] == i for j in leg)
    assert (tmp_path / "run" / "plots" / "tour.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "run" / "metrics.json").read_text())["planned_length_m"] == m["planned_length_m"]


def test_tour_run_is_deterministic_for_a_seed():
    few = {
        "task.points": [[1.0, 1.0, 0.8], [3.0, 1.0, 1.2], [3.0, 3.0, 0.6], [1.0, 3.0, 1.5], [2.0, 2.0, 1.0]],
        "agents.start_jitter": 0.05,
    }
    a = pybullet_swarm.run("tour", seed=3, overrides=few)
    b = pybullet_swarm.run("tour", seed=3, overrides=few)
    assert a.exit_status is ExitStatus.COMPLETED
    skip = {"wall_time_s", "real_time_factor"}
    assert {k: v for k, v in a.metrics.items() if k not in skip} == {
        k: v for k, v in b.metrics.items() if k not in skip
    }
    assert np.array_equal(a.timeseries.positions, b.timeseries.positions)
