"""Construction metrics against hand-computed answers and brute-force references (the proximity
metrics every task reports are tested in test_proximity.py)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pybullet_swarm.metrics import construction, proximity
from pybullet_swarm.metrics.construction import (
    acceleration_series,
    box_to_goal_distance,
    task_lower_bound,
)

V = np.array([0.15, 0.15, 0.15])  # m/s, the thesis's per-axis limit


def test_proximity_metrics_are_still_importable_from_construction() -> None:
    assert construction.proximity_metrics is proximity.proximity_metrics


def test_lower_bound_one_agent_one_box() -> None:
    v = np.array([0.25, 0.15, 0.1])
    res = task_lower_bound([[0.5, 0.5, 0.0]], [[1.0, 0.5, 0.05]], [[2.5, 0.5, 0.05]], v, grasp_height=0.2)
    # approach: max(0.5 / 0.25, 0, 0.25 / 0.1) = 2.5 s; carry: 1.5 / 0.25 = 6 s
    assert res["approach_s"] == pytest.approx(2.5)
    assert res["carry_s"] == pytest.approx(6.0)
    assert res["returns_s"] == 0.0
    assert res["task_lower_bound_s"] == pytest.approx(8.5)


def _two_lane_layout() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    starts = np.array([[0.5, 0.25, 0.15], [0.5, 0.75, 0.15]])
    boxes = np.array([[1.0, 0.25, 0.05], [1.0, 0.75, 0.05]])
    slots = np.array([[2.5, 0.25, 0.05], [2.5, 0.75, 0.05]])
    return starts, boxes, slots


def test_lower_bound_two_agents_two_boxes_symmetric() -> None:
    starts, boxes, slots = _two_lane_layout()
    res = task_lower_bound(starts, boxes, slots, V, grasp_height=0.1)
    assert res["carry_s"] == pytest.approx(20.0)
    assert res["approach_s"] == pytest.approx(2 * 0.5 / 0.15)
    assert res["parallel_agents"] == 2
    assert res["task_lower_bound_s"] == pytest.approx(10.0 + 0.5 / 0.15)


def test_lower_bound_more_boxes_than_agents_adds_returns() -> None:
    starts, boxes, slots = _two_lane_layout()
    res = task_lower_bound(starts[:1], boxes, slots, V, grasp_height=0.1)
    assert res["returns_s"] == pytest.approx(10.0)  # slot -> box: 1.5 m along x
    assert res["task_lower_bound_s"] == pytest.approx(0.5 / 0.15 + 10.0 + 10.0 + 10.0)
    # the schedule start -> box 0 -> slot 0 -> box 1 -> slot 1 attains it
    legs = [starts[0], boxes[0], slots[0], boxes[1], slots[1]]
    legs = [q + [0.0, 0.0, 0.1 * (k > 0)] for k, q in enumerate(legs)]
    schedule = sum(np.max(np.abs(b - a) / V) for a, b in zip(legs[:-1], legs[1:]))
    assert res["task_lower_bound_s"] == pytest.approx(schedule)


def test_lower_bound_lets_a_far_agent_stay_idle() -> None:
    starts = np.array([[0.9, 0.5, 0.15], [2.9, 0.9, 0.15]])
    boxes = np.array([[1.0, 0.4, 0.05], [1.0, 0.6, 0.05]])
    slots = np.array([[1.3, 0.4, 0.05], [1.3, 0.6, 0.05]])
    res = task_lower_bound(starts, boxes, slots, V, grasp_height=0.1)
    # agent 0 alone: 0.1 / 0.15 to box, 2 s carry, 2 s back, 2 s carry
    assert res["task_lower_bound_s"] == pytest.approx(0.1 / 0.15 + 6.0)
    assert res["parallel_agents"] == 1


def _schedule_time(starts: np.ndarray, boxes: np.ndarray, slots: np.ndarray, owner: np.ndarray, h: float) -> float:
    """Makespan, s, of flying straight at full speed; agent ``owner[b]`` takes box b to slot b in order."""
    lift = np.array([0.0, 0.0, h])
    finish = 0.0
    for a in range(starts.shape[0]):
        here, busy = starts[a], 0.0
        for b in np.flatnonzero(owner == a):
            for target in (boxes[b] + lift, slots[b] + lift):
                busy += float(np.max(np.abs(target - here) / V))
                here = target
        finish = max(finish, busy)
    return finish


@pytest.mark.parametrize("seed", range(40))
def test_lower_bound_never_exceeds_a_feasible_schedule(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n, b = int(rng.integers(1, 6)), int(rng.integers(1, 10))
    starts = rng.uniform([0, 0, 0], [3, 1, 0.2], size=(n, 3))
    boxes = rng.uniform([0, 0, 0.05], [0.6, 1, 0.05], size=(b, 3))
    slots = rng.uniform([2.4, 0, 0.05], [3, 1, 0.25], size=(b, 3))
    res = task_lower_bound(starts, boxes, slots, V, grasp_height=0.08)
    for _ in range(5):
        owner = rng.integers(0, n, size=b)
        perm = rng.permutation(b)
        assert res["task_lower_bound_s"] <= _schedule_time(starts, boxes[perm], slots, owner, 0.08) + 1e-9


def test_box_to_goal_uses_the_optimal_assignment() -> None:
    boxes = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]])
    slots = np.array([[1.1, 0.0, 0.0], [0.1, 0.0, 0.0]])
    # identity would give 1.1 + 0.9 = 2.0 m; the swap gives 0.1 + 0.1
    np.testing.assert_allclose(box_to_goal_distance(boxes, slots), [0.2])


def test_box_to_goal_matches_brute_force_with_static_stretches() -> None:
    rng = np.random.default_rng(3)
    slots = rng.uniform(size=(4, 3))
    samples = rng.uniform(size=(6, 4, 3))
    boxes = np.repeat(samples, [3, 1, 4, 1, 2, 5], axis=0)
    expected = [
        min(
            sum(np.linalg.norm(s[i] - slots[j]) for i, j in enumerate(perm))
            for perm in itertools.permutations(range(4))
        )
        for s in boxes
    ]
    np.testing.assert_allclose(box_to_goal_distance(boxes, slots), expected, rtol=1e-12)


def test_acceleration_series_of_quadratic_velocity() -> None:
    t = np.linspace(0.0, 2.0, 41)
    v = np.zeros((t.size, 2, 3))
    v[:, 0, 0] = 0.3 * t  # constant 0.3 m/s^2
    v[:, 1, 2] = t**2  # 2 t m/s^2
    acc = acceleration_series(t, v)
    assert acc.shape == v.shape
    np.testing.assert_allclose(acc[:, 0, 0], 0.3)
    np.testing.assert_allclose(acc[1:-1, 1, 2], 2 * t[1:-1])
    np.testing.assert_allclose(acc[:, :, 1], 0.0)
