"""Flocking and formation fitness on hand-built configurations with known values."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.metrics import flocking as fl


def test_orientation_aligned_opposed_and_perpendicular() -> None:
    aligned = np.array([[[0.2, 0.0, 0.0], [0.5, 0.0, 0.1], [0.1, 0.0, -0.1]]])
    opposed = np.array([[[0.2, 0.0, 0.0], [-0.3, 0.0, 0.0]]])
    perp = np.array([[[0.2, 0.0, 0.0], [0.0, 0.4, 0.0]]])
    assert fl.orientation(aligned)[0] == pytest.approx(1.0)
    assert fl.orientation(opposed)[0] == pytest.approx(0.0, abs=1e-12)
    assert fl.orientation(perp)[0] == pytest.approx(np.sqrt(2.0) / 2.0)
    # an agent hovering (below min_speed) has no heading: |h1 + 0| / 2
    hover = np.array([[[0.2, 0.0, 0.0], [0.001, 0.0, 0.0]]])
    assert fl.orientation(hover)[0] == pytest.approx(0.5)


def test_cohesion_square() -> None:
    # four agents on the corners of a 2 m square: each 1.414 m from the centroid
    p = np.array([[[0, 0, 1], [2, 0, 1], [2, 2, 1], [0, 2, 1]]], dtype=float)
    assert fl.cohesion(p)[0] == pytest.approx(1.0 / (1.0 + np.sqrt(2.0)))


def test_speed_limit_along_direction() -> None:
    u = np.array([[1.0, 0.0, 0.0], [np.sqrt(0.5), np.sqrt(0.5), 0.0], [0.6, 0.8, 0.0]])
    lim = fl.speed_limit_along(u, [0.3, 0.3, 0.2])
    np.testing.assert_allclose(lim, [0.3, 0.3 * np.sqrt(2.0), 0.3 / 0.8])


def test_flocking_fitness_known_values() -> None:
    # two agents 1 m apart flying +x at 0.15 m/s, migration along +x, v_max 0.3 m/s
    p = np.array([[[0, 0, 1], [1, 0, 1]]], dtype=float)
    v = np.array([[[0.15, 0, 0], [0.15, 0, 0]]], dtype=float)
    f = fl.flocking_fitness(p, v, np.array([1.0, 0.0, 0.0]), 0.3)
    assert f["o"][0] == pytest.approx(1.0)
    assert f["d"][0] == pytest.approx(1.0 / 1.5)
    assert f["v"][0] == pytest.approx(0.5)
    assert f["fitness"][0] == pytest.approx(1.0 / 3.0)
    # flying away from the waypoint scores 0 velocity (not negative)
    back = fl.flocking_fitness(p, -v, np.array([1.0, 0.0, 0.0]), 0.3)
    assert back["v"][0] == 0.0 and back["fitness"][0] == 0.0


def test_formation_fitness_known_values() -> None:
    slots = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    exact = slots + [5.0, 3.0, 1.0]  # the formation anywhere: no error
    off = exact.copy()
    off[1] += [0.3, 0.0, 0.0]  # one agent 0.3 m out along x
    p = np.stack([exact, off])
    err = fl.slot_errors(p, slots)
    np.testing.assert_allclose(err[0], 0.0, atol=1e-12)
    # centroid moves by 0.1 m in x: errors |(-0.1,0)|, |(0.2,0)|, |(-0.1,0)|
    np.testing.assert_allclose(err[1], [0.1, 0.2, 0.1], atol=1e-12)
    v = np.zeros((2, 3, 3))
    v[:, :, 1] = 0.2  # moving +y at 0.2 m/s
    f = fl.formation_fitness(p, v, slots, np.array([0.0, 1.0, 0.0]), 0.4)
    np.testing.assert_allclose(f["distance"], [1.0, 1.0 / (1.0 + 0.4 / 3.0)])
    np.testing.assert_allclose(f["velocity"], [0.5, 0.5])
    np.testing.assert_allclose(f["fitness"], f["distance"] * 0.5)


def test_migration_directions_follow_pass_times() -> None:
    route = np.array([[1.0, 0.0, 1.0], [1.0, 1.0, 1.0]])
    t = np.array([0.0, 1.0, 2.0, 3.0])
    c = np.zeros((4, 3))
    u, idx = fl.migration_directions(t, c, route, [1.5, None])
    np.testing.assert_array_equal(idx, [0, 0, 1, 1])
    np.testing.assert_allclose(u[0], [1, 0, 0])
    np.testing.assert_allclose(u[3], [np.sqrt(0.5), np.sqrt(0.5), 0.0])


def test_time_average_stops_at_end() -> None:
    t = np.arange(5, dtype=float)
    assert fl.time_average(t, [1, 1, 3, 5, 100], 3.0) == pytest.approx(2.5)
    assert fl.time_average(t, [1, 1, 3, 5, 100]) == pytest.approx(22.0)
