"""Linear Kalman filter on position and velocity (optionally an acceleration bias), batched.

The world-frame axes of an agent are independent under this model (the accelerometer, once
rotated into the world frame, drives each axis; a fix measures each axis), so the filter runs
one small filter per agent and axis: ``m = 3 n`` rows, each with the state

    x = [p, v]          (position m, velocity m/s), or
    x = [p, v, b]       (plus a world-frame acceleration bias m/s^2).

Prediction over one IMU period ``T`` with the measured world acceleration ``u`` (second-order
Taylor expansion, as eq. 14 of the course report rather than its first-order eq. 13):

    p <- p + T v + T^2/2 (u - b),   v <- v + T (u - b),   b <- b

The process noise is the discrete white-noise acceleration model: an input error of standard
deviation ``sigma_a`` per sample enters through ``G = [T^2/2, T, 0]``, ``Q = sigma_a^2 G G^T``,
plus a random walk of the bias, ``sigma_w^2 T``. A fix ``z`` taken ``lag`` s before the state's
time measures ``p - lag v`` with variance ``sigma_p^2``. Covariances are updated in Joseph form.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


class AxisKalman:
    """``m`` independent 1-D position/velocity(/bias) Kalman filters, stepped together.

    Args:
        x0: (m, d) initial states, d = 2 ([p, v]) or 3 ([p, v, b]).
        P0: (m, d, d) or (d, d) initial covariances.
        dt: s, prediction period.
        accel_std: m/s^2, standard deviation of the acceleration input error per prediction.
        bias_walk: m/s^2/sqrt(s), random-walk density of the bias (d = 3 only).
    """

    def __init__(
        self, x0: NDArray[np.float64], P0: NDArray[np.float64], dt: float, accel_std: float, bias_walk: float = 0.0
    ) -> None:
        self.x = np.array(x0, dtype=float, copy=True)
        m, d = self.x.shape
        if d not in (2, 3):
            raise ValueError(f"state dimension must be 2 or 3, got {d}")
        self.d = d
        self.P = np.array(np.broadcast_to(P0, (m, d, d)), dtype=float, copy=True)
        self.dt = float(dt)
        T = self.dt
        F = np.eye(d)
        F[0, 1] = T
        B = np.array([0.5 * T * T, T, 0.0][:d])
        if d == 3:
            F[0, 2] = -0.5 * T * T
            F[1, 2] = -T
        Q = accel_std**2 * np.outer(B, B)
        if d == 3:
            Q[2, 2] += bias_walk**2 * T
        self.F, self.B, self.Q = F, B, Q

    def predict(self, u: NDArray[np.float64]) -> None:
        """One prediction with measured accelerations ``u`` (m,) m/s^2."""
        self.x = self.x @ self.F.T + np.asarray(u, dtype=float)[:, None] * self.B
        self.P = self.F @ self.P @ self.F.T + self.Q

    def update(self, rows: NDArray[np.int64], z: NDArray[np.float64], variance: float, lag: float = 0.0) -> None:
        """Fuse position measurements ``z`` (k,) m of ``rows`` (k,), taken ``lag`` s before now.

        Args:
            rows: (k,) indices of the filters that got a measurement.
            z: (k,) m, measured positions.
            variance: m^2, measurement noise variance.
            lag: s, age of the measurements (0: taken now).
        """
        if rows.size == 0:
            return
        h = np.zeros(self.d)
        h[0] = 1.0
        h[1] = -lag
        x = self.x[rows]
        P = self.P[rows]
        Ph = P @ h  # (k, d)
        s = np.maximum(Ph @ h + variance, 1e-300)  # (k,) innovation variance (0 only for exact fixes of an exact state)
        K = Ph / s[:, None]  # (k, d)
        x = x + K * (np.asarray(z, dtype=float) - x @ h)[:, None]
        A = np.eye(self.d) - K[:, :, None] * h[None, None, :]  # (k, d, d) I - K h^T
        P = A @ P @ np.swapaxes(A, 1, 2) + variance * K[:, :, None] * K[:, None, :]
        self.x[rows] = x
        self.P[rows] = 0.5 * (P + np.swapaxes(P, 1, 2))

    @property
    def variances(self) -> NDArray[np.float64]:
        """Diagonal of the covariances (m, d)."""
        return np.diagonal(self.P, axis1=1, axis2=2).copy()


def steady_position_std(
    dt: float,
    accel_std: float,
    fix_every: int,
    fix_std: float,
    *,
    bias_walk: float = 0.0,
    bias: bool = True,
    initial: NDArray[np.float64] | None = None,
    cycles: int = 400,
) -> float:
    """Per-axis position standard deviation, m, that the filter settles to with a fix every ``fix_every``
    predictions: the largest over a fix cycle (just before a fix), after ``cycles`` cycles of the
    covariance recursion (no data needed: the covariance of a linear filter does not depend on it).

    Args:
        dt: s, prediction period.
        accel_std: m/s^2, acceleration input error per prediction.
        fix_every: predictions per fix (>= 1).
        fix_std: m, per-axis standard deviation of a fix.
        bias_walk: m/s^2/sqrt(s), random-walk density of the bias (with ``bias``).
        bias: whether the state has the acceleration bias.
        initial: (d, d) initial covariance (default: 1 m^2, 1 (m/s)^2, 1 (m/s^2)^2).
        cycles: fix cycles to iterate.
    """
    d = 3 if bias else 2
    P0 = np.eye(d) if initial is None else np.asarray(initial, dtype=float)
    kf = AxisKalman(np.zeros((1, d)), P0, dt, accel_std, bias_walk)
    rows = np.zeros(1, dtype=np.int64)
    worst = 0.0
    for c in range(cycles):
        for _ in range(max(int(fix_every), 1)):
            kf.predict(np.zeros(1))
        if c == cycles - 1:
            worst = float(kf.P[0, 0, 0])
        kf.update(rows, np.zeros(1), fix_std**2)
    return float(np.sqrt(worst))
