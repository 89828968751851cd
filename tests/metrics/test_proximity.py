"""Proximity metrics of any swarm against hand-computed answers and brute-force references."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pybullet_swarm.metrics import proximity
from pybullet_swarm.metrics.collisions import proximity_episodes
from pybullet_swarm.metrics.proximity import (
    nearest_neighbour_distances,
    proximity_metrics,
    thesis_proximity_metrics,
    utility_of_space,
)


def _brute_nn(p: np.ndarray) -> np.ndarray:
    m, n, _ = p.shape
    out = np.full((m, n), np.inf)
    for k in range(m):
        for i in range(n):
            for j in range(n):
                if i != j:
                    out[k, i] = min(out[k, i], float(np.linalg.norm(p[k, i] - p[k, j])))
    return out


def _brute_proximity(t: np.ndarray, p: np.ndarray, thr: float) -> tuple[int, float]:
    dt = float(np.median(np.diff(t)))
    onsets, time_s = 0, 0.0
    for i, j in itertools.combinations(range(p.shape[1]), 2):
        o, s = proximity_episodes(np.linalg.norm(p[:, i] - p[:, j], axis=1), thr, dt)
        onsets, time_s = onsets + o, time_s + s
    return onsets, time_s


def _pair(t: np.ndarray, gap: np.ndarray, y_offset: float = 0.0) -> np.ndarray:
    """(m, 2, 3) m: two agents on the x axis line at a centre distance ``gap`` (m,) m."""
    p = np.zeros((t.size, 2, 3))
    p[:, :, 2] = 1.0
    p[:, 0, 0], p[:, 1, 0] = 1.5 - gap / 2, 1.5 + gap / 2
    p[:, 0, 1], p[:, 1, 1] = 0.5 - y_offset / 2, 0.5 + y_offset / 2
    return p


@pytest.mark.parametrize("seed,n", [(0, 1), (1, 2), (2, 5), (3, 12), (4, 70)])
def test_nearest_neighbour_matches_brute_force(seed: int, n: int) -> None:
    p = np.random.default_rng(seed).uniform(0, [3, 1, 1], size=(15, n, 3))
    np.testing.assert_allclose(nearest_neighbour_distances(p), _brute_nn(p), rtol=1e-12)


def test_head_on_approach_and_separation_is_one_violation() -> None:
    t = np.arange(251) * 0.04  # 0..10 s
    gap = 0.1 + 0.1 * np.abs(t - 5.0)  # closest 0.10 m at t = 5 s
    res = proximity_metrics(t, _pair(t, gap), threshold=0.15)
    # below while |t - 5| < 0.5 s: samples 113..137, 25 samples of 0.04 s
    assert res["proximity_violations"] == 1
    assert res["proximity_time_s"] == pytest.approx(1.0)
    assert res["min_separation_m"] == pytest.approx(0.10)
    assert res["mean_nn_distance_m"] == pytest.approx(gap.mean())


def test_pair_below_at_start_counts_once_and_each_dip_counts() -> None:
    t = np.arange(5) * 0.5
    res = proximity_metrics(t, _pair(t, np.array([0.1, 0.1, 0.2, 0.1, 0.3])), threshold=0.15)
    assert res["proximity_violations"] == 2
    assert res["proximity_time_s"] == pytest.approx(1.5)


def test_passing_30cm_apart_never_violates() -> None:
    t = np.arange(201) * 0.1
    p = np.zeros((t.size, 2, 3))
    p[:, 0] = np.stack([0.5 + 0.1 * t, np.full_like(t, 0.35), np.ones_like(t)], axis=1)
    p[:, 1] = np.stack([2.5 - 0.1 * t, np.full_like(t, 0.65), np.ones_like(t)], axis=1)
    res = proximity_metrics(t, p, threshold=0.15)
    assert res["proximity_violations"] == 0
    assert res["proximity_time_s"] == 0.0
    assert res["min_separation_m"] == pytest.approx(0.30, abs=1e-9)


def test_single_agent_has_no_pairs() -> None:
    res = proximity_metrics(np.arange(3.0), np.zeros((3, 1, 3)), threshold=0.15)
    assert res == {
        "proximity_violations": 0,
        "proximity_time_s": 0.0,
        "min_separation_m": None,
        "mean_nn_distance_m": None,
    }


@pytest.mark.parametrize("dense_limit", [64, 1])
def test_proximity_matches_pairwise_episodes(dense_limit: int, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(proximity, "BROADCAST_MAX_AGENTS", dense_limit)  # 1: k-d tree path
    rng = np.random.default_rng(7)
    p = np.cumsum(rng.normal(0, 0.03, size=(120, 6, 3)), axis=0) + rng.uniform(0, 0.5, size=(1, 6, 3))
    t = np.arange(120) * 0.05
    res = proximity_metrics(t, p, threshold=0.15)
    onsets, time_s = _brute_proximity(t, p, 0.15)
    nn = _brute_nn(p)
    assert onsets > 3
    assert res["proximity_violations"] == onsets
    assert res["proximity_time_s"] == pytest.approx(time_s)
    assert res["min_separation_m"] == pytest.approx(nn.min())
    assert res["mean_nn_distance_m"] == pytest.approx(nn.mean())


# ---------------------------------------------------------------------------------------------
# The thesis's collision count: crossings of each agent's nearest-neighbour curve (Fig. 3.12)


def _line(gaps_left: list[float], gaps_right: list[float]) -> np.ndarray:
    """(m, 3, 3) m: agent 1 fixed at x = 1.5, agent 0 ``gaps_left`` to its left, agent 2 ``gaps_right`` to its right."""
    m = len(gaps_left)
    p = np.zeros((m, 3, 3))
    p[:, :, 1], p[:, :, 2] = 0.5, 1.0
    p[:, 0, 0] = 1.5 - np.asarray(gaps_left)
    p[:, 1, 0] = 1.5
    p[:, 2, 0] = 1.5 + np.asarray(gaps_right)
    return p


def test_one_close_pass_is_two_thesis_collisions_and_one_pair_onset() -> None:
    t = np.arange(251) * 0.04
    p = _pair(t, 0.1 + 0.1 * np.abs(t - 5.0))  # below 0.15 m while |t - 5| < 0.5 s
    res = thesis_proximity_metrics(p, diameter=0.15)
    assert res["thesis_collisions_per_agent"] == [1, 1]  # both curves cross the line once
    assert res["thesis_collisions"] == 2
    assert proximity_metrics(t, p, threshold=0.15)["proximity_violations"] == 1


def test_an_agent_below_the_line_while_its_neighbour_changes_crosses_once() -> None:
    # sample:          0    1    2    3    4
    left = [0.3, 0.1, 0.1, 0.3, 0.3]  # agent 0 <-> agent 1, m
    right = [0.3, 0.3, 0.1, 0.1, 0.3]  # agent 1 <-> agent 2, m
    p = _line(left, right)
    res = thesis_proximity_metrics(p, diameter=0.15)
    # agent 1's nearest distance is 0.3, 0.1, 0.1, 0.1, 0.3: one crossing (neighbour 0, then 2)
    assert res["thesis_collisions_per_agent"] == [1, 1, 1]
    assert res["thesis_collisions"] == 3
    # pair onsets: (0, 1) at sample 1 and (1, 2) at sample 2; (0, 2) never closer than 0.2 m
    assert proximity_metrics(np.arange(5.0), p, threshold=0.15)["proximity_violations"] == 2
    nn = np.array([left, np.minimum(left, right), right]).T  # (5, 3) m
    assert res["nn_distance_diameters"] == pytest.approx(nn.mean() / 0.15, rel=1e-12)


def test_thesis_count_starts_below_once_counts_every_dip_and_not_the_line_itself() -> None:
    res = thesis_proximity_metrics(_pair(np.arange(5.0), np.array([0.1, 0.1, 0.2, 0.1, 0.3])), diameter=0.15)
    assert res["thesis_collisions_per_agent"] == [2, 2]  # below at the start (1) and the dip at sample 3 (1)
    # gaps of 0.5 and 0.25 m are exact in binary: the middle sample sits exactly on the line
    on_line = thesis_proximity_metrics(_pair(np.arange(3.0), np.array([0.5, 0.25, 0.5])), diameter=0.25)
    assert on_line["thesis_collisions"] == 0  # exactly one diameter is not below the line
    assert on_line["nn_distance_diameters"] == pytest.approx((2.0 + 1.0 + 2.0) / 3)
    just_below = thesis_proximity_metrics(_pair(np.arange(3.0), np.array([0.5, 0.2499, 0.5])), diameter=0.25)
    assert just_below["thesis_collisions"] == 2


def test_thesis_count_of_a_lone_agent_and_bad_diameters() -> None:
    assert thesis_proximity_metrics(np.zeros((4, 1, 3)), 0.15) == {
        "thesis_collisions": 0,
        "thesis_collisions_per_agent": [0],
        "nn_distance_diameters": None,
    }
    assert thesis_proximity_metrics(np.zeros((0, 2, 3)), 0.15)["thesis_collisions_per_agent"] == [0, 0]
    for bad in (0.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="diameter"):
            thesis_proximity_metrics(np.zeros((2, 2, 3)), bad)


@pytest.mark.parametrize("dense_limit", [64, 1])
def test_thesis_count_matches_a_per_agent_loop(dense_limit: int, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(proximity, "BROADCAST_MAX_AGENTS", dense_limit)  # 1: k-d tree path
    rng = np.random.default_rng(11)
    p = np.cumsum(rng.normal(0, 0.03, size=(150, 6, 3)), axis=0) + rng.uniform(0, 0.5, size=(1, 6, 3))
    nn = _brute_nn(p)
    expected = []
    for i in range(6):
        below_before, count = False, 0
        for k in range(nn.shape[0]):
            below = nn[k, i] < 0.15
            count += int(below and not below_before)
            below_before = below
        expected.append(count)
    res = thesis_proximity_metrics(p, 0.15)
    assert sum(expected) > 5
    assert res["thesis_collisions_per_agent"] == expected
    assert res["thesis_collisions"] == sum(expected)


def test_utility_of_space_of_a_straight_line() -> None:
    x = np.linspace(0.05, 2.95, 291)
    xy = np.stack([x, np.full_like(x, 0.55)], axis=1)[:, None, :]  # (m, 1, 2)
    assert utility_of_space(xy, (3.0, 1.0)) == pytest.approx(0.1)  # 30 of 300 cells
    two = np.concatenate([xy, xy], axis=1)  # a second agent on the same line
    assert utility_of_space(two, (3.0, 1.0)) == pytest.approx(0.1)
    outside = np.concatenate([xy, [[[-1.0, -1.0]]]], axis=0)  # clipped into cell (0, 0)
    assert utility_of_space(outside, (3.0, 1.0)) == pytest.approx(31 / 300)


def test_utility_of_space_full_cover() -> None:
    gx, gy = np.meshgrid(np.arange(30) * 0.1 + 0.05, np.arange(10) * 0.1 + 0.05)
    xy = np.stack([gx.ravel(), gy.ravel()], axis=1)[:, None, :]
    assert utility_of_space(xy, (3.0, 1.0)) == pytest.approx(1.0)
