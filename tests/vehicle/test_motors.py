"""Motor lag, saturation and the hover rotor speed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import physics_scenario

from pybullet_swarm.vehicle import load_vehicle
from pybullet_swarm.vehicle.dynamics import motor_alpha, motor_update


@pytest.mark.parametrize("vehicle", ["quad150", "cf2x"])
def test_motor_step_reaches_63_percent_at_time_constant(make_sim, vehicle):
    params = load_vehicle(vehicle)
    sim = make_sim(physics_scenario(start_z=50.0, vehicle=vehicle))
    w0, w1 = 0.3 * params.max_rotor_speed, 0.7 * params.max_rotor_speed
    sim.set_open_loop(np.full((1, 4), w0), motor_state=True)
    sim.set_open_loop(np.full((1, 4), w1))
    times, speeds = [0.0], [w0]
    for _ in range(int(4 * params.motor_time_constant * sim.physics_hz) + 2):
        sim.step(1)
        times.append(sim.time)
        speeds.append(sim.controller.rotor_speeds[0, 0])
    frac = (np.array(speeds) - w0) / (w1 - w0)
    t63 = float(np.interp(1.0 - math.exp(-1.0), frac, times))
    assert t63 == pytest.approx(params.motor_time_constant, rel=0.05)
    assert np.all(np.diff(frac) > 0) and frac[-1] < 1.0


@pytest.mark.parametrize("vehicle", ["quad150", "cf2x"])
def test_the_world_applies_kf_w_squared_of_the_lagged_rotor_speed(make_sim, vehicle):
    """The force Bullet applies after a rotor step, measured as the body's acceleration step by step,
    is 4 kf w(t)^2 with w(t) = w1 + (w0 - w1) exp(-t / tau), t the end of each physics step (the
    kernel advances the motors, then applies their new speeds for the step)."""
    params = load_vehicle(vehicle)
    sim = make_sim(physics_scenario(start_z=50.0, vehicle=vehicle))
    g, h, tau = sim.scenario.sim.gravity, 1.0 / sim.physics_hz, params.motor_time_constant
    w0, w1 = 0.3 * params.max_rotor_speed, 0.8 * params.max_rotor_speed
    sim.set_open_loop(np.full((1, 4), w0), motor_state=True)
    sim.set_open_loop(np.full((1, 4), w1))
    n = int(round(5 * tau / h))
    accel = np.empty(n)
    for k in range(n):
        v_before = sim.state.velocities[0, 2]
        sim.step(1)
        accel[k] = (sim.state.velocities[0, 2] - v_before) / h  # m/s^2, measured
    t_end = h * np.arange(1, n + 1)  # s, end of each step
    w = w1 + (w0 - w1) * np.exp(-t_end / tau)  # rad/s
    expected = 4.0 * params.kf * w**2 / params.mass - g
    np.testing.assert_allclose(accel, expected, rtol=0.0, atol=1e-9 * g)
    assert np.abs(sim.state.body_rates).max() < 1e-9  # equal rotors: no torque
    # the rotor speed the force implies closes the gap as exp(-t / tau): the time constant it
    # gives at every step is the vehicle's (63.2 % of the way at t = tau)
    w_seen = np.sqrt((accel + g) * params.mass / (4.0 * params.kf))
    tau_seen = -t_end / np.log((w1 - w_seen) / (w1 - w0))
    np.testing.assert_allclose(tau_seen, tau, rtol=1e-6)
    # teeth: a step late (w at the start of each step) or no lag at all miss by far more
    late = 4.0 * params.kf * (w1 + (w0 - w1) * np.exp(-(t_end - h) / tau)) ** 2 / params.mass - g
    assert np.abs(accel - late).max() > 1e-3 * g
    assert np.abs(accel - (4.0 * params.kf * w1**2 / params.mass - g)).max() > 0.5 * g


def test_motor_saturates_to_range():
    w = np.full((2, 4), 100.0)
    cmd = np.array([[-50.0] * 4, [1e6] * 4])
    for _ in range(2000):
        motor_update(w, cmd, motor_alpha(1 / 240, 0.02), 2000.0)
    assert np.allclose(w[0], 0.0, atol=1e-6)
    assert np.allclose(w[1], 2000.0)


@pytest.mark.parametrize("vehicle", ["quad150", "cf2x"])
def test_open_loop_hover_at_analytic_speed_holds_altitude(make_sim, vehicle):
    sim = make_sim(physics_scenario(start_z=1.0, vehicle=vehicle))
    p = sim.params
    w_hover = math.sqrt(p.mass * sim.scenario.sim.gravity / (4 * p.kf))
    assert w_hover == pytest.approx(p.hover_rotor_speed(sim.scenario.sim.gravity))
    sim.set_open_loop(np.full((1, 4), w_hover), motor_state=True)
    z0 = sim.state.positions[0].copy()
    sim.step(2 * sim.physics_hz)  # 2 s
    drift = np.linalg.norm(sim.state.positions[0] - z0)
    assert drift < 1e-3
    # and 1 % less thrust does sink measurably: the test can fail
    sim2 = make_sim(physics_scenario(start_z=1.0, vehicle=vehicle))
    sim2.set_open_loop(np.full((1, 4), w_hover * math.sqrt(0.99)), motor_state=True)
    sim2.step(2 * sim2.physics_hz)
    assert z0[2] - sim2.state.positions[0, 2] > 0.01


def test_mixer_maps_hover_and_torques():
    p = load_vehicle("quad150")
    w2 = np.full(4, p.hover_rotor_speed() ** 2)
    thrust, tx, ty, tz = p.mixer @ w2
    assert thrust == pytest.approx(p.mass * 9.81)
    assert abs(tx) < 1e-12 and abs(ty) < 1e-12 and abs(tz) < 1e-12
    # speeding up the left rotors (y > 0) rolls the body right-side up: positive tau_x
    left = p.rotor_xy[:, 1] > 0
    _, tx, _, _ = p.mixer @ (w2 * np.where(left, 1.1, 1.0))
    assert tx > 0
    # speeding up the counter-clockwise rotors yaws the body clockwise: negative tau_z
    ccw = p.spin > 0
    _, _, _, tz = p.mixer @ (w2 * np.where(ccw, 1.1, 1.0))
    assert tz < 0
    assert np.allclose(p.mixer @ p.mixer_inverse, np.eye(4))
