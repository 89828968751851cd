"""Construction-task metrics from recorded arrays: box progress and a lower bound of the task's time.

The proximity metrics every task reports (nearest neighbours, the thesis's collision count, use of
space) are in ``metrics.proximity`` (importable from here as before).

The construction task (thesis sections 3.5.3 and 3.6) has agents carry boxes from a depot to
goal slots. Everything here reads plain arrays (positions, times, box layouts); nothing touches
PyBullet or a live simulation.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from pybullet_swarm.metrics.proximity import (  # noqa: F401  (their home before metrics.proximity)
    BROADCAST_MAX_AGENTS,
    _as_positions,
    nearest_neighbour_distances,
    proximity_metrics,
    thesis_proximity_metrics,
    utility_of_space,
)


def _travel_times(a: NDArray[np.float64], b: NDArray[np.float64], v_max: NDArray[np.float64]) -> NDArray[np.float64]:
    """(len(a), len(b)) s, minimum flight time between points under a per-axis speed limit."""
    return np.max(np.abs(a[:, None, :] - b[None, :, :]) / v_max, axis=2)


def _empty_leg_cost(approach: NDArray[np.float64], returns: NDArray[np.float64], k: int) -> tuple[float, float]:
    """Cheapest (approach s, returns s) when exactly k agents fly start -> box and B - k boxes follow a return.

    ``approach``: (n, B) s start -> pick-up; ``returns``: (B,) s cheapest slot -> pick-up of each box.
    Agent rows carry a big offset so that the assignment uses as few of them as it can, i.e.
    exactly k (there are only B - k return rows).
    """
    n, b = approach.shape
    big = 1.0 + b * float(max(approach.max(), returns.max(initial=0.0)))
    cost = np.vstack([approach + big, np.broadcast_to(returns, (b - k, b))])
    rows, cols = linear_sum_assignment(cost)
    from_agent = rows < n
    return (float(approach[rows[from_agent], cols[from_agent]].sum()), float(returns[cols[~from_agent]].sum()))


def task_lower_bound(
    agent_starts: ArrayLike,
    boxes: ArrayLike,
    slots: ArrayLike,
    v_max: ArrayLike,
    *,
    grasp_height: float,
    n_agents: int | None = None,
) -> dict[str, Any]:
    """Analytic lower bound on the construction task's completion time, s.

    Flight model: each axis moves at no more than ``v_max[k]``, so going from p to q takes at least
    T(p, q) = max_k |q_k - p_k| / v_max[k] (accelerations, take-off, grasping and collision
    avoidance are ignored, and so is the bottom-layer-first order -- all of them only add time).
    An agent holds a box with its centre ``grasp_height`` above the box centre, so it picks box b
    up at P_b = box_b + (0, 0, h) and drops it into slot s at D_s = slot_s + (0, 0, h). An agent
    carries one box at a time, and each box is picked up once and put straight into a slot.

    Derivation. Every box needs one loaded leg P_b -> D_s and, before it, one empty leg ending at
    P_b that starts either at an agent's start or at a slot where that agent dropped its previous
    box. T obeys the triangle inequality, so detours only add time.

    * carry: the boxes fill distinct slots, so the loaded legs take at least the optimal
      assignment of boxes to slots with cost T(P_b, D_s) (``linear_sum_assignment``).
    * If exactly k agents carry something (1 <= k <= K = min(n, B)), k empty legs start at
      distinct agent starts and end at distinct boxes, and the other B - k are returns
      from a slot, each into box b at least r_b = min_s T(D_s, P_b).
      approach + returns is at least the optimal assignment of the B boxes to k agent starts
      (cost T(start_a, P_b)) and B - k return trips (cost r_b).
    * The k agents share the work W_k = carry + approach_k + returns_k, so the busiest flies at
      least W_k / k. Since k is not known in advance, LB_work = min over k of W_k / k. With cheap
      approaches this is k = K: approach of the K cheapest start -> box pairs and B - n returns
      (when B > n); a far-away agent can make fewer workers cheaper, which the minimum covers.
    * Every box must be delivered by some agent flying from its start to the box and then to a
      slot: LB_single = max over boxes b of [min_a T(start_a, P_b) + min_s T(P_b, D_s)].

    The bound is max(LB_work, LB_single).

    Args:
        agent_starts: (n, 3) m, agent start positions; a single row is shared by all ``n_agents``.
        boxes: (B, 3) m, box centres in the depot.
        slots: (S, 3) m, goal slot centres, S >= B (any box may fill any slot).
        v_max: (3,) m/s, per-axis velocity limit (positive).
        grasp_height: m, agent centre above the box centre while holding it.
        n_agents: agents that may work; default the number of start rows. With several start rows
            it must not exceed them (the bound then lets the cheapest ``n_agents`` work).

    Returns:
        ``task_lower_bound_s``: max(LB_work, LB_single), s.
        ``carry_s``: optimal total loaded-leg time, s.
        ``approach_s``: start -> box time of the minimising k, s.
        ``returns_s``: slot -> box time of the B - k return trips, s.
        ``parallel_agents``: k, the number of working agents that attains LB_work.
        ``work_bound_s``: LB_work, s. ``single_chain_s``: LB_single, s.
    """
    starts = np.atleast_2d(np.asarray(agent_starts, dtype=float))
    bx = np.asarray(boxes, dtype=float).reshape(-1, 3)
    sl = np.asarray(slots, dtype=float).reshape(-1, 3)
    vm = np.broadcast_to(np.asarray(v_max, dtype=float), (3,))
    if starts.shape[1] != 3 or starts.shape[0] == 0:
        raise ValueError(f"agent_starts: expected shape (n, 3) with n >= 1, got {starts.shape}")
    if np.any(vm <= 0):
        raise ValueError(f"v_max: must be positive on every axis, got {vm.tolist()}")
    if sl.shape[0] < bx.shape[0]:
        raise ValueError(f"slots: {sl.shape[0]} slots cannot take {bx.shape[0]} boxes")
    n = starts.shape[0] if n_agents is None else int(n_agents)
    if n < 1 or (starts.shape[0] > 1 and n > starts.shape[0]):
        raise ValueError(f"n_agents: {n_agents} does not fit {starts.shape[0]} start rows")
    if starts.shape[0] == 1:
        starts = np.repeat(starts, n, axis=0)
    n_boxes = bx.shape[0]
    if n_boxes == 0:
        return {
            "task_lower_bound_s": 0.0,
            "carry_s": 0.0,
            "approach_s": 0.0,
            "returns_s": 0.0,
            "parallel_agents": 0,
            "work_bound_s": 0.0,
            "single_chain_s": 0.0,
        }

    lift = np.array([0.0, 0.0, float(grasp_height)])
    pick, drop = bx + lift, sl + lift
    carry_t = _travel_times(pick, drop, vm)  # (B, S) s
    approach_t = _travel_times(starts, pick, vm)  # (n, B) s
    return_t = _travel_times(drop, pick, vm).min(axis=0)  # (B,) s, cheapest slot -> box b
    rows, cols = linear_sum_assignment(carry_t)
    carry = float(carry_t[rows, cols].sum())

    best: tuple[float, int, float, float] | None = None
    for k in range(min(n, n_boxes), 0, -1):  # ties keep the largest k
        approach, returns = _empty_leg_cost(approach_t, return_t, k)
        bound = (carry + approach + returns) / k
        if best is None or bound < best[0] - 1e-12:
            best = (bound, k, approach, returns)
    assert best is not None
    work_bound, k, approach, returns = best
    single = float(np.max(approach_t.min(axis=0) + carry_t.min(axis=1)))
    return {
        "task_lower_bound_s": max(work_bound, single),
        "carry_s": carry,
        "approach_s": approach,
        "returns_s": returns,
        "parallel_agents": k,
        "work_bound_s": work_bound,
        "single_chain_s": single,
    }


def box_to_goal_distance(box_positions: ArrayLike, slots: ArrayLike) -> NDArray[np.float64]:
    """Total distance of the boxes to the goal structure over time (thesis Fig. 5.4).

    Per sample, boxes are matched to slots by the assignment minimising the summed Euclidean
    centre distance, and that sum is returned. A sample identical to the previous one (no box
    moved, exact comparison) reuses its value.

    Args:
        box_positions: (m, B, 3) m, box centres.
        slots: (S, 3) m, slot centres (S == B normally; otherwise min(B, S) pairs are matched).

    Returns:
        (m,) m.
    """
    bp = _as_positions(box_positions)
    sl = np.asarray(slots, dtype=float).reshape(-1, 3)
    m = bp.shape[0]
    out = np.zeros(m)
    if m == 0 or bp.shape[1] == 0 or sl.shape[0] == 0:
        return out
    changed = np.ones(m, dtype=bool)
    changed[1:] = np.any(bp[1:] != bp[:-1], axis=(1, 2))
    idx = np.flatnonzero(changed)
    for k in idx:
        d = np.linalg.norm(bp[k][:, None, :] - sl[None, :, :], axis=2)  # (B, S) m
        rows, cols = linear_sum_assignment(d)
        out[k] = d[rows, cols].sum()
    # each unchanged sample takes the value of the last changed one before it
    return out[np.maximum.accumulate(np.where(changed, np.arange(m), 0))]


def acceleration_series(t: ArrayLike, velocities: ArrayLike) -> NDArray[np.float64]:
    """Accelerations from recorded velocities by central differences (one-sided at the ends).

    Args:
        t: (m,) s, sample times.
        velocities: (m, n, 3) m/s.

    Returns:
        (m, n, 3) m/s^2; zeros with fewer than two samples.
    """
    tt = np.asarray(t, dtype=float)
    v = np.asarray(velocities, dtype=float)
    if v.shape[0] != tt.shape[0]:
        raise ValueError(f"t: {tt.shape[0]} samples but velocities has {v.shape[0]}")
    if tt.size < 2:
        return np.zeros_like(v)
    return np.gradient(v, tt, axis=0)
