"""Flocking and formation fitness of a migrating swarm (pure numpy, per time step).

Flocking fitness, per time step (the course report's definition, brought to 3-D quadrotors):

* orientation ``o = |sum_i h_i| / N``, with ``h_i`` the unit horizontal heading of agent i. A
  quadrotor can fly in any direction whatever its yaw, so its heading is the direction of its
  horizontal velocity; an agent slower than ``min_speed`` has no heading and adds nothing.
* cohesion ``d = 1 / (1 + mean_i |p_i - c|)``, c the centroid, distances in 3-D, m.
* velocity ``v = max(0, v_c . u) / v_max``, with ``v_c`` the centroid's velocity, ``u`` the unit
  horizontal direction from the centroid to the current waypoint (the migration direction) and
  ``v_max`` the fastest speed the per-axis limits allow along ``u``.
* fitness ``o d v``.

Formation fitness, per time step: distance metric ``1 / (1 + mean slot error)``, where agent
i's slot error is ``|(p_i - c) - (s_i - s_bar)|`` (its offset from the formation's centroid
against its slot's offset from the slots' centroid, m: invariant to where the formation is, as
the Laplacian controller is), the same velocity metric ``v`` as above, and their product.

Arrays: ``positions`` and ``velocities`` are (T, n, 3) m and m/s, one row per time sample.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: m/s, an agent slower than this has no heading
MIN_SPEED = 0.01


def _series(a: ArrayLike) -> NDArray[np.float64]:
    x = np.asarray(a, dtype=float)
    return x[None] if x.ndim == 2 else x


def headings(velocities: ArrayLike, min_speed: float = MIN_SPEED) -> NDArray[np.float64]:
    """Unit horizontal headings (T, n, 2) from velocities (T, n, 3) m/s (0 below ``min_speed``)."""
    v = _series(velocities)[..., :2]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(s > min_speed, v / np.where(s > 0.0, s, 1.0), 0.0)


def orientation(velocities: ArrayLike, min_speed: float = MIN_SPEED) -> NDArray[np.float64]:
    """Orientation metric (T,) in [0, 1]: |sum of unit horizontal headings| / N."""
    h = headings(velocities, min_speed)
    return np.linalg.norm(h.sum(axis=1), axis=-1) / h.shape[1]


def cohesion(positions: ArrayLike) -> NDArray[np.float64]:
    """Cohesion metric (T,) in (0, 1]: 1 / (1 + mean distance m to the centroid)."""
    p = _series(positions)
    c = p.mean(axis=1, keepdims=True)
    return 1.0 / (1.0 + np.linalg.norm(p - c, axis=-1).mean(axis=1))


def speed_limit_along(directions: ArrayLike, v_axis: ArrayLike) -> NDArray[np.float64]:
    """Fastest speed (T,) m/s along unit directions (T, 3) under per-axis limits v_axis (3,) m/s."""
    u = np.abs(np.atleast_2d(np.asarray(directions, dtype=float)))
    v = np.broadcast_to(np.asarray(v_axis, dtype=float), (3,))
    with np.errstate(divide="ignore"):
        per_axis = np.where(u > 1e-12, v / np.where(u > 1e-12, u, 1.0), np.inf)
    return per_axis.min(axis=1)


def migration_speed(velocities: ArrayLike, directions: ArrayLike, v_max: ArrayLike) -> NDArray[np.float64]:
    """Velocity metric (T,): max(0, centroid velocity . direction) / v_max.

    Args:
        velocities: (T, n, 3) m/s.
        directions: (T, 3) or (3,) unit migration directions.
        v_max: (T,) or scalar m/s, the speed the metric is normalised by.
    """
    vc = _series(velocities).mean(axis=1)  # (T, 3) centroid velocity
    u = np.broadcast_to(np.asarray(directions, dtype=float), vc.shape)
    return np.maximum(np.sum(vc * u, axis=1), 0.0) / np.asarray(v_max, dtype=float)


def flocking_fitness(
    positions: ArrayLike, velocities: ArrayLike, directions: ArrayLike, v_max: ArrayLike, min_speed: float = MIN_SPEED
) -> dict[str, NDArray[np.float64]]:
    """Per time step ``o``, ``d``, ``v`` and ``fitness = o d v`` (each (T,)); see the module docstring."""
    o = orientation(velocities, min_speed)
    d = cohesion(positions)
    v = migration_speed(velocities, directions, v_max)
    return {"o": o, "d": d, "v": v, "fitness": o * d * v}


def slot_errors(positions: ArrayLike, slots: ArrayLike) -> NDArray[np.float64]:
    """Slot error (T, n) m of every agent: |(p_i - c) - (s_i - s_bar)|.

    Args:
        positions: (T, n, 3) m.
        slots: (n, 3) m, each agent's place in the formation (any origin).
    """
    p = _series(positions)
    s = np.asarray(slots, dtype=float)
    rel_p = p - p.mean(axis=1, keepdims=True)
    rel_s = s - s.mean(axis=0, keepdims=True)
    return np.linalg.norm(rel_p - rel_s[None], axis=-1)


def formation_fitness(
    positions: ArrayLike, velocities: ArrayLike, slots: ArrayLike, directions: ArrayLike, v_max: ArrayLike
) -> dict[str, NDArray[np.float64]]:
    """Per time step ``error`` (mean slot error, m), ``distance`` = 1 / (1 + error), ``velocity`` and
    ``fitness`` = distance * velocity (each (T,))."""
    err = slot_errors(positions, slots).mean(axis=1)
    dist = 1.0 / (1.0 + err)
    vel = migration_speed(velocities, directions, v_max)
    return {"error": err, "distance": dist, "velocity": vel, "fitness": dist * vel}


def migration_directions(
    t: ArrayLike, centroids: ArrayLike, route: ArrayLike, pass_times: list[float | None] | ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Migration direction and current waypoint at every sample.

    The current waypoint at time t is the first one not yet passed (passed ones have a pass
    time <= t); after the last one is passed it stays the last. The direction is the unit
    horizontal vector from the centroid to it (zero when the centroid is on it).

    Args:
        t: (T,) s, sample times.
        centroids: (T, 3) m.
        route: (W, 3) m, waypoints in order.
        pass_times: (W,) s, when each waypoint was passed (None / NaN: never).

    Returns:
        directions (T, 3), waypoint index (T,).
    """
    t = np.asarray(t, dtype=float)
    w = np.asarray(route, dtype=float).reshape(-1, 3)
    times = np.array([np.nan if x is None else float(x) for x in np.asarray(pass_times, dtype=object).ravel()])
    passed = np.where(np.isnan(times), np.inf, times)
    idx = np.sum(passed[None, :] <= t[:, None] + 1e-9, axis=1)
    idx = np.minimum(idx, len(w) - 1).astype(np.int64)
    d = w[idx] - np.asarray(centroids, dtype=float).reshape(-1, 3)
    d[:, 2] = 0.0
    norm = np.linalg.norm(d, axis=1, keepdims=True)
    return np.where(norm > 1e-9, d / np.where(norm > 0.0, norm, 1.0), 0.0), idx


def time_average(t: ArrayLike, values: ArrayLike, t_end: float | None = None) -> float | None:
    """Mean of uniformly sampled values (T,) over the samples with t <= t_end (all when None)."""
    t = np.asarray(t, dtype=float)
    x = np.asarray(values, dtype=float)
    keep = np.ones(t.size, dtype=bool) if t_end is None else t <= t_end + 1e-9
    return float(x[keep].mean()) if np.any(keep) else None


def route_fitness_series(
    t: ArrayLike,
    positions: ArrayLike,
    velocities: ArrayLike,
    route: ArrayLike,
    pass_times: list[float | None] | ArrayLike,
    v_axis: ArrayLike,
    slots: ArrayLike | None = None,
    min_speed: float = MIN_SPEED,
) -> dict[str, Any]:
    """Every per-step series of a route run: flocking (o, d, v, fitness) and, with slots, formation.

    Args:
        t: (T,) s.
        positions: (T, n, 3) m.
        velocities: (T, n, 3) m/s.
        route: (W, 3) m.
        pass_times: (W,) s or None per waypoint.
        v_axis: (3,) m/s per-axis velocity limit.
        slots: (n, 3) m, formation slots (None: no formation).

    Returns:
        ``{"t", "waypoint", "direction", "flocking": {...}, "formation": {...} or None}``.
    """
    p = np.asarray(positions, dtype=float)
    v = np.asarray(velocities, dtype=float)
    u, idx = migration_directions(t, p.mean(axis=1), route, pass_times)
    vmax = speed_limit_along(u, v_axis)
    vmax = np.where(np.isfinite(vmax), vmax, np.inf)
    flock = flocking_fitness(p, v, u, vmax, min_speed)
    form = formation_fitness(p, v, slots, u, vmax) if slots is not None else None
    return {"t": np.asarray(t, dtype=float), "waypoint": idx, "direction": u, "flocking": flock, "formation": form}
