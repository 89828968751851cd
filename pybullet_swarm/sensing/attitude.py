"""Attitude from the gyroscope with accelerometer and heading corrections, vectorised over agents.

Quaternions are scalar-last (x, y, z, w) as everywhere in the project; a quaternion ``q`` maps
body to world. The filter is a complementary filter on the rotation group: the gyroscope's
body rates are integrated exactly over each IMU period (``q <- q (x) Exp(omega T)``); the
accelerometer pulls the estimated "up" direction towards the measured specific force with a
first-order gain (roll and pitch only); an optional absolute heading (motion capture) pulls the
yaw by a fraction of its error at every fix.

A quadrotor's accelerometer sees thrust plus drag, not gravity: in a sustained acceleration the
specific force tilts with the airframe and a correction towards gravity pulls the tilt estimate
towards level. That correction (``update(..., tilt=True)``, used by the IMU-only dead
reckoning) is faded out when the norm of the specific force departs from g; the fused estimator
corrects the tilt against the expected specific force instead (see
``OnboardEstimation._level_from_bias``) and calls ``update(..., tilt=False)``.
"""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np
from numpy.typing import NDArray


# The quaternion helpers below run several times per control tick on every agent; as the
# controller's kernels they are compiled loops over rows (n, ...) rather than chains of small
# numpy operations, whose per-call overhead dominates for swarms of a few agents.


@numba.njit(cache=True)
def quat_multiply(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Hamilton products ``a (x) b`` (n, 4) of quaternions (n, 4) (x, y, z, w)."""
    out = np.empty((a.shape[0], 4))
    for i in range(a.shape[0]):
        ax, ay, az, aw = a[i, 0], a[i, 1], a[i, 2], a[i, 3]
        bx, by, bz, bw = b[i, 0], b[i, 1], b[i, 2], b[i, 3]
        out[i, 0] = aw * bx + ax * bw + ay * bz - az * by
        out[i, 1] = aw * by - ax * bz + ay * bw + az * bx
        out[i, 2] = aw * bz + ax * by - ay * bx + az * bw
        out[i, 3] = aw * bw - ax * bx - ay * by - az * bz
    return out


@numba.njit(cache=True)
def rotation_matrices(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrices (n, 3, 3) body -> world of unit quaternions (n, 4) (x, y, z, w)."""
    R = np.empty((q.shape[0], 3, 3))
    for i in range(q.shape[0]):
        x, y, z, w = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        R[i, 0, 0] = 1 - 2 * (y * y + z * z)
        R[i, 0, 1] = 2 * (x * y - z * w)
        R[i, 0, 2] = 2 * (x * z + y * w)
        R[i, 1, 0] = 2 * (x * y + z * w)
        R[i, 1, 1] = 1 - 2 * (x * x + z * z)
        R[i, 1, 2] = 2 * (y * z - x * w)
        R[i, 2, 0] = 2 * (x * z - y * w)
        R[i, 2, 1] = 2 * (y * z + x * w)
        R[i, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


@numba.njit(cache=True)
def quat_exp(rotvec: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit quaternions (n, 4) of rotation vectors (n, 3) rad (axis times angle)."""
    out = np.empty((rotvec.shape[0], 4))
    for i in range(rotvec.shape[0]):
        angle = math.sqrt(rotvec[i, 0] ** 2 + rotvec[i, 1] ** 2 + rotvec[i, 2] ** 2)
        # sin(angle / 2) / angle, with its series near zero
        k = 0.5 - angle * angle / 48.0 if angle < 1e-6 else math.sin(0.5 * angle) / angle
        for j in range(3):
            out[i, j] = k * rotvec[i, j]
        out[i, 3] = math.cos(0.5 * angle)
    return out


@numba.njit(cache=True)
def quat_log(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation vectors (n, 3) rad of unit quaternions (n, 4) (the shorter way round)."""
    out = np.empty((q.shape[0], 3))
    for i in range(q.shape[0]):
        sign = -1.0 if q[i, 3] < 0.0 else 1.0
        s = math.sqrt(q[i, 0] ** 2 + q[i, 1] ** 2 + q[i, 2] ** 2)
        k = 2.0 if s < 1e-12 else 2.0 * math.atan2(s, sign * q[i, 3]) / s
        for j in range(3):
            out[i, j] = sign * k * q[i, j]
    return out


@numba.njit(cache=True)
def cross_rows(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Row-wise cross products (n, 3) of vectors (n, 3)."""
    out = np.empty((a.shape[0], 3))
    for i in range(a.shape[0]):
        out[i, 0] = a[i, 1] * b[i, 2] - a[i, 2] * b[i, 1]
        out[i, 1] = a[i, 2] * b[i, 0] - a[i, 0] * b[i, 2]
        out[i, 2] = a[i, 0] * b[i, 1] - a[i, 1] * b[i, 0]
    return out


def quat_conjugate(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Inverse rotation of unit quaternions (..., 4)."""
    out = np.array(q, dtype=float, copy=True)
    out[..., :3] *= -1.0
    return out


def quat_normalize(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit quaternions (..., 4)."""
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def yaw_of(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Heading (...,) rad of quaternions (..., 4): the yaw of the z-y-x Euler angles."""
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def wrap_angle(a: NDArray[np.float64] | float) -> NDArray[np.float64]:
    """Angles wrapped into [-pi, pi) rad."""
    return (np.asarray(a, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def mean_body_rates(q_prev: NDArray[np.float64], q_now: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
    """Mean body rates (n, 3) rad/s that turn ``q_prev`` into ``q_now`` (n, 4) in ``dt`` s.

    This is what an IMU's integrated gyroscope output (delta angle / period) reports.
    """
    return quat_log(quat_multiply(quat_conjugate(q_prev), np.ascontiguousarray(q_now))) / dt


@dataclasses.dataclass(frozen=True)
class AttitudeGains:
    """Gains of the complementary attitude filter.

    Attributes:
        tilt: 1/s, accelerometer correction of roll and pitch (0: gyroscope only).
        heading: fraction of the heading error removed at each heading fix, in [0, 1].
        gate: m/s^2, the accelerometer correction fades to zero as | |f| - g | grows to this.
    """

    tilt: float = 0.5
    heading: float = 0.3
    gate: float = 1.0


class ComplementaryFilter:
    """Attitude estimates of ``n`` agents from gyroscope, accelerometer and optional heading fixes.

    Args:
        q0: (n, 4) initial attitude estimates (x, y, z, w).
        gains: correction gains.
        gravity: m/s^2.
    """

    def __init__(self, q0: NDArray[np.float64], gains: AttitudeGains, gravity: float) -> None:
        self._q = quat_normalize(np.array(q0, dtype=float, copy=True))
        self._R: NDArray[np.float64] | None = None
        self.gains = gains
        self.gravity = float(gravity)

    @property
    def q(self) -> NDArray[np.float64]:
        """Attitude estimates (n, 4) (x, y, z, w); assign to replace them."""
        return self._q

    @q.setter
    def q(self, value: NDArray[np.float64]) -> None:
        self._q = value
        self._R = None

    def update(self, gyro: NDArray[np.float64], accel: NDArray[np.float64], dt: float, *, tilt: bool = True) -> None:
        """Propagate by one IMU period.

        Args:
            gyro: (n, 3) rad/s, bias-corrected body rates (mean over the period).
            accel: (n, 3) m/s^2, bias-corrected specific force in the body frame.
            dt: s, the IMU period.
            tilt: correct roll and pitch towards the accelerometer's gravity direction (False: the
                caller corrects the tilt itself, e.g. from a Kalman filter's acceleration bias).
        """
        omega = gyro
        k = self.gains.tilt
        if tilt and k > 0.0:
            norm = np.linalg.norm(accel, axis=1)
            weight = np.clip(1.0 - np.abs(norm - self.gravity) / self.gains.gate, 0.0, 1.0)
            measured_up = accel / np.maximum(norm, 1e-9)[:, None]
            estimated_up = self.rotation[:, 2, :]  # world z seen in the body frame: third row of R
            # rotating the body by +k (m x e) moves the estimated up direction towards the measured one
            omega = gyro + (k * weight)[:, None] * cross_rows(measured_up, np.ascontiguousarray(estimated_up))
        self.q = quat_normalize(quat_multiply(self.q, quat_exp(omega * dt)))

    def rotate_world(self, rotvec: NDArray[np.float64]) -> None:
        """Turn the estimates by small world-frame rotations (n, 3) rad: ``q <- Exp(rotvec) (x) q``."""
        self.q = quat_normalize(quat_multiply(quat_exp(rotvec), self.q))

    def correct_heading(self, heading: NDArray[np.float64], rows: NDArray[np.int64] | None = None) -> None:
        """Pull the yaw of ``rows`` (default: all) towards measured headings (k,) rad."""
        sel = slice(None) if rows is None else rows
        err = wrap_angle(np.asarray(heading, dtype=float) - yaw_of(self.q[sel]))
        turn = self.gains.heading * err
        rz = np.zeros((turn.shape[0], 4))
        rz[:, 2] = np.sin(0.5 * turn)
        rz[:, 3] = np.cos(0.5 * turn)
        q = self._q.copy()
        q[sel] = quat_normalize(quat_multiply(rz, q[sel]))  # world-frame turn about z
        self.q = q

    @property
    def rotation(self) -> NDArray[np.float64]:
        """Estimated rotation matrices (n, 3, 3) body -> world (cached until the estimate changes)."""
        if self._R is None:
            self._R = rotation_matrices(self._q)
        return self._R
