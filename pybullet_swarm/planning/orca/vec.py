"""3-vectors as tuples inside the compiled kernels: the arithmetic of the ORCA package.

Every function is compiled (``njit``); vectors are ``(x, y, z)`` tuples of floats, matrices
``(n, 3)`` float arrays read and written by row.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.orca.cache import njit

Vec = tuple[float, float, float]


@njit
def dot(a: Vec, b: Vec) -> float:
    """a . b."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit
def cross(a: Vec, b: Vec) -> Vec:
    """a x b."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit
def add(a: Vec, b: Vec, s: float) -> Vec:
    """a + s b."""
    return (a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2])


@njit
def scale(a: Vec, s: float) -> Vec:
    """s a."""
    return (a[0] * s, a[1] * s, a[2] * s)


@njit
def row(A: NDArray[np.float64], i: int) -> Vec:
    """Row i of an (n, 3) array."""
    return (A[i, 0], A[i, 1], A[i, 2])


@njit
def set_row(A: NDArray[np.float64], i: int, a: Vec) -> None:
    """Write a into row i of an (n, 3) array."""
    A[i, 0] = a[0]
    A[i, 1] = a[1]
    A[i, 2] = a[2]


@njit
def axis(k: int, s: float) -> Vec:
    """s times the unit vector of axis k."""
    if k == 0:
        return (s, 0.0, 0.0)
    if k == 1:
        return (0.0, s, 0.0)
    return (0.0, 0.0, s)
