"""Estimation error metrics: closed forms of RMSE, mean error, heading error, NEES."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pybullet_swarm.metrics.estimation import ErrorAccumulator, EstimationErrors, nees, nees_bounds, wrapped_abs


def test_accumulator_closed_forms():
    acc = ErrorAccumulator()
    truth = np.zeros((2, 3))
    acc.add(np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 0.0]]), truth, np.array([0.1, -0.1]), np.array([0.0, 0.0]))
    acc.add(
        np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]),
        truth,
        np.array([math.pi - 0.05, 0.0]),
        np.array([-math.pi + 0.05, 0.0]),
    )
    s = acc.summary()
    assert s["samples"] == 4
    assert s["rmse_m"] == pytest.approx(math.sqrt((25.0 + 1.0) / 4))
    assert s["mean_error_m"] == pytest.approx((5.0 + 1.0) / 4)
    assert s["rmse_axis_m"] == pytest.approx([math.sqrt(9 / 4), math.sqrt(16 / 4), math.sqrt(1 / 4)])
    assert s["max_error_m"] == pytest.approx(5.0)
    assert s["heading_error_rad"] == pytest.approx((0.1 + 0.1 + 0.1 + 0.0) / 4)  # wrapped across +-pi
    assert ErrorAccumulator().summary()["rmse_m"] is None


def test_wrapped_abs_and_nees():
    assert wrapped_abs(np.array([3.1]), np.array([-3.1]))[0] == pytest.approx(2 * math.pi - 6.2)
    P = np.array([[[4.0, 0.0], [0.0, 0.25]]])
    assert nees(np.array([[2.0, 0.5]]), P)[0] == pytest.approx(2.0)
    lo, hi = nees_bounds(2, 50)
    assert lo < 2.0 < hi and hi - lo < 1.2


def test_estimation_errors_report_the_three_sources():
    e = EstimationErrors()
    n = 2
    truth = np.zeros((n, 3))
    yaw = np.zeros(n)
    e.add_fix(np.array([True, False]), np.array([[0.01, 0.0, 0.0], [9.0, 9.0, 9.0]]), np.array([0.02, 5.0]), truth, yaw)
    e.add_tick(
        kalman=np.full((n, 3), 0.001),
        kalman_yaw=yaw,
        velocity=np.zeros((n, 3)),
        tilt_error=np.zeros(n),
        position_variance=np.full((n, 3), 1e-6),
        imu=np.full((n, 3), 1.0),
        imu_yaw=yaw + 0.1,
        held_fix=np.full((n, 3), 0.01),
        true_positions=truth,
        true_velocities=np.zeros((n, 3)),
        true_yaw=yaw,
    )
    m = e.metrics({"state": "estimated"})
    for source in ("kalman", "gps", "imu"):
        assert {"rmse_m", "mean_error_m", "heading_error_rad"} <= set(m[source])
    assert m["gps"]["rmse_m"] == pytest.approx(0.01)  # the dropped fix is not scored
    assert m["gps"]["heading_error_rad"] == pytest.approx(0.02)
    assert m["kalman"]["rmse_m"] == pytest.approx(math.sqrt(3) * 0.001)
    assert m["kalman"]["position_nees"] == pytest.approx(3.0)
    assert m["imu"]["heading_error_rad"] == pytest.approx(0.1)
    assert m["kalman_to_gps_rmse"] == pytest.approx(math.sqrt(3) * 0.1)
    assert m["state"] == "estimated"
