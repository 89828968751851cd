"""The batched position/velocity Kalman filter on synthetic constant-acceleration data."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.metrics.estimation import nees, nees_bounds
from pybullet_swarm.sensing.kalman import AxisKalman

T = 1.0 / 48.0  # s, prediction period
FIX_EVERY = 5  # predictions per position fix


def _simulate(
    rng: np.random.Generator,
    runs: int,
    steps: int,
    *,
    sigma_a: float,
    sigma_p: float,
    bias: bool = False,
    sigma_b: float = 0.0,
):
    """Monte Carlo of ``runs`` independent 1-D filters tracking constant accelerations.

    Returns the NEES (steps, runs) after each step and the final errors (runs, d).
    """
    d = 3 if bias else 2
    P0 = np.diag([0.02**2, 0.05**2, sigma_b**2][:d])
    x_hat = np.zeros((runs, d))
    truth = rng.multivariate_normal(np.zeros(d), P0, size=runs)  # the prior is the truth's distribution
    accel = rng.uniform(-1.0, 1.0, size=runs)  # m/s^2, constant per run
    kf = AxisKalman(x_hat, P0, T, sigma_a, 0.0)
    rows = np.arange(runs)
    out = np.empty((steps, runs))
    for k in range(steps):
        b = truth[:, 2] if bias else 0.0
        u = accel + b + sigma_a * rng.normal(size=runs)  # measured acceleration
        truth[:, 0] += T * truth[:, 1] + 0.5 * T * T * accel
        truth[:, 1] += T * accel
        kf.predict(u)
        if (k + 1) % FIX_EVERY == 0:
            kf.update(rows, truth[:, 0] + sigma_p * rng.normal(size=runs), sigma_p**2)
        out[k] = nees(kf.x - truth, kf.P)
    return out, kf.x - truth


@pytest.mark.parametrize("bias", [False, True])
def test_filter_is_consistent_on_constant_acceleration(bias):
    rng = np.random.default_rng(7)
    runs, steps = 400, 300
    d = 3 if bias else 2
    eps, err = _simulate(rng, runs, steps, sigma_a=0.05, sigma_p=0.01, bias=bias, sigma_b=0.1)
    mean = eps.mean(axis=1)  # average NEES over the runs, per step
    lo, hi = nees_bounds(d, runs, 0.95)
    inside = np.mean((mean >= lo) & (mean <= hi))
    assert inside >= 0.88, f"only {inside:.2%} of the steps inside [{lo:.2f}, {hi:.2f}]"
    assert abs(mean.mean() - d) < 0.1 * d
    # and the filter actually learnt something: the position error is well below a fix's noise
    assert np.sqrt(np.mean(err[:, 0] ** 2)) < 0.6 * 0.01


def test_overconfident_filter_fails_the_chi_square_test():
    # the same data, but the filter believes the accelerometer 10x better than it is
    rng = np.random.default_rng(3)
    runs = 400
    P0 = np.diag([0.02**2, 0.05**2])
    truth = rng.multivariate_normal(np.zeros(2), P0, size=runs)
    kf = AxisKalman(np.zeros((runs, 2)), P0, T, 0.005)
    rows = np.arange(runs)
    for k in range(300):
        u = 0.05 * rng.normal(size=runs)
        kf.predict(u)
        if (k + 1) % FIX_EVERY == 0:
            kf.update(rows, truth[:, 0] + 0.01 * rng.normal(size=runs), 0.01**2)
    lo, hi = nees_bounds(2, runs)
    assert nees(kf.x - truth, kf.P).mean() > hi


def test_zero_noise_estimate_equals_truth():
    runs = 6
    x0 = np.column_stack([np.linspace(-1, 1, runs), np.linspace(0.2, -0.3, runs), np.zeros(runs)])
    kf = AxisKalman(x0, np.diag([1e-4, 1e-4, 1e-4]), T, 0.05, 0.01)
    truth = x0.copy()
    accel = np.linspace(-2.0, 2.0, runs)
    rows = np.arange(runs)
    for k in range(500):
        truth[:, 0] += T * truth[:, 1] + 0.5 * T * T * accel
        truth[:, 1] += T * accel
        kf.predict(accel)
        if k % 7 == 0:
            kf.update(rows, truth[:, 0], 1e-4)
    np.testing.assert_allclose(kf.x, truth, rtol=0, atol=1e-12)


def test_lagged_fix_measures_the_past_position():
    # a fix taken `lag` s ago at p - lag v equals the present state exactly: no correction
    x0 = np.array([[1.0, 0.4]])
    kf = AxisKalman(x0, np.diag([0.01, 0.01]), T, 0.05)
    kf.update(np.array([0]), np.array([1.0 - 0.0125 * 0.4]), 1e-4, lag=0.0125)
    np.testing.assert_allclose(kf.x, x0, atol=1e-15)
    assert kf.P[0, 0, 0] < 0.01  # but the uncertainty shrank


def test_prediction_follows_closed_form_and_covariance_grows():
    kf = AxisKalman(np.array([[0.0, 1.0]]), np.zeros((2, 2)), 0.1, 0.2)
    kf.predict(np.array([2.0]))
    np.testing.assert_allclose(kf.x, [[0.1 + 0.5 * 2.0 * 0.01, 1.2]])
    G = np.array([0.005, 0.1])
    np.testing.assert_allclose(kf.P[0], 0.04 * np.outer(G, G))
    with pytest.raises(ValueError):
        AxisKalman(np.zeros((1, 4)), np.eye(4), 0.1, 0.1)


def test_steady_position_std_matches_the_error_the_filter_settles_to():
    from pybullet_swarm.sensing.kalman import steady_position_std

    sigma_a, sigma_p, runs = 0.03, 0.01, 2000
    expected = steady_position_std(T, sigma_a, FIX_EVERY, sigma_p, bias=False)
    rng = np.random.default_rng(11)
    truth = np.zeros((runs, 2))
    kf = AxisKalman(np.zeros((runs, 2)), np.diag([0.02**2, 0.05**2]), T, sigma_a, 0.0)
    rows = np.arange(runs)
    before = []
    for k in range(400):
        w = sigma_a * rng.normal(size=runs)  # the input error the filter is told about
        truth[:, 0] += T * truth[:, 1] + 0.5 * T * T * w
        truth[:, 1] += T * w
        kf.predict(np.zeros(runs))
        if (k + 1) % FIX_EVERY == 0:
            if k > 200:
                before.append(kf.x[:, 0] - truth[:, 0])  # just before a fix: the largest of the cycle
            kf.update(rows, truth[:, 0] + sigma_p * rng.normal(size=runs), sigma_p**2)
    rms = float(np.sqrt(np.mean(np.square(before))))
    assert rms == pytest.approx(expected, rel=0.08)
    assert 0.2 * sigma_p < expected < sigma_p  # the filter averages fixes, it does not invent accuracy
    # more accurate fixes, more accurate estimate
    assert steady_position_std(T, sigma_a, FIX_EVERY, 0.003, bias=False) < 0.5 * expected
