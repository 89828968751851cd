"""Order parameters of pybullet_swarm.metrics.flock on hand-made series with exact values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pybullet_swarm.metrics.flock import (
    FLOCK_KEYS,
    FitnessTolerances,
    algebraic_connectivity,
    cluster_labels,
    flock_fitness,
    flock_metrics,
    order_series,
    transfer_gauss,
    transfer_hyperbolic,
    transfer_peak,
)

# agents 0 and 1 one metre apart (connected, colliding at r_coll 1.5 m), agent 2 alone 5 m outside the arena
POS = np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [10.0, 0.0, 1.0]]])
VEL = np.array([[[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 0.0]]])


def _series() -> dict[str, np.ndarray]:
    return order_series(POS, VEL, arena_size=[5.0, 5.0], r_coll=1.5, connection_range=2.0)


def test_every_order_parameter_on_a_hand_made_sample() -> None:
    s = _series()
    c = 1.0 / math.sqrt(2.0)
    assert s["velocity_correlation"][0] == pytest.approx(c)  # agent 2 is alone: left out
    assert s["collision_ratio"][0] == pytest.approx(1.0 / 3.0)
    assert s["distance_outside_m"][0] == pytest.approx(5.0 / 3.0)
    assert s["disconnected_agents"][0] == 1
    assert s["min_cluster"][0] == 1
    assert s["max_cluster"][0] == 2
    assert s["mean_speed"][0] == pytest.approx((2.0 + math.sqrt(2.0)) / 3.0)
    assert s["safety"][0] == pytest.approx(2.0 / 3.0)
    assert s["order"][0] == pytest.approx((2.0 * c + 1.0) / 3.0)  # an agent without neighbours counts 1
    assert s["union"][0] == pytest.approx(0.5)  # two components of three agents
    assert s["connectivity"][0] == pytest.approx(0.0)  # a disconnected graph
    assert s["min_distance_m"][0] == pytest.approx(1.0)


def test_algebraic_connectivity_of_a_path_and_a_triangle() -> None:
    path = np.array([[[0, 1, 0], [1, 0, 1], [0, 1, 0]]], dtype=bool)  # Laplacian eigenvalues 0, 1, 3
    triangle = ~np.eye(3, dtype=bool)[None]  # 0, 3, 3
    assert algebraic_connectivity(path)[0] == pytest.approx(1.0)
    assert algebraic_connectivity(triangle)[0] == pytest.approx(3.0)


def test_clusters_of_a_chain_are_one_component() -> None:
    adj = np.zeros((1, 5, 5), dtype=bool)
    for i, j in ((0, 1), (1, 2), (3, 4)):
        adj[0, i, j] = adj[0, j, i] = True
    assert cluster_labels(adj)[0].tolist() == [0, 0, 0, 3, 3]


def test_transfer_functions() -> None:
    assert transfer_peak(1.0, 1.0, 0.5) == 1.0
    assert transfer_peak(0.75, 1.0, 0.5) == pytest.approx(0.5)  # sin^2(pi / 4)
    assert transfer_peak(0.4, 1.0, 0.5) == 0.0
    assert transfer_gauss(2.0, 2.0) == pytest.approx(math.exp(-1.0))
    assert transfer_hyperbolic(0.0, 3.0) == 1.0
    assert transfer_hyperbolic(3.0, 3.0) == pytest.approx(0.25)


def test_fitness_is_the_product_of_its_factors() -> None:
    avg = {
        "mean_speed": 0.75,
        "collision_ratio": 0.0,
        "distance_outside_m": 0.0,
        "velocity_correlation": 0.8,
        "disconnected_agents": 1.0,
        "max_cluster": 9.0,
    }
    tol = FitnessTolerances(v_flock=1.0, v_tol=0.5, r_tol=1.0, disc_tol=1.0, cluster_tol=1.0)
    assert flock_fitness(avg, 10, tol) == pytest.approx(0.5 * 1.0 * 1.0 * 0.8 * 0.25 * 0.25)


def test_time_averages_leave_out_the_warm_up() -> None:
    pos = np.concatenate([POS, POS + np.array([100.0, 0.0, 0.0])])  # second sample: all 95+ m outside
    vel = np.concatenate([VEL, VEL])
    s = order_series(pos, vel, arena_size=[5.0, 5.0], r_coll=1.5, connection_range=2.0)
    tol = FitnessTolerances(v_flock=1.0, v_tol=0.5, r_tol=1.0)
    m = flock_metrics(s, [0.0, 1.0], 0.5, 3, tol)
    assert list(m) == list(FLOCK_KEYS)
    assert m["distance_outside_m"] == pytest.approx((95.0 + 96.0 + 105.0) / 3.0)
    assert flock_metrics(s, [0.0, 1.0], 2.0, 3, tol) == {k: None for k in FLOCK_KEYS}
