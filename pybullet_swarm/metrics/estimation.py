"""Estimation error: position and heading error of the Kalman filter and of its two baselines.

The course report scores an estimator by its mean Euclidean position error and mean absolute
heading error over a run; ``metrics.json`` keeps those (``mean_error_m``, ``heading_error_rad``)
and adds the root-mean-square position error (``rmse_m``), per source:

* ``kalman``: the fused estimate the agents fly on, scored at every control tick;
* ``gps``: positioning alone, scored at every fix (the error of the fixes themselves, i.e. the
  sensor's noise; ``hold_rmse_m`` adds the staleness of holding the last fix between fixes);
* ``imu``: IMU dead reckoning (calibrated accelerometer and gyroscope, no fixes), scored at
  every control tick.

Consistency of a filter is judged by the normalised estimation error squared
``NEES = e^T P^-1 e``: for a consistent filter its average over ``N`` independent runs, times
``N``, is chi-square distributed with ``N d`` degrees of freedom (``d`` state components).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray


def wrapped_abs(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """|a - b| of angles (...,) rad, wrapped into [0, pi]."""
    d = (np.asarray(a, dtype=float) - np.asarray(b, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi
    return np.abs(d)


def nees(errors: NDArray[np.float64], covariances: NDArray[np.float64]) -> NDArray[np.float64]:
    """Normalised estimation error squared (...,) of errors (..., d) with covariances (..., d, d)."""
    e = np.asarray(errors, dtype=float)
    sol = np.linalg.solve(np.asarray(covariances, dtype=float), e[..., None])[..., 0]
    return np.sum(e * sol, axis=-1)


def nees_bounds(dof: int, runs: int, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided ``confidence`` interval of the average NEES over ``runs`` runs of a ``dof``-state filter."""
    from scipy.stats import chi2

    tail = 0.5 * (1.0 - confidence)
    k = dof * runs
    return float(chi2.ppf(tail, k) / runs), float(chi2.ppf(1.0 - tail, k) / runs)


class ErrorAccumulator:
    """Running position and heading error statistics of ``channels`` estimate sources at once
    (over agents and time), so one control tick costs a handful of array operations."""

    def __init__(self, channels: int = 1) -> None:
        self.channels = channels
        self.count = np.zeros(channels)  # samples (agent-instants)
        self.sum_sq = np.zeros((channels, 3))  # m^2, per axis
        self.sum_norm = np.zeros(channels)  # m
        self.max_norm = np.zeros(channels)  # m
        self.heading_count = np.zeros(channels)
        self.sum_heading = np.zeros(channels)  # rad

    def add(
        self,
        estimate: NDArray[np.float64],
        truth: NDArray[np.float64],
        est_yaw: NDArray[np.float64] | None = None,
        true_yaw: NDArray[np.float64] | None = None,
    ) -> None:
        """Add errors of positions (channels, k, 3) m (or (k, 3) for one channel) against the truth
        (broadcastable), and optionally headings (channels, k) rad against ``true_yaw`` (k,)."""
        e = np.asarray(estimate, dtype=float) - truth
        e = e.reshape(self.channels, -1, 3)
        k = e.shape[1]
        if k == 0:
            return
        e2 = e * e
        self.count += k
        self.sum_sq += e2.sum(axis=1)
        norm = np.sqrt(e2.sum(axis=2))
        self.sum_norm += norm.sum(axis=1)
        np.maximum(self.max_norm, norm.max(axis=1), out=self.max_norm)
        if est_yaw is not None and true_yaw is not None:
            h = wrapped_abs(np.reshape(est_yaw, (-1, k)), true_yaw)
            self.heading_count[: h.shape[0]] += k
            self.sum_heading[: h.shape[0]] += h.sum(axis=1)

    def summary(self, channel: int = 0) -> dict[str, Any]:
        """``rmse_m``, ``mean_error_m``, ``heading_error_rad`` (None without data), ``rmse_axis_m``,
        ``max_error_m``, ``samples`` of one channel."""
        c = float(self.count[channel])
        if c == 0:
            return {
                "rmse_m": None,
                "mean_error_m": None,
                "heading_error_rad": None,
                "rmse_axis_m": None,
                "max_error_m": None,
                "samples": 0,
            }
        hc = float(self.heading_count[channel])
        return {
            "rmse_m": math.sqrt(float(self.sum_sq[channel].sum()) / c),
            "mean_error_m": float(self.sum_norm[channel]) / c,
            "heading_error_rad": float(self.sum_heading[channel]) / hc if hc else None,
            "rmse_axis_m": [math.sqrt(float(x) / c) for x in self.sum_sq[channel]],
            "max_error_m": float(self.max_norm[channel]),
            "samples": int(c),
        }


class EstimationErrors:
    """The errors of a run's onboard estimation against the truth, accumulated while it runs."""

    SOURCES = ("kalman", "gps", "imu")
    #: channels scored at every control tick
    TICK = ("kalman", "imu", "gps_hold", "velocity")

    def __init__(self) -> None:
        self.tick = ErrorAccumulator(len(self.TICK))
        self.fix = ErrorAccumulator(1)
        self.tilt_sum = 0.0
        self.tilt_count = 0
        self.nees_sum = 0.0
        self.nees_count = 0

    def add_fix(
        self,
        valid: NDArray[np.bool_],
        fixes: NDArray[np.float64],
        headings: NDArray[np.float64] | None,
        true_positions: NDArray[np.float64],
        true_yaw: NDArray[np.float64],
    ) -> None:
        """Score the fixes (n, 3) m (and headings (n,) rad) of the agents marked ``valid`` (n,)."""
        self.fix.add(
            fixes[valid], true_positions[valid], None if headings is None else headings[valid], true_yaw[valid]
        )

    def add_tick(
        self,
        kalman: NDArray[np.float64],
        kalman_yaw: NDArray[np.float64],
        velocity: NDArray[np.float64],
        tilt_error: NDArray[np.float64],
        position_variance: NDArray[np.float64],
        imu: NDArray[np.float64],
        imu_yaw: NDArray[np.float64],
        held_fix: NDArray[np.float64],
        true_positions: NDArray[np.float64],
        true_velocities: NDArray[np.float64],
        true_yaw: NDArray[np.float64],
    ) -> None:
        """Score one control tick.

        Args:
            kalman: (n, 3) m, fused position estimates.
            kalman_yaw: (n,) rad, their headings.
            velocity: (n, 3) m/s, fused velocity estimates.
            tilt_error: (n,) rad, angle between estimated and true body z axes.
            position_variance: (n, 3) m^2, the filter's position variance per axis.
            imu: (n, 3) m, dead-reckoning positions.
            imu_yaw: (n,) rad, their headings.
            held_fix: (n, 3) m, the last fix of each agent.
            true_positions: (n, 3) m, the true positions.
            true_velocities: (n, 3) m/s, the true velocities.
            true_yaw: (n,) rad, the true headings.
        """
        est = np.stack([kalman, imu, held_fix, velocity])  # (4, n, 3)
        truth = np.stack([true_positions, true_positions, true_positions, true_velocities])
        self.tick.add(est, truth, np.stack([kalman_yaw, imu_yaw]), true_yaw)
        self.tilt_sum += float(tilt_error.sum())
        self.tilt_count += tilt_error.size
        e = est[0] - true_positions
        self.nees_sum += float(np.sum(e * e / np.maximum(position_variance, 1e-30)))
        self.nees_count += e.shape[0]

    def metrics(self, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """The ``estimation`` entry of ``metrics.json``."""
        idx = {name: i for i, name in enumerate(self.TICK)}
        out: dict[str, Any] = {
            "kalman": self.tick.summary(idx["kalman"]),
            "gps": self.fix.summary(0),
            "imu": self.tick.summary(idx["imu"]),
        }
        out["gps"]["hold_rmse_m"] = self.tick.summary(idx["gps_hold"])["rmse_m"]
        out["kalman"]["velocity_rmse_m_s"] = self.tick.summary(idx["velocity"])["rmse_m"]
        out["kalman"]["tilt_error_rad"] = self.tilt_sum / self.tilt_count if self.tilt_count else None
        # expected 3 (position of three axes) for a consistent filter
        out["kalman"]["position_nees"] = self.nees_sum / self.nees_count if self.nees_count else None
        k, g = out["kalman"]["rmse_m"], out["gps"]["rmse_m"]
        out["kalman_to_gps_rmse"] = (k / g) if (k is not None and g) else None
        if extra:
            out.update(extra)
        return out
