"""Onboard state estimation of every agent: sensors, attitude filter, Kalman filter, baselines.

One ``OnboardEstimation`` serves the whole swarm with numpy arrays of shape (n, ...):

* before take-off (``start``) a calibration phase of ``calibration_s`` seconds at rest yields
  the IMU biases and the initial position (the agents rest on the pad, so the phase is sampled
  from the resting state without advancing the simulation clock: runs on estimated state keep
  the same timeline as runs on true state);
* at every positioning instant (``take_fix``) the positioning sensor takes its fixes;
* at every control tick (``control_tick``) the IMU is sampled over the last period, the
  complementary filter propagates the attitude (and takes the heading of a new fix), the
  accelerometer is rotated into the world frame and drives the Kalman prediction, a new fix
  updates it, and the two baselines advance: IMU dead reckoning (the same IMU, its own
  gyroscope-and-accelerometer attitude, no fixes) and positioning alone (the last fix held).

``state_array`` (n, 13) holds the estimate in the simulation's state layout (position,
quaternion, velocity, world angular velocity), ready for the position loop and the planners.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.control.rotations import euler_to_quat, quat_to_euler
from pybullet_swarm.sensing.attitude import AttitudeGains, ComplementaryFilter, cross_rows, rotation_matrices, yaw_of
from pybullet_swarm.sensing.calibration import CalibrationResult, RestCalibration
from pybullet_swarm.sensing.imu import Imu, ImuNoise
from pybullet_swarm.sensing.kalman import AxisKalman
from pybullet_swarm.sensing.positioning import Fix, PositioningParams, PositioningSensor


@dataclasses.dataclass(frozen=True)
class EstimatorParams:
    """Estimator settings (same fields as the scenario's ``sensing.estimator``).

    Attributes:
        calibration_s: s at rest before take-off for the bias calibration and the initial fix average
            (0: no calibration, biases taken as zero, the first fix starts the filter).
        tilt_gain: 1/s, accelerometer correction of the attitude filter's roll and pitch.
        heading_gain: fraction of the heading error removed at each fix that carries a heading.
        accel_process_std: m/s^2, standard deviation of the world acceleration input error per IMU
            sample (accelerometer noise plus the fast part of the gravity leaked by attitude errors;
            the slow part is the bias state's).
        estimate_bias: add a world-frame acceleration bias to the Kalman state (absorbs the residual
            accelerometer bias and slow attitude errors).
        bias_walk: m/s^2/sqrt(s), random-walk density of that bias.
        initial_bias_std: m/s^2, initial standard deviation of that bias.
        initial_velocity_std: m/s, initial velocity standard deviation (the agents start at rest).
    """

    calibration_s: float = 2.0
    tilt_gain: float = 0.5
    heading_gain: float = 0.3
    accel_process_std: float = 0.03
    estimate_bias: bool = True
    bias_walk: float = 0.003
    initial_bias_std: float = 0.05
    initial_velocity_std: float = 0.01


class OnboardEstimation:
    """Sensors and estimators of ``n`` agents.

    Args:
        n: number of agents.
        imu: IMU noise model.
        positioning: positioning sensor settings.
        params: estimator settings.
        control_hz: IMU and estimator rate, Hz.
        gravity: m/s^2.
        rng: parent generator; the IMU, the positioning sensor and neighbour sensing get a child each.
    """

    def __init__(
        self,
        n: int,
        imu: ImuNoise,
        positioning: PositioningParams,
        params: EstimatorParams,
        *,
        control_hz: float,
        gravity: float,
        rng: np.random.Generator,
    ) -> None:
        self.n = n
        self.params = params
        self.dt = 1.0 / float(control_hz)
        self.control_hz = float(control_hz)
        self.gravity = float(gravity)
        imu_rng, pos_rng, self.neighbour_rng = rng.spawn(3)
        self.imu = Imu(n, imu, control_hz, gravity, rng=imu_rng)
        self.positioning = PositioningSensor(n, positioning, rng=pos_rng)
        self.state_array = np.zeros((n, 13))  # estimate: position, quaternion, velocity, world angular velocity
        self.state_array[:, 6] = 1.0
        self.calibration: CalibrationResult | None = None
        self._pending: Fix | None = None
        self.time = 0.0

    # ----------------------------------------------------------------- start
    def start(self, state: NDArray[np.float64], t: float = 0.0) -> CalibrationResult:
        """Calibrate at rest from the true resting state (n, 13) and start the filters at time ``t`` s."""
        p, n = self.params, self.n
        q_rest = state[:, 3:7].copy()
        cal = RestCalibration(n, self.gravity)
        n_imu = int(round(p.calibration_s * self.control_hz))
        for _ in range(n_imu):
            s = self.imu.at_rest(q_rest)
            cal.add_imu(s.accel, s.gyro)
        rate = self.positioning.params.rate_hz
        n_fix = max(1, int(round(p.calibration_s * rate)))
        for j in range(n_fix):  # the fixes of the calibration phase, dropouts included
            tj = t - (n_fix - 1 - j) / rate
            fix = self.positioning.measure(tj, state[:, :3], q_rest)
            cal.add_fix(fix.valid, fix.positions, fix.headings)
        result = cal.result()
        missing = result.position_fixes == 0
        if np.any(missing):  # no fix at all: start from one noisy fix regardless of dropouts and outages
            extra = self.positioning.measure(t, state[:, :3], q_rest)
            result.position[missing] = extra.positions[missing]
            result.position_fixes[missing] = 1
            if result.heading is not None and extra.headings is not None:
                result.heading[missing] = extra.headings[missing]
        self.calibration = result
        self.positioning.fixes = self.positioning.dropped = 0  # count the fixes of the flight only
        self._init_filters(state, result, t)
        return result

    def _init_filters(self, state: NDArray[np.float64], cal: CalibrationResult, t: float) -> None:
        p, n = self.params, self.n
        # level at rest (the calibration's assumption); heading from the fixes, else the known placement
        yaw = yaw_of(state[:, 3:7])
        if cal.heading is not None:
            yaw = np.where(np.isfinite(cal.heading), cal.heading, yaw)
        q0 = euler_to_quat(np.column_stack([np.zeros(n), np.zeros(n), yaw]))
        gains = AttitudeGains(tilt=p.tilt_gain, heading=p.heading_gain)
        self.attitude = ComplementaryFilter(q0, gains, self.gravity)
        self.dr_attitude = ComplementaryFilter(q0, AttitudeGains(tilt=p.tilt_gain, heading=0.0), self.gravity)
        d = 3 if p.estimate_bias else 2
        x0 = np.zeros((n * 3, d))
        x0[:, 0] = cal.position.reshape(-1)
        P0 = np.zeros((n * 3, d, d))
        P0[:, 0, 0] = np.repeat(self.positioning.params.noise_std**2 / cal.position_fixes, 3)
        P0[:, 1, 1] = p.initial_velocity_std**2
        if d == 3:
            P0[:, 2, 2] = p.initial_bias_std**2
        self.kalman = AxisKalman(x0, P0, self.dt, p.accel_process_std, p.bias_walk)
        self.dr_position = cal.position.copy()  # (n, 3) m, IMU dead reckoning
        self.dr_velocity = np.zeros((n, 3))  # (n, 3) m/s
        self.fix_position = cal.position.copy()  # (n, 3) m, positioning alone: the last fix
        self.fix_heading = None if cal.heading is None else np.where(np.isfinite(cal.heading), cal.heading, yaw)
        self.fix_time = np.full(n, t)  # (n,) s, when that fix was taken
        self._q_prev = state[:, 3:7].copy()
        self._v_prev = state[:, 7:10].copy()
        self.time = t
        self._fill(np.zeros((n, 3)))

    # ----------------------------------------------------------------- ticks
    def take_fix(self, t: float, state: NDArray[np.float64]) -> Fix:
        """Take the positioning fixes of time ``t`` s from the true state (n, 13); fused at the next control tick."""
        fix = self.positioning.measure(t, state[:, :3], state[:, 3:7])
        v = fix.valid
        self.fix_position[v] = fix.positions[v]
        self.fix_time[v] = t
        if fix.headings is not None and self.fix_heading is not None:
            self.fix_heading[v] = fix.headings[v]
        self._pending = fix
        return fix

    def control_tick(self, t: float, state: NDArray[np.float64]) -> None:
        """Sample the IMU over the last period, propagate every estimator to time ``t`` s, fuse a new fix."""
        if t > self.time + 1e-12:
            q_now, v_now = state[:, 3:7], state[:, 7:10]
            sample = self.imu.measure_motion(self._q_prev, q_now, self._v_prev, v_now)
            self._q_prev = q_now.copy()
            self._v_prev = v_now.copy()
            cal = self.calibration
            assert cal is not None
            accel = sample.accel - cal.accel_bias
            gyro = sample.gyro - cal.gyro_bias
            self._predict(accel, gyro)
            self.time = t
        else:
            gyro = np.zeros((self.n, 3))
        fix = self._pending
        if fix is not None:
            self._pending = None
            rows = np.nonzero(fix.valid)[0]
            if rows.size:
                axis_rows = (rows[:, None] * 3 + np.arange(3)).reshape(-1)
                var = self.positioning.params.noise_std**2
                self.kalman.update(axis_rows, fix.positions[rows].reshape(-1), var, lag=max(t - fix.time_s, 0.0))
                if fix.headings is not None and self.params.heading_gain > 0.0:
                    self.attitude.correct_heading(fix.headings[rows], rows)
        self._fill(gyro)

    def _predict(self, accel: NDArray[np.float64], gyro: NDArray[np.float64]) -> None:
        dt, g = self.dt, np.array([0.0, 0.0, self.gravity])
        if self.kalman.d == 3:
            self.attitude.update(gyro, accel, dt, tilt=False)
            self._level_from_bias(accel)
        else:
            self.attitude.update(gyro, accel, dt)
        a_world = np.einsum("nij,nj->ni", self.attitude.rotation, accel) - g
        self.kalman.predict(a_world.reshape(-1))
        self.dr_attitude.update(gyro, accel, dt)
        a_dr = np.einsum("nij,nj->ni", self.dr_attitude.rotation, accel) - g
        self.dr_position += dt * self.dr_velocity + 0.5 * dt * dt * a_dr
        self.dr_velocity += dt * a_dr

    def _level_from_bias(self, accel: NDArray[np.float64]) -> None:
        """Accelerometer correction of the tilt against the expected specific force.

        A world-frame tilt error ``phi`` of the attitude estimate makes the rotated accelerometer
        ``F = R f`` (m/s^2) wrong by ``phi x F``, which the Kalman filter learns from the fixes as
        its acceleration bias ``b``. So the part of ``b`` across ``F`` is read as the tilt error
        ``phi = F x b / |F|^2`` and moved, at the rate ``tilt_gain``, from the bias into the
        attitude (``R <- Exp(-k dt phi) R``, ``b <- b - k dt b_perp``). Unlike a correction
        towards gravity this stays right in sustained accelerations, where a quadrotor's specific
        force tilts with the airframe.
        """
        F = np.einsum("nij,nj->ni", self.attitude.rotation, accel)  # (n, 3) m/s^2
        b = self.kalman.x[:, 2].reshape(self.n, 3)  # (n, 3) m/s^2
        f2 = np.maximum(np.einsum("ni,ni->n", F, F), 1e-6)[:, None]
        phi = cross_rows(F, np.ascontiguousarray(b)) / f2  # (n, 3) rad
        step = min(self.params.tilt_gain * self.dt, 1.0)
        self.attitude.rotate_world(-step * phi)
        b_perp = b - F * (np.einsum("ni,ni->n", F, b)[:, None] / f2)
        self.kalman.x[:, 2] = (b - step * b_perp).reshape(-1)

    def _fill(self, gyro: NDArray[np.float64]) -> None:
        x = self.kalman.x
        s = self.state_array
        s[:, :3] = x[:, 0].reshape(self.n, 3)
        s[:, 3:7] = self.attitude.q
        s[:, 7:10] = x[:, 1].reshape(self.n, 3)
        s[:, 10:13] = np.einsum("nij,nj->ni", self.attitude.rotation, gyro)

    # ---------------------------------------------------------------- access
    @property
    def positions(self) -> NDArray[np.float64]:
        """Kalman position estimates (n, 3) m (a view)."""
        return self.state_array[:, :3]

    @property
    def yaw(self) -> NDArray[np.float64]:
        """Estimated headings (n,) rad."""
        return yaw_of(self.attitude.q)

    @property
    def dr_yaw(self) -> NDArray[np.float64]:
        """Dead-reckoning headings (n,) rad."""
        return yaw_of(self.dr_attitude.q)

    @property
    def variances(self) -> NDArray[np.float64]:
        """Kalman variances (n, 3, d): per axis x, y, z the variance of p m^2, v (m/s)^2 (and b (m/s^2)^2)."""
        return self.kalman.variances.reshape(self.n, 3, self.kalman.d)

    def channels(self) -> dict[str, NDArray[np.float64]]:
        """Arrays to record with the time series, by channel name (``est_*``)."""
        out = {
            "est_kalman_position": self.state_array[:, :3],
            "est_kalman_velocity": self.state_array[:, 7:10],
            "est_kalman_rpy": quat_to_euler(self.attitude.q),
            "est_kalman_variance": self.variances,
            "est_gps_position": self.fix_position,
            "est_gps_time": self.fix_time,
            "est_imu_position": self.dr_position,
            "est_imu_rpy": quat_to_euler(self.dr_attitude.q),
        }
        if self.fix_heading is not None:
            out["est_gps_yaw"] = self.fix_heading
        return out

    def score_fix(self, errors: Any, fix: Fix, state: NDArray[np.float64]) -> None:
        """Hand a fix and the true state (n, 13) to an error accumulator (``metrics.estimation.EstimationErrors``)."""
        errors.add_fix(fix.valid, fix.positions, fix.headings, state[:, :3], yaw_of(state[:, 3:7]))

    def score_tick(self, errors: Any, state: NDArray[np.float64]) -> None:
        """Hand this tick's estimates and the true state (n, 13) to an error accumulator."""
        R_est = self.attitude.rotation
        R_true = rotation_matrices(state[:, 3:7])
        cos_tilt = np.clip(np.einsum("ni,ni->n", R_est[:, :, 2], R_true[:, :, 2]), -1.0, 1.0)
        errors.add_tick(
            kalman=self.state_array[:, :3],
            kalman_yaw=self.yaw,
            velocity=self.state_array[:, 7:10],
            tilt_error=np.arccos(cos_tilt),
            position_variance=self.variances[:, :, 0],
            imu=self.dr_position,
            imu_yaw=self.dr_yaw,
            held_fix=self.fix_position,
            true_positions=state[:, :3],
            true_velocities=state[:, 7:10],
            true_yaw=yaw_of(state[:, 3:7]),
        )

    def summary(self) -> dict[str, Any]:
        """Settings and counters of the run's sensing (merged into the ``estimation`` metrics)."""
        cal = self.calibration
        out: dict[str, Any] = {
            "positioning_noise_std_m": float(self.positioning.params.noise_std),
            "positioning_rate_hz": int(self.positioning.params.rate_hz),
            "fixes": int(self.positioning.fixes),
            "fixes_dropped": int(self.positioning.dropped),
        }
        if cal is not None:
            acc_err = np.linalg.norm(cal.accel_bias - self.imu.accel_bias, axis=1)
            gyr_err = np.linalg.norm(cal.gyro_bias - self.imu.gyro_bias, axis=1)
            out["calibration"] = {
                "imu_samples": int(cal.imu_samples),
                "accel_bias_error_m_s2": float(acc_err.mean()),
                "accel_bias_m_s2": float(np.linalg.norm(self.imu.accel_bias, axis=1).mean()),
                "gyro_bias_error_rad_s": float(gyr_err.mean()),
                "gyro_bias_rad_s": float(np.linalg.norm(self.imu.gyro_bias, axis=1).mean()),
            }
        return out

    def neighbour_noise(self, count: int) -> NDArray[np.float64]:
        """Noise (count, 3) m to add to ``count`` sensed neighbour positions (the positioning noise)."""
        return self.positioning.neighbour_noise(self.neighbour_rng, count)


def expected_position_std(positioning: PositioningParams, params: EstimatorParams, *, control_hz: float) -> float:
    """Per-axis standard deviation, m, of a hovering agent's Kalman position estimate once the filter
    has settled (the largest over a fix cycle): what an agent can expect of its own position, e.g.
    to size its clearances. 0 for exact fixes."""
    from pybullet_swarm.sensing.kalman import steady_position_std

    if positioning.noise_std <= 0.0:
        return 0.0
    return steady_position_std(
        1.0 / float(control_hz),
        params.accel_process_std,
        max(1, round(float(control_hz) / positioning.rate_hz)),
        positioning.noise_std,
        bias_walk=params.bias_walk,
        bias=params.estimate_bias,
    )
