"""Start-up calibration at rest: IMU biases and the initial position, before take-off.

As in the course report's fusion controller, the estimator first watches the resting robot:
the mean accelerometer reading minus the specific force of a level body at rest (``g`` along body
z) is the accelerometer bias, the mean gyroscope reading is the gyroscope bias, and the mean of
the positioning fixes (and headings) is the initial pose. The level assumption holds for
agents resting on flat ground; a tilted pad would leak into the accelerometer bias.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.sensing.attitude import wrap_angle


@dataclasses.dataclass(frozen=True)
class CalibrationResult:
    """What the calibration learnt.

    Attributes:
        accel_bias: (n, 3) m/s^2.
        gyro_bias: (n, 3) rad/s.
        position: (n, 3) m, mean of the fixes (NaN rows for agents that got none).
        position_fixes: (n,) number of fixes averaged.
        heading: (n,) rad, circular mean of the fix headings, or None.
        imu_samples: number of IMU samples averaged.
    """

    accel_bias: NDArray[np.float64]
    gyro_bias: NDArray[np.float64]
    position: NDArray[np.float64]
    position_fixes: NDArray[np.int64]
    heading: NDArray[np.float64] | None
    imu_samples: int


class RestCalibration:
    """Accumulates IMU samples and fixes of ``n`` resting agents.

    Args:
        n: number of agents.
        gravity: m/s^2.
    """

    def __init__(self, n: int, gravity: float) -> None:
        self.n = n
        self.gravity = float(gravity)
        self._acc = np.zeros((n, 3))
        self._gyr = np.zeros((n, 3))
        self._k = 0
        self._pos = np.zeros((n, 3))
        self._npos = np.zeros(n, dtype=np.int64)
        self._head = np.zeros((n, 2))  # sum of (cos, sin)
        self._has_heading = False

    def add_imu(self, accel: NDArray[np.float64], gyro: NDArray[np.float64]) -> None:
        """Add one IMU sample: specific force (n, 3) m/s^2 and rates (n, 3) rad/s."""
        self._acc += accel
        self._gyr += gyro
        self._k += 1

    def add_fix(
        self, valid: NDArray[np.bool_], positions: NDArray[np.float64], headings: NDArray[np.float64] | None
    ) -> None:
        """Add the fixes (n, 3) m (and headings (n,) rad) of the agents marked ``valid`` (n,)."""
        self._pos[valid] += positions[valid]
        self._npos += valid
        if headings is not None:
            self._has_heading = True
            self._head[valid, 0] += np.cos(headings[valid])
            self._head[valid, 1] += np.sin(headings[valid])

    def result(self) -> CalibrationResult:
        """Biases and initial pose from what was added (zero biases without IMU samples)."""
        k = max(self._k, 1)
        acc = self._acc / k
        accel_bias = acc - np.array([0.0, 0.0, self.gravity]) if self._k else np.zeros((self.n, 3))
        gyro_bias = self._gyr / k
        with np.errstate(invalid="ignore", divide="ignore"):
            pos = self._pos / self._npos[:, None]
        heading = None
        if self._has_heading:
            heading = wrap_angle(np.arctan2(self._head[:, 1], self._head[:, 0]))
            heading[self._npos == 0] = np.nan
        return CalibrationResult(accel_bias, gyro_bias, pos, self._npos.copy(), heading, self._k)
