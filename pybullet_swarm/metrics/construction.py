"""Construction-task metrics from recorded arrays: proximity, the thesis's collision count, use of
space, box progress, a time bound.

The construction task (thesis sections 3.5.3 and 3.6) has agents carry boxes from a depot to
goal slots. Everything here reads plain arrays (positions, times, box layouts); nothing touches
PyBullet or a live simulation.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

BROADCAST_MAX_AGENTS = 64
"""Swarms up to this size use dense pairwise distances; larger ones a k-d tree per sample."""

_CHUNK_ELEMENTS = 1 << 19
"""Pairwise distances held at once by the dense path (about 12 MB of float64 differences)."""


def _as_positions(positions: ArrayLike) -> NDArray[np.float64]:
    p = np.asarray(positions, dtype=float)
    if p.ndim != 3 or p.shape[2] != 3:
        raise ValueError(f"positions: expected shape (m, n, 3), got {p.shape}")
    return p


def _pairwise_chunks(p: NDArray[np.float64]) -> Iterator[tuple[int, NDArray[np.float64]]]:
    """Yield (first sample, (c, n, n) m centre distances) with an infinite diagonal, a chunk of samples at a time."""
    m, n, _ = p.shape
    step = max(1, _CHUNK_ELEMENTS // max(1, n * n))
    diag = np.arange(n)
    for s in range(0, m, step):
        c = p[s : s + step]
        d = np.linalg.norm(c[:, :, None, :] - c[:, None, :, :], axis=3)
        d[:, diag, diag] = np.inf
        yield s, d


def _kdtree_nn(sample: NDArray[np.float64]) -> tuple[cKDTree, NDArray[np.float64]]:
    """K-d tree of one sample's (n, 3) m positions and each agent's (n,) m nearest-neighbour distance."""
    tree = cKDTree(sample)
    dd, _ = tree.query(sample, k=2)
    return tree, dd[:, 1]


def nearest_neighbour_distances(positions: ArrayLike) -> NDArray[np.float64]:
    """Distance of each agent to its nearest other agent, centre to centre.

    Args:
        positions: (m, n, 3) m, agent centres at m samples.

    Returns:
        (m, n) m; ``inf`` everywhere when n == 1.
    """
    p = _as_positions(positions)
    m, n, _ = p.shape
    out = np.full((m, n), np.inf)
    if n < 2:
        return out
    if n <= BROADCAST_MAX_AGENTS:
        for s, d in _pairwise_chunks(p):
            out[s : s + d.shape[0]] = d.min(axis=2)
    else:
        for k in range(m):
            out[k] = _kdtree_nn(p[k])[1]
    return out


def _sample_period(t: NDArray[np.float64]) -> float:
    """Nominal sample period, s: the median spacing of ``t`` (0 with fewer than two samples)."""
    if t.size < 2:
        return 0.0
    return float(np.median(np.diff(t)))


def _dense_proximity(p: NDArray[np.float64], threshold: float) -> tuple[int, int, float, float]:
    """Onsets, below-threshold pair-samples, min separation (m) and sum of nn distances (m) for small n."""
    n = p.shape[1]
    iu, ju = np.triu_indices(n, 1)
    prev = np.zeros(iu.size, dtype=bool)  # nothing is below before the first sample
    onsets = below_count = 0
    min_sep, nn_sum = np.inf, 0.0
    for _, d in _pairwise_chunks(p):
        pair = d[:, iu, ju]  # (c, P) m
        below = pair < threshold
        onsets += int(np.count_nonzero(below[0] & ~prev))
        onsets += int(np.count_nonzero(below[1:] & ~below[:-1]))
        below_count += int(np.count_nonzero(below))
        prev = below[-1]
        min_sep = min(min_sep, float(pair.min()))
        nn_sum += float(d.min(axis=2).sum())
    return onsets, below_count, min_sep, nn_sum


def _kdtree_proximity(p: NDArray[np.float64], threshold: float) -> tuple[int, int, float, float]:
    """As ``_dense_proximity`` with a k-d tree per sample (memory O(n + pairs below threshold))."""
    n = p.shape[1]
    prev = np.zeros(0, dtype=np.int64)
    onsets = below_count = 0
    min_sep, nn_sum = np.inf, 0.0
    for sample in p:
        tree, nn = _kdtree_nn(sample)
        pairs = tree.query_pairs(threshold, output_type="ndarray")  # (q, 2), distance <= threshold
        if pairs.size:
            dist = np.linalg.norm(sample[pairs[:, 0]] - sample[pairs[:, 1]], axis=1)
            pairs = pairs[dist < threshold]
        keys = np.unique(pairs[:, 0].astype(np.int64) * n + pairs[:, 1])
        onsets += int(np.setdiff1d(keys, prev, assume_unique=True).size)
        below_count += int(keys.size)
        prev = keys
        min_sep = min(min_sep, float(nn.min()))
        nn_sum += float(nn.sum())
    return onsets, below_count, min_sep, nn_sum


def proximity_metrics(t: ArrayLike, positions: ArrayLike, threshold: float) -> dict[str, Any]:
    """Collision counts by the thesis's criterion: two agent centres closer than one agent diameter.

    A pair of agents "collides" while its centre distance is below ``threshold`` (thesis section
    3.5.3, Fig. 3.12: the nearest-neighbour distance under the dashed collision line).

    Args:
        t: (m,) s, sample times (uniformly spaced in recordings).
        positions: (m, n, 3) m, agent centres.
        threshold: m, collision distance (one agent diameter).

    Returns:
        ``proximity_violations``: onsets over all agent pairs, i.e. samples where a pair's distance
        goes from >= threshold to < threshold; a pair already below at the first sample counts once.
        ``proximity_time_s``: sum over pairs of (samples below threshold) * dt, s, with dt the
        median spacing of ``t`` (each sample stands for one nominal period; two pairs below at
        once count twice; 0 with fewer than two samples).
        ``min_separation_m``: smallest centre distance over time and pairs, m (None when n < 2).
        ``mean_nn_distance_m``: mean over time and agents of the nearest-neighbour distance, m
        (None when n < 2).
    """
    tt = np.asarray(t, dtype=float)
    p = _as_positions(positions)
    m, n, _ = p.shape
    if tt.shape != (m,):
        raise ValueError(f"t: expected shape ({m},), got {tt.shape}")
    if threshold <= 0:
        raise ValueError(f"threshold: must be positive, got {threshold}")
    if n < 2 or m == 0:
        return {
            "proximity_violations": 0,
            "proximity_time_s": 0.0,
            "min_separation_m": None,
            "mean_nn_distance_m": None,
        }
    kernel = _dense_proximity if n <= BROADCAST_MAX_AGENTS else _kdtree_proximity
    onsets, below_count, min_sep, nn_sum = kernel(p, float(threshold))
    return {
        "proximity_violations": onsets,
        "proximity_time_s": below_count * _sample_period(tt),
        "min_separation_m": min_sep,
        "mean_nn_distance_m": nn_sum / (m * n),
    }


def thesis_proximity_metrics(positions: ArrayLike, diameter: float) -> dict[str, Any]:
    """The thesis's collision count, per agent, and the nearest-neighbour reading of its use of space.

    Thesis section 3.5.3 and Fig. 3.12: each agent's distance to its nearest other agent, centre
    to centre, is drawn over time with the collision line at one agent diameter; section 3.6:
    "Number of collisions will be the number of times an agent moves below the collision line".
    So each agent's curve is counted on its own: a crossing is a sample where the agent's
    nearest-neighbour distance is below ``diameter`` and the previous sample's was not (an agent
    already below at the first sample counts once, as in ``proximity_metrics``). Two agents that
    close in on each other are two crossings here (one per curve) and one pair onset in
    ``proximity_violations``; an agent whose nearest neighbour changes while it stays below the
    line is one crossing however many pairs it meets.

    Args:
        positions: (m, n, 3) m, agent centres at m samples.
        diameter: m, the collision line (one agent diameter), > 0.

    Returns:
        ``thesis_collisions``: crossings summed over agents (int).
        ``thesis_collisions_per_agent``: (n,) list of each agent's crossings.
        ``nn_distance_diameters``: the mean over samples and agents of the nearest-neighbour
        distance divided by ``diameter`` (None when n < 2 or there are no samples). A
        proximity-based alternative to ``utility_of_space`` after the thesis's wording ("how
        efficiently the agents move in proximity to each other ... the lowest [is] as close to
        each other as possible without triggering a collision"): 1.0 is that lowest level, values
        below 1 need time under the collision line, larger values mean agents keep more room.
    """
    p = _as_positions(positions)
    if not (diameter > 0 and np.isfinite(diameter)):
        raise ValueError(f"diameter: must be a positive length, got {diameter}")
    m, n, _ = p.shape
    if m == 0 or n < 2:
        return {"thesis_collisions": 0, "thesis_collisions_per_agent": [0] * n, "nn_distance_diameters": None}
    nn = nearest_neighbour_distances(p)  # (m, n) m
    below = nn < diameter  # (m, n)
    crossings = below[0].astype(np.int64) + np.count_nonzero(below[1:] & ~below[:-1], axis=0)
    return {
        "thesis_collisions": int(crossings.sum()),
        "thesis_collisions_per_agent": [int(c) for c in crossings],
        "nn_distance_diameters": float(nn.mean() / diameter),
    }


def utility_of_space(xy: ArrayLike, arena_size: ArrayLike, cell: float = 0.1) -> float:
    """Fraction of the arena floor that the swarm flew over: our reading of an undefined thesis metric.

    The thesis never defines "utility of space" (section 3.6, Tables 5.3 and 6.x) beyond words --
    "how efficiently the agents move in proximity to each other", lowest preferred, the lowest
    level being agents moving as close to each other as possible without collisions -- and
    reports percentages (74 % for 3D stigmergy, 78 % for the layered variant, explained by
    collision avoidance needing "more space to manoeuvre") without saying how they were computed.
    This function is therefore our reading, not the thesis's formula: the share of floor cells
    that any agent's horizontal position visited during the run (a swarm that shares narrow
    corridors scores low, one that spreads out or detours scores high). ``nn_distance_diameters``
    of ``thesis_proximity_metrics`` is a proximity-based alternative reading, reported beside it.

    The floor [0, Lx] x [0, Ly] is cut into ``ceil(Lx / cell) x ceil(Ly / cell)`` cells (the last
    row/column may be narrower). Points outside the arena are clipped into the border cells;
    non-finite points are ignored.

    Args:
        xy: (m, n, 2) m, horizontal agent positions (any (..., 2) array works; a (..., 3) array
            uses its first two columns).
        arena_size: (2,) m, (Lx, Ly); extra entries (a height) are ignored.
        cell: m, edge of a square floor cell.

    Returns:
        Visited fraction in [0, 1].
    """
    size = np.asarray(arena_size, dtype=float).ravel()
    if size.size < 2 or np.any(size[:2] <= 0):
        raise ValueError(f"arena_size: expected two positive lengths, got {size.tolist()}")
    if cell <= 0:
        raise ValueError(f"cell: must be positive, got {cell}")
    pts = np.asarray(xy, dtype=float)
    pts = pts.reshape(-1, pts.shape[-1])[:, :2]
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    shape = np.maximum(1, np.ceil(size[:2] / cell - 1e-9)).astype(np.int64)  # (2,) cells per axis
    # the small offset puts points on a cell boundary (0.3 / 0.1 = 2.9999...) into the upper cell
    idx = np.clip(np.floor(pts / cell + 1e-9).astype(np.int64), 0, shape - 1)
    visited = np.unique(idx[:, 0] * shape[1] + idx[:, 1]).size
    return float(visited / (shape[0] * shape[1]))


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
