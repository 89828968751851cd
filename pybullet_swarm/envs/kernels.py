"""Compiled fill of the ``own`` observation block: one call for every agent, whatever the swarm size.

A numpy version of the same arithmetic (quaternion to roll/pitch/yaw, copies, clipping) costs
tens of microseconds per step in dispatch alone, which at one agent is a sizeable part of a
planner period's physics.
"""
from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray


@numba.njit(cache=True)
def fill_own(out: NDArray[np.float64], s: NDArray[np.float64], rates: NDArray[np.float64],
             carrying: NDArray[np.float64], t_frac: float) -> None:  # pragma: no cover - compiled
    """Write the 14 ``own`` columns of every row of ``out`` (n, dim).

    Args:
        out: (n, dim) observation rows, columns 0..13 written.
        s: (n, 13) state rows: position m, quaternion (x, y, z, w), velocity m/s, angular velocity.
        rates: (n, 3) body rates, rad/s.
        carrying: (n,) 1.0 when the agent holds a box, else 0.0.
        t_frac: elapsed time over the time limit.
    """
    for i in range(s.shape[0]):
        for j in range(3):
            out[i, j] = s[i, j]
            out[i, 3 + j] = s[i, 7 + j]
            out[i, 9 + j] = rates[i, j]
        x, y, z, w = s[i, 3], s[i, 4], s[i, 5], s[i, 6]
        out[i, 6] = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
        sp = 2.0 * (w * y - z * x)
        out[i, 7] = math.asin(min(1.0, max(-1.0, sp)))
        out[i, 8] = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        out[i, 12] = carrying[i]
        out[i, 13] = t_frac


@numba.njit(cache=True)
def clip_rows(out: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64]) -> bool:  # pragma: no cover
    """Clip every row of ``out`` (n, dim) to [low, high] (dim,) in place, non-finite values to 0;
    returns True when a value was not finite."""
    bad = False
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            v = out[i, j]
            if not math.isfinite(v):
                bad = True
                v = 0.0
            if v < low[j]:
                v = low[j]
            elif v > high[j]:
                v = high[j]
            out[i, j] = v
    return bad


@numba.njit(cache=True)
def fill_neighbours(out: NDArray[np.float64], col: int, own: NDArray[np.float64], own_vel: NDArray[np.float64],
                    pos: NDArray[np.float64], vel: NDArray[np.float64], cand: NDArray[np.int64], k: int,
                    radius: float) -> None:  # pragma: no cover - compiled
    """Write the ``neighbours`` block (7 k columns from ``col``) of every row of ``out``.

    For agent i the candidates are ``cand[i]`` (or ``cand[0]`` for every agent when ``cand`` has one
    row: all agents, brute force for small swarms); indices outside [0, n) and i itself are skipped.
    The k nearest candidates within ``radius`` (true positions) are written nearest first (ties in
    candidate order) as relative position, relative velocity (to what the agent knows of itself) and
    a present flag; the remaining slots are zeros.

    Args:
        out: (n, dim) observation rows.
        col: first column of the block.
        own: (n, 3) m, each agent's own position as it knows it.
        own_vel: (n, 3) m/s, its own velocity as it knows it.
        pos: (n, 3) m, true positions.
        vel: (n, 3) m/s, true velocities.
        cand: (n, m) or (1, m) candidate indices.
        k: neighbour slots.
        radius: m, sensing radius (inclusive).
    """
    n = pos.shape[0]
    r2 = radius * radius
    best_d = np.empty(k)
    best_j = np.empty(k, dtype=np.int64)
    shared = cand.shape[0] == 1
    for i in range(n):
        row = 0 if shared else i
        cnt = 0
        for c in range(cand.shape[1]):
            j = cand[row, c]
            if j < 0 or j >= n or j == i:
                continue
            dx, dy, dz = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2]
            d2 = dx * dx + dy * dy + dz * dz
            if d2 > r2:
                continue
            if cnt < k:
                q = cnt
                cnt += 1
            elif d2 < best_d[k - 1]:
                q = k - 1
            else:
                continue
            while q > 0 and best_d[q - 1] > d2:
                best_d[q] = best_d[q - 1]
                best_j[q] = best_j[q - 1]
                q -= 1
            best_d[q] = d2
            best_j[q] = j
        for q in range(k):
            base = col + 7 * q
            if q < cnt:
                j = best_j[q]
                for a in range(3):
                    out[i, base + a] = pos[j, a] - own[i, a]
                    out[i, base + 3 + a] = vel[j, a] - own_vel[i, a]
                out[i, base + 6] = 1.0
            else:
                for a in range(7):
                    out[i, base + a] = 0.0
