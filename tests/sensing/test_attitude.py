"""Quaternion helpers, the complementary attitude filter, the IMU model and the rest calibration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pybullet_swarm.control.rotations import euler_to_quat, quat_to_euler, quat_to_matrix
from pybullet_swarm.sensing.attitude import (
    AttitudeGains,
    ComplementaryFilter,
    mean_body_rates,
    quat_exp,
    quat_log,
    quat_multiply,
    rotation_matrices,
    wrap_angle,
    yaw_of,
)
from pybullet_swarm.sensing.calibration import RestCalibration
from pybullet_swarm.sensing.imu import Imu, ImuNoise
from pybullet_swarm.sensing.positioning import PositioningParams, PositioningSensor

G = 9.81


def _quats(n=8, seed=0):
    return euler_to_quat(np.random.default_rng(seed).uniform(-1.2, 1.2, size=(n, 3)))


def test_quaternion_helpers_match_rotation_matrices():
    q, r = _quats(), _quats(seed=1)
    np.testing.assert_allclose(rotation_matrices(q), quat_to_matrix(q), atol=1e-14)
    np.testing.assert_allclose(quat_to_matrix(quat_multiply(q, r)), quat_to_matrix(q) @ quat_to_matrix(r), atol=1e-12)
    v = np.array([[0.3, -0.2, 0.1], [0.0, 0.0, 0.0], [1e-9, 0.0, 0.0], [0.0, 3.0, 0.0]])
    np.testing.assert_allclose(quat_log(quat_exp(v)), v, atol=1e-12)
    # Exp of a rotation vector about z by a is the yaw a
    assert yaw_of(quat_exp(np.array([[0.0, 0.0, 0.7]])))[0] == pytest.approx(0.7)
    assert wrap_angle(3 * math.pi) == pytest.approx(-math.pi)


def test_mean_body_rates_recover_a_constant_rotation():
    q0 = _quats(4)
    w = np.array([[0.5, -0.2, 1.0], [0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.1, 0.1, -0.3]])
    q1 = quat_multiply(q0, quat_exp(w * 0.02))
    np.testing.assert_allclose(mean_body_rates(q0, q1, 0.02), w, atol=1e-9)


def test_gyro_integration_without_noise_tracks_the_truth_exactly():
    q_true = _quats(3)
    f = ComplementaryFilter(q_true, AttitudeGains(tilt=0.0, heading=0.0), G)
    w = np.array([[0.3, 0.1, -0.5], [0.0, 0.4, 0.0], [-1.0, 0.2, 0.3]])
    for _ in range(480):
        q_true = quat_multiply(q_true, quat_exp(w / 48.0))
        f.update(w, np.zeros((3, 3)), 1.0 / 48.0)
    np.testing.assert_allclose(np.abs(np.sum(f.q * q_true, axis=1)), 1.0, atol=1e-10)


def test_accelerometer_levels_a_tilted_estimate_and_fixes_pull_the_heading():
    wrong = euler_to_quat(np.array([[0.2, -0.15, 0.5], [-0.3, 0.1, -2.0]]))
    f = ComplementaryFilter(wrong, AttitudeGains(tilt=1.0, heading=0.5), G)
    level_at_rest = np.tile([0.0, 0.0, G], (2, 1))  # the truth is level and at rest
    for _ in range(48 * 8):
        f.update(np.zeros((2, 3)), level_at_rest, 1.0 / 48.0)
    rpy = quat_to_euler(f.q)
    np.testing.assert_allclose(rpy[:, :2], 0.0, atol=1e-3)  # 8 time constants: e^-8 of the error
    np.testing.assert_allclose(rpy[:, 2], [0.5, -2.0], atol=0.02)  # yaw untouched by the accelerometer
    for _ in range(30):
        f.correct_heading(np.array([0.0, 3.0]))
    np.testing.assert_allclose(wrap_angle(yaw_of(f.q) - np.array([0.0, 3.0])), 0.0, atol=1e-6)


def test_imu_reads_gravity_at_rest_and_specific_force_in_flight():
    imu = Imu(2, ImuNoise(0.0, 0.0, 0.0, 0.0), 48.0, G, rng=np.random.default_rng(0))
    q = euler_to_quat(np.array([[0.0, 0.0, 1.0], [0.3, 0.0, 0.0]]))
    s = imu.at_rest(q)
    np.testing.assert_allclose(s.accel, np.einsum("nji,j->ni", quat_to_matrix(q), [0.0, 0.0, G]), atol=1e-12)
    np.testing.assert_allclose(s.gyro, 0.0, atol=1e-15)
    # free fall: the accelerometer reads nothing
    s = imu.measure(q, np.tile([0.0, 0.0, -G], (2, 1)), np.zeros((2, 3)))
    np.testing.assert_allclose(s.accel, 0.0, atol=1e-12)


def test_imu_noise_and_bias_statistics():
    noise = ImuNoise(
        accel_noise_density=0.01, gyro_noise_density=0.001, accel_bias=[0.1, -0.2, 0.3], gyro_bias=[0.01, 0.0, -0.02]
    )
    imu = Imu(400, noise, 50.0, G, rng=np.random.default_rng(1))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (400, 1))
    acc = np.stack([imu.at_rest(q).accel for _ in range(50)])  # (50, 400, 3)
    assert noise.accel_std(50.0) == pytest.approx(0.01 * 5.0)  # density * sqrt(rate / 2)
    assert acc[..., 0].std() == pytest.approx(0.05, rel=0.03)
    np.testing.assert_allclose(acc.mean(axis=(0, 1)), [0.1, -0.2, 0.3 + G], atol=0.003)
    drawn = Imu(2000, ImuNoise(accel_bias_std=0.2), 48.0, G, rng=np.random.default_rng(2))
    assert drawn.accel_bias.std() == pytest.approx(0.2, rel=0.05)


def test_bias_calibration_recovers_an_injected_bias_within_ten_percent():
    bias_a = np.array([0.3, -0.2, 0.5])
    bias_g = np.array([0.02, -0.015, 0.01])
    noise = ImuNoise(accel_noise_density=0.01, gyro_noise_density=5e-4, accel_bias=bias_a, gyro_bias=bias_g)
    n = 5
    imu = Imu(n, noise, 48.0, G, rng=np.random.default_rng(4))
    cal = RestCalibration(n, G)
    level = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    for _ in range(96):  # 2 s at 48 Hz
        s = imu.at_rest(level)
        cal.add_imu(s.accel, s.gyro)
    sensor = PositioningSensor(n, PositioningParams(noise_std=0.01), rng=np.random.default_rng(5))
    truth = np.arange(15.0).reshape(n, 3)
    for _ in range(20):
        fix = sensor.measure(0.0, truth, level)
        cal.add_fix(fix.valid, fix.positions, fix.headings)
    r = cal.result()
    assert np.all(np.abs(r.accel_bias - bias_a) <= 0.1 * np.abs(bias_a))
    assert np.all(np.abs(r.gyro_bias - bias_g) <= 0.1 * np.abs(bias_g))
    assert np.all(np.abs(r.position - truth) < 4 * 0.01 / math.sqrt(20))
    assert r.imu_samples == 96 and np.all(r.position_fixes == 20)


def test_positioning_dropouts_and_outages():
    sensor = PositioningSensor(
        1000, PositioningParams(dropout_probability=0.25, outages=[[1.0, 2.0]]), rng=np.random.default_rng(6)
    )
    p, q = np.zeros((1000, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (1000, 1))
    fix = sensor.measure(0.5, p, q)
    assert fix.valid.mean() == pytest.approx(0.75, abs=0.05)
    assert fix.positions.std() == pytest.approx(0.01, rel=0.1)
    assert not sensor.measure(1.5, p, q).valid.any()
    assert sensor.measure(2.0, p, q).valid.any()
    assert sensor.fixes + sensor.dropped == 3000
