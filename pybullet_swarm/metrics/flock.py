"""Order parameters of a flock in a bounded arena, per sample and time-averaged (pure numpy).

Two families, both computed from recorded positions (T, n, 3) m and velocities (T, n, 3) m/s:

Vásárhelyi et al. (Science Robotics 2018), the order parameters their evolutionary optimisation
scores (robotsim), with ``A_t`` the graph of pairs within ``connection_range`` m:

* ``velocity_correlation``: mean over agents i of the mean, over the other members j of i's
  connected cluster, of ``v_i . v_j / (|v_i| |v_j|)`` (agents alone in their cluster left out;
  0 when every agent is alone);
* ``collision_ratio``: the fraction of the N (N - 1) / 2 pairs closer than ``r_coll`` m;
* ``distance_outside_m``: the mean over agents of the horizontal distance outside the arena
  [0, Lx] x [0, Ly] (0 inside);
* ``disconnected_agents``: agents with no other agent within ``connection_range``;
* ``min_cluster`` / ``max_cluster``: sizes of the smallest and largest connected clusters;
* ``mean_speed``: mean |v_i| m/s.

SwarmLab (Soria et al., IROS 2020, ``compute_swarm_performance.m``) on the same graph:

* ``safety = 1 - collision_ratio``;
* ``order``: mean over agents of the mean ``v_i . v_j / (|v_i| |v_j|)`` over i's neighbours (an agent
  without neighbours counts 1);
* ``union = (N - N_cc) / (N - 1)``, N_cc the number of connected components;
* ``connectivity = lambda_2(L) / N``, the algebraic connectivity of the graph's Laplacian over N.

``fitness`` is the robotsim product of transfer functions of the time-averaged order parameters
(see ``flock_fitness``). Every time average is over the samples at or after ``warmup_s``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: m/s, a velocity slower than this has no direction (its correlations count 0)
MIN_SPEED = 1e-6
#: samples per block of the pairwise computations (bounds the (block, n, n) temporaries)
BLOCK = 512

#: the keys of ``metrics.json["flock"]``, in order
FLOCK_KEYS = (
    "velocity_correlation",
    "collision_ratio",
    "distance_outside_m",
    "disconnected_agents",
    "min_cluster",
    "max_cluster",
    "mean_speed",
    "safety",
    "order",
    "union",
    "connectivity",
    "fitness",
)


@dataclasses.dataclass(frozen=True)
class FitnessTolerances:
    """Targets and tolerances of the robotsim transfer functions (``flock_fitness``).

    Attributes:
        v_flock: m/s, the preferred flocking speed.
        v_tol: m/s, speed below v_flock at which the speed factor reaches 0 (F1's width).
        r_tol: m, mean distance outside the arena at which the wall factor falls to 1/e (F2's width).
        a_tol: collision ratio at which the collision factor is 1/4 (F3's constant).
        disc_tol: disconnected agents at which the disconnection factor is 1/4.
        cluster_tol: agents missing from the largest cluster at which the cluster factor is 1/4.
    """

    v_flock: float
    v_tol: float
    r_tol: float
    a_tol: float = 3e-5
    disc_tol: float = 1.0
    cluster_tol: float = 1.0


def _series(a: ArrayLike) -> NDArray[np.float64]:
    x = np.asarray(a, dtype=float)
    return x[None] if x.ndim == 2 else x


def unit_velocities(velocities: ArrayLike) -> NDArray[np.float64]:
    """Unit velocities (T, n, 3) of velocities (T, n, 3) m/s (0 where slower than ``MIN_SPEED``)."""
    v = _series(velocities)
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(s > MIN_SPEED, v / np.where(s > MIN_SPEED, s, 1.0), 0.0)


def pair_distances(positions: ArrayLike) -> NDArray[np.float64]:
    """Pairwise centre distances (T, n, n) m of positions (T, n, 3) m."""
    p = _series(positions)
    d = p[:, :, None, :] - p[:, None, :, :]
    return np.sqrt(np.einsum("tijk,tijk->tij", d, d))


def adjacency(distances: NDArray[np.float64], radius: float) -> NDArray[np.bool_]:
    """Graph (T, n, n) of distinct pairs within ``radius`` m (inclusive), from distances (T, n, n) m."""
    a = distances <= radius
    n = a.shape[-1]
    a[:, np.arange(n), np.arange(n)] = False
    return a


def cluster_labels(adj: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Connected-component label (T, n) of every agent: the smallest index in its component."""
    t, n, _ = adj.shape
    labels = np.broadcast_to(np.arange(n), (t, n)).copy()
    for _ in range(n):  # label propagation: at most n - 1 rounds to cross a component
        nb = np.where(adj, labels[:, None, :], n).min(axis=2)
        new = np.minimum(labels, nb)
        if np.array_equal(new, labels):
            break
        labels = new
    return labels


def cluster_sizes(labels: NDArray[np.int64]) -> NDArray[np.int64]:
    """Size (T, n) of the cluster each agent belongs to, from labels (T, n)."""
    return (labels[:, :, None] == labels[:, None, :]).sum(axis=2)


def velocity_correlation(unit_v: NDArray[np.float64], labels: NDArray[np.int64]) -> NDArray[np.float64]:
    """Vásárhelyi's velocity correlation (T,) within connected clusters (see the module docstring)."""
    n = unit_v.shape[1]
    same = labels[:, :, None] == labels[:, None, :]
    same[:, np.arange(n), np.arange(n)] = False
    dots = np.einsum("tik,tjk->tij", unit_v, unit_v)
    k = same.sum(axis=2)  # (T, n) other members of each agent's cluster
    per_agent = np.where(k > 0, (dots * same).sum(axis=2) / np.maximum(k, 1), 0.0)
    counted = (k > 0).sum(axis=1)
    return np.where(counted > 0, per_agent.sum(axis=1) / np.maximum(counted, 1), 0.0)


def collision_ratio(distances: NDArray[np.float64], r_coll: float) -> NDArray[np.float64]:
    """Fraction (T,) of the n (n - 1) / 2 pairs closer than ``r_coll`` m (0 for one agent)."""
    n = distances.shape[-1]
    if n < 2:
        return np.zeros(distances.shape[0])
    iu = np.triu_indices(n, 1)
    return (distances[:, iu[0], iu[1]] < r_coll).mean(axis=1)


def distance_outside(positions: ArrayLike, arena_size: ArrayLike) -> NDArray[np.float64]:
    """Mean horizontal distance (T,) m of the agents outside the arena [0, Lx] x [0, Ly] (0 inside)."""
    p = _series(positions)[..., :2]
    size = np.asarray(arena_size, dtype=float).reshape(2)
    out = np.maximum(-p, 0.0) + np.maximum(p - size, 0.0)
    return np.linalg.norm(out, axis=-1).mean(axis=1)


def swarmlab_order(unit_v: NDArray[np.float64], adj: NDArray[np.bool_]) -> NDArray[np.float64]:
    """SwarmLab's order (T,): mean over agents of the mean cosine to their neighbours (1 without any)."""
    dots = np.einsum("tik,tjk->tij", unit_v, unit_v)
    k = adj.sum(axis=2)
    per_agent = np.where(k > 0, (dots * adj).sum(axis=2) / np.maximum(k, 1), 1.0)
    return per_agent.mean(axis=1)


def union(labels: NDArray[np.int64]) -> NDArray[np.float64]:
    """SwarmLab's union (T,) = (N - N_cc) / (N - 1) (1 for one agent)."""
    n = labels.shape[1]
    if n < 2:
        return np.ones(labels.shape[0])
    n_cc = (labels == np.arange(n)[None, :]).sum(axis=1)
    return (n - n_cc) / (n - 1)


def algebraic_connectivity(adj: NDArray[np.bool_]) -> NDArray[np.float64]:
    """lambda_2 (T,) of the Laplacian L = D - A of each graph (T, n, n) (0 for one agent)."""
    a = adj.astype(float)
    if a.shape[-1] < 2:
        return np.zeros(a.shape[0])
    lap = -a
    n = a.shape[-1]
    lap[:, np.arange(n), np.arange(n)] = a.sum(axis=2)
    return np.linalg.eigvalsh(lap)[:, 1]


def order_series(
    positions: ArrayLike,
    velocities: ArrayLike,
    *,
    arena_size: ArrayLike,
    r_coll: float,
    connection_range: float,
) -> dict[str, NDArray[np.float64]]:
    """Every order parameter per sample (each (T,)), plus ``min_distance_m`` (T,) the closest pair.

    Args:
        positions: (T, n, 3) m.
        velocities: (T, n, 3) m/s.
        arena_size: (2,) m.
        r_coll: m, pairs closer than this collide.
        connection_range: m, pairs within it are connected (clusters, neighbours).
    """
    p, v = _series(positions), _series(velocities)
    t_n, n = p.shape[0], p.shape[1]
    keys = [k for k in FLOCK_KEYS if k != "fitness"] + ["min_distance_m"]
    out = {k: np.zeros(t_n) for k in keys}
    for s in range(0, t_n, BLOCK):
        sl = slice(s, min(s + BLOCK, t_n))
        d = pair_distances(p[sl])
        adj = adjacency(d, connection_range)
        labels = cluster_labels(adj)
        sizes = cluster_sizes(labels)
        u = unit_velocities(v[sl])
        out["velocity_correlation"][sl] = velocity_correlation(u, labels)
        out["collision_ratio"][sl] = collision_ratio(d, r_coll)
        out["distance_outside_m"][sl] = distance_outside(p[sl], arena_size)
        out["disconnected_agents"][sl] = (~adj.any(axis=2)).sum(axis=1)
        out["min_cluster"][sl] = sizes.min(axis=1)
        out["max_cluster"][sl] = sizes.max(axis=1)
        out["mean_speed"][sl] = np.linalg.norm(v[sl], axis=-1).mean(axis=1)
        out["safety"][sl] = 1.0 - out["collision_ratio"][sl]
        out["order"][sl] = swarmlab_order(u, adj)
        out["union"][sl] = union(labels)
        out["connectivity"][sl] = algebraic_connectivity(adj) / n
        if n > 1:
            iu = np.triu_indices(n, 1)
            out["min_distance_m"][sl] = d[:, iu[0], iu[1]].min(axis=1)
        else:
            out["min_distance_m"][sl] = np.inf
    return out


def transfer_peak(x: float, x0: float, width: float) -> float:
    """F1: 0 up to ``x0 - width``, rising as sin^2 to 1 at ``x0`` and 1 beyond (robotsim's step)."""
    if x >= x0:
        return 1.0
    if x <= x0 - width:
        return 0.0
    return math.sin(0.5 * math.pi * (x - x0 + width) / width) ** 2


def transfer_gauss(x: float, width: float) -> float:
    """F2: exp(-x^2 / width^2)."""
    return math.exp(-(x * x) / (width * width))


def transfer_hyperbolic(x: float, a: float) -> float:
    """F3: a^2 / (x + a)^2 (1 at x = 0, 1/4 at x = a)."""
    return (a * a) / ((x + a) * (x + a))


def flock_fitness(averages: dict[str, float], n: int, tol: FitnessTolerances) -> float:
    """robotsim's fitness: the product of the transfer functions of the time-averaged order parameters.

    ``F1(mean_speed; v_flock, v_tol) F3(collision_ratio; a_tol) F2(distance_outside_m; r_tol)
    max(velocity_correlation, 0) F3(disconnected_agents; disc_tol) F3(n - max_cluster; cluster_tol)``.
    """
    return (
        transfer_peak(averages["mean_speed"], tol.v_flock, tol.v_tol)
        * transfer_hyperbolic(averages["collision_ratio"], tol.a_tol)
        * transfer_gauss(averages["distance_outside_m"], tol.r_tol)
        * max(averages["velocity_correlation"], 0.0)
        * transfer_hyperbolic(averages["disconnected_agents"], tol.disc_tol)
        * transfer_hyperbolic(max(n - averages["max_cluster"], 0.0), tol.cluster_tol)
    )


def flock_metrics(
    series: dict[str, NDArray[np.float64]], t: ArrayLike, warmup_s: float, n: int, tol: FitnessTolerances
) -> dict[str, Any]:
    """``metrics.json["flock"]``: the time averages of ``order_series`` over samples at or after
    ``warmup_s`` (None each when no sample is), and the fitness of those averages."""
    tt = np.asarray(t, dtype=float)
    keep = tt >= warmup_s - 1e-9
    if not np.any(keep):
        return {k: None for k in FLOCK_KEYS}
    avg = {k: float(np.mean(series[k][keep])) for k in FLOCK_KEYS if k != "fitness"}
    avg["fitness"] = flock_fitness(avg, n, tol)
    return avg
