"""Proximity metrics of any swarm from recorded arrays: nearest-neighbour distances, close
approaches and the thesis's collision count, the use of the arena's floor.

Every task's run reports them (the clock merges them into metrics.json). Everything here reads
plain arrays (positions, times); nothing touches PyBullet or a live simulation.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
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
