"""Inertial measurement unit: accelerometer and gyroscope with white noise and a constant bias.

The IMU is sampled at the control rate. Like a real IMU's integrated outputs (delta velocity
and delta angle over a sample period), each sample is the *mean* over the last period: the
accelerometer reports the mean specific force ``R^T (dv/T + g e_z)`` in the body frame, the
gyroscope the mean body rate that turns the previous attitude into the current one. Both then get
a constant per-agent bias and fresh Gaussian white noise.

Default figures (Crazyflie 2.x class, Bosch BMI088 data sheet, typical values):

* accelerometer noise density 175 ug/sqrt(Hz) (160 x/y, 190 z) = 1.7e-3 m/s^2/sqrt(Hz);
  zero-g offset +-20 mg, taken as a bias standard deviation of 0.2 m/s^2 per axis;
* gyroscope noise density 0.014 deg/s/sqrt(Hz) = 2.4e-4 rad/s/sqrt(Hz); zero-rate offset
  +-1 deg/s, taken as a bias standard deviation of 0.017 rad/s per axis.

A sample averaged over the period ``T`` of white noise with density ``N`` has the standard
deviation ``N / sqrt(2 T)`` = ``N sqrt(rate / 2)``. Motor vibration, which dominates a real
airframe's accelerometer noise, is not simulated (raise the densities to model it).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.sensing.attitude import mean_body_rates, rotation_matrices

#: m/s^2 per g
STANDARD_GRAVITY = 9.80665


@dataclasses.dataclass(frozen=True)
class ImuNoise:
    """Noise model of an IMU (same fields as the scenario's ``sensing.imu``).

    Attributes:
        accel_noise_density: m/s^2/sqrt(Hz), white noise of the accelerometer.
        gyro_noise_density: rad/s/sqrt(Hz), white noise of the gyroscope.
        accel_bias_std: m/s^2, per-axis standard deviation of each agent's constant accelerometer bias.
        gyro_bias_std: rad/s, per-axis standard deviation of each agent's constant gyroscope bias.
        accel_bias: (3,) m/s^2, the same bias for every agent instead of a drawn one (None: drawn).
        gyro_bias: (3,) rad/s, likewise for the gyroscope.
    """

    accel_noise_density: float = 175e-6 * STANDARD_GRAVITY
    gyro_noise_density: float = math.radians(0.014)
    accel_bias_std: float = 0.02 * STANDARD_GRAVITY
    gyro_bias_std: float = math.radians(1.0)
    accel_bias: tuple[float, float, float] | list[float] | None = None
    gyro_bias: tuple[float, float, float] | list[float] | None = None

    def accel_std(self, rate_hz: float) -> float:
        """Standard deviation m/s^2 of one accelerometer sample at ``rate_hz``."""
        return self.accel_noise_density * math.sqrt(0.5 * rate_hz)

    def gyro_std(self, rate_hz: float) -> float:
        """Standard deviation rad/s of one gyroscope sample at ``rate_hz``."""
        return self.gyro_noise_density * math.sqrt(0.5 * rate_hz)


@dataclasses.dataclass(frozen=True)
class ImuSample:
    """One IMU sample of every agent.

    Attributes:
        accel: (n, 3) m/s^2, specific force in the body frame.
        gyro: (n, 3) rad/s, body rates.
    """

    accel: NDArray[np.float64]
    gyro: NDArray[np.float64]


class Imu:
    """The IMUs of ``n`` agents, sampled every ``1 / rate_hz`` s.

    Args:
        n: number of agents.
        noise: the noise model.
        rate_hz: sample rate, Hz.
        gravity: m/s^2.
        rng: the generator of this sensor's biases and noise.
    """

    def __init__(self, n: int, noise: ImuNoise, rate_hz: float, gravity: float, *, rng: np.random.Generator) -> None:
        self.n = n
        self.noise = noise
        self.dt = 1.0 / float(rate_hz)
        self.gravity = float(gravity)
        self.rng = rng
        self.accel_sigma = noise.accel_std(rate_hz)  # m/s^2 per sample
        self.gyro_sigma = noise.gyro_std(rate_hz)  # rad/s per sample
        self.accel_bias = self._bias(noise.accel_bias, noise.accel_bias_std)  # (n, 3) m/s^2
        self.gyro_bias = self._bias(noise.gyro_bias, noise.gyro_bias_std)  # (n, 3) rad/s
        self._gravity_world = np.array([0.0, 0.0, self.gravity])

    def _bias(self, fixed: tuple[float, float, float] | list[float] | None, std: float) -> NDArray[np.float64]:
        drawn = self.rng.normal(0.0, 1.0, size=(self.n, 3)) * std  # always drawn: the stream does not depend on it
        return np.tile(np.asarray(fixed, dtype=float), (self.n, 1)) if fixed is not None else drawn

    def measure(
        self,
        quaternions: NDArray[np.float64],
        mean_acceleration: NDArray[np.float64],
        mean_body_rate: NDArray[np.float64],
    ) -> ImuSample:
        """Sample from true motion over the last period.

        Args:
            quaternions: (n, 4) true attitude now (x, y, z, w).
            mean_acceleration: (n, 3) m/s^2, mean world acceleration over the period.
            mean_body_rate: (n, 3) rad/s, mean body rate over the period.
        """
        R = rotation_matrices(np.asarray(quaternions, dtype=float))
        specific = np.einsum("nji,nj->ni", R, mean_acceleration + self._gravity_world)  # R^T (a + g e_z)
        noise = self.rng.normal(0.0, 1.0, size=(2, self.n, 3))
        accel = specific + self.accel_bias + self.accel_sigma * noise[0]
        gyro = mean_body_rate + self.gyro_bias + self.gyro_sigma * noise[1]
        return ImuSample(accel, gyro)

    def measure_motion(
        self,
        q_prev: NDArray[np.float64],
        q_now: NDArray[np.float64],
        v_prev: NDArray[np.float64],
        v_now: NDArray[np.float64],
    ) -> ImuSample:
        """Sample from the true states at the start and the end of the period.

        Args:
            q_prev, q_now: (n, 4) attitudes one period ago and now.
            v_prev, v_now: (n, 3) m/s world velocities one period ago and now.
        """
        return self.measure(q_now, (v_now - v_prev) / self.dt, mean_body_rates(q_prev, q_now, self.dt))

    def at_rest(self, quaternions: NDArray[np.float64]) -> ImuSample:
        """A sample of agents resting with attitude ``quaternions`` (n, 4)."""
        zero = np.zeros((self.n, 3))
        return self.measure(quaternions, zero, zero)
