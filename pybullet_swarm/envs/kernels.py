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
def fill_own(
    out: NDArray[np.float64],
    s: NDArray[np.float64],
    rates: NDArray[np.float64],
    carrying: NDArray[np.float64],
    t_frac: float,
) -> None:  # pragma: no cover - compiled
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
def clip_rows(
    out: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64]
) -> bool:  # pragma: no cover
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
