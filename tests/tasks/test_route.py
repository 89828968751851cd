"""The route task: validation, waypoint passing, metrics, and short flights on the bundled scenarios."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.tasks.route import SEED_FORMATION, RouteRuntime, RouteTask


def _spec(**kw: object) -> RouteTask:
    data = {"kind": "route", "time_limit_s": 10.0, "waypoints": [[1, 0, 1], [1, 1, 1]], "pass_radius": 0.2}
    data.update(kw)
    return RouteTask(**data)


def test_centroid_passes_in_order() -> None:
    rt = RouteRuntime(_spec(), 2)
    # centroid at (1, 1): near waypoint 1, but waypoint 0 first
    assert not rt.observe(0.1, np.array([[1, 0.9, 1], [1, 1.1, 1]], dtype=float))
    assert rt.next == 0
    assert not rt.observe(0.2, np.array([[0.9, 0, 1], [1.1, 0, 1]], dtype=float))
    assert rt.next == 1 and rt.pass_times[0] == pytest.approx(0.2)
    assert rt.observe(0.3, np.array([[1, 0.9, 1], [1, 1.1, 1]], dtype=float))
    assert rt.completed_at == pytest.approx(0.3)
    m = rt.metrics()
    assert m["route_time_s"] == pytest.approx(0.3) and m["waypoints_passed"] == 2
    assert m["agents_passed_all"] == 2


def test_every_agent_criterion_waits_for_the_straggler() -> None:
    rt = RouteRuntime(_spec(criterion="every_agent"), 2)
    rt.observe(0.1, np.array([[1, 0, 1], [0, 0, 1]], dtype=float))
    assert rt.next == 0
    rt.observe(0.2, np.array([[1, 1, 1], [1, 0, 1]], dtype=float))
    assert rt.next == 1


def test_default_formation_is_the_report_formation_scaled() -> None:
    rt = RouteRuntime(_spec(formation={"scale": 2.0}), 5)
    np.testing.assert_allclose(rt.slots[:, :2], 2.0 * SEED_FORMATION)
    info = rt.task_info()
    np.testing.assert_allclose(info["layout"].formation_slots.mean(axis=0), 0.0, atol=1e-12)


@pytest.mark.parametrize(
    "override, field",
    [
        ({"task.waypoints": [[9.0, 1.0, 1.0]]}, "task.waypoints[0]"),
        ({"task.waypoints": [[2.2, 1.35, 1.0]]}, "task.waypoints[0]"),  # inside a pillar
        ({"task.formation": {"scale": 2.0}}, "task.formation.slots"),  # 10 agents, 5 slots
        ({"arena.obstacles": [{"shape": "box", "size": [0.5, 0.3], "position": [3, 3]}]}, "arena.obstacles[0].size"),
        (
            {"arena.obstacles": [{"shape": "cylinder", "size": [0.2, 1.0], "position": [6.9, 3]}]},
            "arena.obstacles[0].position",
        ),
        (
            {"arena.obstacles": [{"shape": "cylinder", "size": [0.2, 1.0], "position": [1.0, 2.0]}]},
            "arena.obstacles[0]",
        ),
        ({"sensing.range.rays": 0}, "sensing.range.rays"),
    ],
)
def test_bad_route_scenarios_are_one_line_errors(override: dict, field: str) -> None:
    with pytest.raises(ConfigError) as exc:
        load_scenario("flocking", override)
    msg = str(exc.value)
    assert msg.startswith(f"flocking.yaml: {field}:") and "\n" not in msg


def test_laplacian_bad_graph_is_a_config_error() -> None:
    with pytest.raises(
        ConfigError,
        match=r"^formation\.yaml: planner\.params\.graph: must be a 5 x 5 adjacency "
        r"matrix \(agents\.count = 5\), got 2 rows$",
    ):
        load_scenario("formation", {"planner.params.graph": [[0, 1], [1, 0]]})
    with pytest.raises(ConfigError, match=r"^formation\.yaml: planner\.params\.graph: must be symmetric"):
        load_scenario("formation", {"planner.params.graph": [[0, 1], [0, 0]]})
    with pytest.raises(ConfigError, match=r"^formation\.yaml: planner\.params\.graph: is not connected"):
        load_scenario("formation", {"agents.count": 3, "planner.params.graph": [[0, 1, 0], [1, 0, 0], [0, 0, 0]]})


def test_short_formation_flight_passes_a_waypoint_without_contacts() -> None:
    """The formation takes off and migrates 1 m with Braitenberg on (real physics, range sensors cast)."""
    import pybullet_swarm as ps

    sc = load_scenario(
        "formation",
        {
            "task.waypoints": [[2.0, 2.0, 1.0]],
            "task.time_limit_s": 25.0,
            "arena.obstacles": [{"shape": "cylinder", "size": [0.15, 2.0], "position": [2.0, 0.8]}],
        },
    )
    r = ps.run(sc, seed=1)
    m = r.metrics
    assert m["exit_status"] == "completed" and m["waypoints_passed"] == 1
    assert m["collisions"]["agent_agent"] == 0 and m["collisions"]["agent_obstacle"] == 0
    assert 0.0 < m["fitness"] <= 1.0 and 0.0 < m["formation"]["distance"] <= 1.0
    assert m["formation"]["error_m"] < 0.2
    assert set(m["flocking"]) == {"o", "d", "v", "fitness"}
    assert "braitenberg_active_fraction" in m


@pytest.mark.slow
def test_flocking_obstacle_course_is_deterministic_and_sees_obstacles(tmp_path) -> None:
    import pybullet_swarm as ps

    sc = load_scenario("flocking", {"task.time_limit_s": 12.0})
    with ps.Simulation(sc, seed=0) as sim:
        sim.step(sim.planner_every * 60)  # 6 s
        obs = sim.observations()
        assert obs[0].ranges.shape == (8,)
        assert np.all((obs[0].ranges >= 0) & (obs[0].ranges <= 0.5))
        r1 = sim.run()
    r2 = ps.run(sc, seed=0, out=tmp_path / "run")
    assert r1.metrics["flocking"] == r2.metrics["flocking"]
    for name in ("fitness.png", "course.png"):
        assert (tmp_path / "run" / "plots" / name).is_file()
