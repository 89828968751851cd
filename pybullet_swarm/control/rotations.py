"""Rotation helpers on arrays (scalar-last quaternions as in Bullet)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def quat_to_matrix(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrices (n, 3, 3) body -> world from quaternions (n, 4) (x, y, z, w)."""
    q = np.asarray(q, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def quat_to_euler(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Roll, pitch, yaw (n, 3) rad (intrinsic z-y-x) from quaternions (n, 4) (x, y, z, w)."""
    q = np.asarray(q, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], -1)


def euler_to_quat(rpy: NDArray[np.float64]) -> NDArray[np.float64]:
    """Quaternions (n, 4) (x, y, z, w) from roll, pitch, yaw (n, 3) rad (intrinsic z-y-x)."""
    rpy = np.asarray(rpy, dtype=float)
    cr, sr = np.cos(rpy[..., 0] / 2), np.sin(rpy[..., 0] / 2)
    cp, sp = np.cos(rpy[..., 1] / 2), np.sin(rpy[..., 1] / 2)
    cy, sy = np.cos(rpy[..., 2] / 2), np.sin(rpy[..., 2] / 2)
    return np.stack(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ],
        -1,
    )
