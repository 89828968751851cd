"""Reynolds rules, each in isolation, point the right way; the planner climbs first and follows the route."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.planning import reynolds as ry
from pybullet_swarm.planning.base import CommandKind, Observation, TaskInfo
from pybullet_swarm.planning.views.route import RouteLayout


def test_separation_points_away_and_grows_closer() -> None:
    p = np.array([1.0, 1.0, 1.0])
    near = ry.separation(p, np.array([[1.2, 1.0, 1.0]]), 0.5)
    nearer = ry.separation(p, np.array([[1.1, 1.0, 1.0]]), 0.5)
    assert near[0] < 0 and abs(near[1]) < 1e-12  # pushed to -x, away from the neighbour
    assert np.linalg.norm(nearer) == pytest.approx(2 * np.linalg.norm(near))  # 1 / distance
    assert np.all(ry.separation(p, np.array([[2.0, 1.0, 1.0]]), 0.5) == 0)  # outside the radius: nothing


def test_alignment_points_to_the_neighbours_velocity() -> None:
    a = ry.alignment(np.zeros(3), np.array([[0.2, 0.0, 0.0], [0.0, 0.2, 0.0]]))
    np.testing.assert_allclose(a, [0.1, 0.1, 0.0])
    np.testing.assert_allclose(ry.alignment(np.array([0.1, 0.1, 0.0]), np.array([[0.1, 0.1, 0.0]])), 0.0)


def test_cohesion_points_to_the_neighbours_centroid() -> None:
    c = ry.cohesion(np.zeros(3), np.array([[1.0, 0.0, 0.0], [1.0, 2.0, 0.0]]))
    np.testing.assert_allclose(c, [1.0, 1.0, 0.0])


def test_migration_points_to_the_waypoint_and_slows_at_the_end() -> None:
    m = ry.migration(np.array([0.0, 0.0, 0.5]), np.array([3.0, 4.0, 1.0]), 0.25)
    np.testing.assert_allclose(m, [0.15, 0.2, 0.0])  # horizontal, at the migration speed
    slow = ry.migration(np.array([0.0, 0.0, 1.0]), np.array([0.1, 0.0, 1.0]), 0.25, slow_radius=0.5)
    np.testing.assert_allclose(slow, [0.05, 0.0, 0.0])


def test_altitude_band_and_limits() -> None:
    assert ry.altitude_hold(0.5, (0.8, 1.2), 1.0) == pytest.approx(0.3)
    assert ry.altitude_hold(1.0, (0.8, 1.2), 1.0) == 0.0
    assert ry.altitude_hold(1.5, (0.8, 1.2), 1.0) == pytest.approx(-0.3)
    v = ry.scale_to_limits(np.array([0.6, 0.3, 0.0]), np.array([0.3, 0.3, 0.3]))
    np.testing.assert_allclose(v, [0.3, 0.15, 0.0])  # direction kept


def _obs(pos: list[float], nb: list[list[float]] | None = None) -> Observation:
    nbp = np.asarray(nb if nb else np.zeros((0, 3)), dtype=float).reshape(-1, 3)
    return Observation(
        0,
        0.0,
        np.asarray(pos, dtype=float),
        np.zeros(3),
        0.0,
        -1,
        np.arange(1, len(nbp) + 1),
        nbp,
        np.zeros_like(nbp),
        None,  # a route has no objects to see
    )


def test_planner_climbs_first_then_migrates_and_switches_waypoints() -> None:
    info = TaskInfo(
        arena_size=np.array([5.0, 5.0]),
        n_agents=1,
        agent_radius=0.1,
        v_max=np.full(3, 0.3),
        layout=RouteLayout(np.array([[2.0, 1.0, 1.0], [2.0, 3.0, 1.0]]), pass_radius=0.3),
    )
    pl = ry.ReynoldsPlanner()
    pl.reset(0, np.random.default_rng(0), info)
    ground = pl.plan(_obs([1.0, 1.0, 0.01]), None)
    assert ground.kind == CommandKind.VELOCITY
    assert ground.vector[2] > 0 and np.allclose(ground.vector[:2], 0.0)
    cruise = pl.velocity(_obs([1.0, 1.0, 1.0]))
    assert cruise[0] > 0 and abs(cruise[1]) < 1e-9  # towards waypoint 0
    pl.velocity(_obs([1.9, 1.0, 1.0]))  # within 0.75 x pass radius: next one
    assert pl.route.index == 1
    assert pl.velocity(_obs([1.9, 1.0, 1.0]))[1] > 0


def test_unknown_parameter_refused() -> None:
    from pybullet_swarm.errors import ConfigError
    from pybullet_swarm.experiment.scenario import load_scenario

    with pytest.raises(ConfigError, match=r"^flocking\.yaml: planner\.params\.speed: unknown field, got 1\.0$"):
        load_scenario("flocking", {"planner.params.speed": 1.0})
    with pytest.raises(
        ConfigError,
        match=r"^flocking\.yaml: planner\.params\.altitude_band: must be \[lo, hi\] m "
        r"with lo <= hi, got \[1\.2, 0\.8\]$",
    ):
        load_scenario("flocking", {"planner.params.altitude_band": [1.2, 0.8]})
    with pytest.raises(ConfigError, match=r"planner\.params\.altitude_band\[1\]: must be > 0"):
        load_scenario("flocking", {"planner.params.altitude_band": [0.5, -1.0]})
