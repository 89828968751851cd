"""The runtime cascade against the python-control design, payload rejection, and limits."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
from conftest import physics_scenario

from pybullet_swarm.control import kernels
from pybullet_swarm.control.cascade import CascadeController
from pybullet_swarm.control.design import ReferenceStep, design_controller
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.control.rotations import quat_to_matrix
from pybullet_swarm.types import ExitStatus
from pybullet_swarm.vehicle import load_vehicle
from pybullet_swarm.world.world import World


def _hovering_sim(make_sim, vehicle="quad150", **extra):
    sim = make_sim(physics_scenario(start_z=1.0, vehicle=vehicle, **{"limits.velocity": None, **extra}))
    w = sim.params.hover_rotor_speed(sim.scenario.sim.gravity)
    sim.controller.rotor_speeds[:] = w
    sim.controller.rotor_commands[:] = w
    start = sim.state.positions.copy()
    sim.set_targets(start)
    sim.step(2 * sim.physics_hz)
    return sim, start


#: Normalised RMS error (RMS of simulated - model over the step) the step tests allow: 0.1 %.
#: The README's claim is 2 %; the sampled-data model is exact up to the small-angle and
#: sin(error) nonlinearities (measured 0.001 % .. 0.04 %), while a continuous-time model with
#: the same gains and motor lag but no sampling misses by 0.3 .. 0.9 % (checked below).
NRMSE_TOL = 1e-3


def _nrmse(y: np.ndarray, model: np.ndarray, amp: float) -> float:
    return float(np.sqrt(np.mean((y - model) ** 2)) / amp)


def _design_step(sys: control.StateSpace, amp: float, n: int) -> np.ndarray:
    """The model's response to a step of ``amp`` at its samples 1..n (the step enters at sample 0)."""
    t = np.arange(n + 1) * sys.dt
    return amp * np.asarray(control.step_response(sys, T=t).outputs).ravel()[1:]


def _continuous_closed_loop(design, loop: str) -> control.TransferFunction:
    """The same gains on the continuous-time plant (motor lag, no sampling, no holds): the model a
    design that ignored the sample-and-hold would predict."""

    def closed(plant, gains):
        kp, kd, ki = gains
        num, den = np.asarray(plant.num[0][0], float), np.asarray(plant.den[0][0], float)
        return control.tf(
            np.polymul(num, [kp, ki]), np.polyadd(np.polymul(den, [1.0, 0.0]), np.polymul(num, [kd, kp, ki]))
        )

    att = control.tf([1.0], [design.motor_time_constant, 1.0, 0.0, 0.0])
    if loop == "x":
        return closed(closed(att, design.gains("pitch")) * control.tf([1.0], [1.0, 0.0, 0.0]), design.gains("x"))
    return closed(att, design.gains(loop))


def _continuous_step(sys: control.TransferFunction, dt: float, amp: float, n: int) -> np.ndarray:
    t = np.arange(n + 1) * dt
    return amp * np.asarray(control.step_response(sys, T=t).outputs).ravel()[1:]


@pytest.mark.parametrize("vehicle", ["quad150", "cf2x"])
@pytest.mark.parametrize("axis", [0, 2])
def test_position_step_response_matches_design_model(make_sim, vehicle, axis):
    sim, start = _hovering_sim(make_sim, vehicle)
    amp = 0.1
    target = start.copy()
    target[0, axis] += amp
    base = sim.state.positions[0, axis]
    sim.set_targets(target)
    n = int(8.0 * sim.scenario.sim.control_hz)
    y = np.empty(n)
    for k in range(n):
        sim.step()  # one control period
        y[k] = sim.state.positions[0, axis] - base
    loop = "xyz"[axis]
    design = sim.controller.design
    err = _nrmse(y, _design_step(design.closed_loop(loop), amp, n), amp)
    print(f"{vehicle} {loop} step: NRMSE {100 * err:.4f} %")  # shown with pytest -s
    assert err < NRMSE_TOL, f"{vehicle} {loop}: normalised RMS error {err:.2e}"
    unsampled = _nrmse(y, _continuous_step(_continuous_closed_loop(design, loop), 1 / design.position_hz, amp, n), amp)
    print(f"{vehicle} {loop} step: NRMSE from a continuous-time model without sampling {100 * unsampled:.3f} %")
    assert unsampled > 2 * NRMSE_TOL  # the tolerance is tight enough to tell the sampling apart


def _roll_step(vehicle: str, amp: float, n: int) -> tuple[np.ndarray, CascadeController]:
    """Roll angle (n,) rad at each physics step after a roll reference step, hovering thrust held.

    The position loop is left out (the desired attitude is set directly); the physics step runs in
    the simulation's order: state read, attitude kernel, wrench applied, Bullet step.
    """
    params = load_vehicle(vehicle)
    g = 9.81
    with World(physics_hz=240.0, gravity=g) as world:
        world.add_agents(params.urdf_path, np.array([[0.0, 0.0, 10.0]]), mass=params.mass, inertia=params.inertia)
        ctrl = CascadeController(params, 1, physics_hz=240.0, control_hz=48.0, gravity=g)
        ctrl.reset(1, rotor_speed=params.hover_rotor_speed(g))
        ctrl.thrust_acc[:] = g
        c, s = math.cos(amp), math.sin(amp)
        ctrl.R_des[0] = [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
        state = np.zeros((1, 13))
        world.read_agent_states(state)
        roll = np.empty(n)
        for k in range(n):
            ctrl.physics_update(state)
            world.apply_agent_wrenches(ctrl.forces, ctrl.torques)
            world.step()
            world.read_agent_states(state)
            r = quat_to_matrix(state[:, 3:7])[0]
            roll[k] = math.atan2(r[2, 1], r[2, 2])
    return roll, ctrl


@pytest.mark.parametrize("vehicle", ["quad150", "cf2x"])
def test_roll_step_response_matches_design_model(vehicle):
    amp, n = 0.1, 240
    roll, ctrl = _roll_step(vehicle, amp, n)
    design = ctrl.design
    err = _nrmse(roll, _design_step(design.closed_loop("roll"), amp, n), amp)
    print(f"{vehicle} roll step: NRMSE {100 * err:.4f} %")
    assert err < NRMSE_TOL, f"{vehicle} roll: normalised RMS error {err:.2e}"
    unsampled = _nrmse(roll, _continuous_step(_continuous_closed_loop(design, "roll"), 1 / 240, amp, n), amp)
    print(f"{vehicle} roll step: NRMSE from a continuous-time model without sampling {100 * unsampled:.3f} %")
    assert unsampled > 2 * NRMSE_TOL


@pytest.mark.parametrize("vehicle", ["quad150", "cf2x"])
def test_yaw_step_response_matches_design_model(make_sim, vehicle):
    sim, start = _hovering_sim(make_sim, vehicle)
    amp, n = 0.1, 240
    assert sim.step_count % sim.control_every == 0  # the step enters with the next position tick
    sim.set_targets(start, yaw=np.array([amp]))
    yaw = np.empty(n)
    for k in range(n):
        sim.step(1)
        r = quat_to_matrix(sim.state.quaternions)[0]
        yaw[k] = math.atan2(r[1, 0], r[0, 0])
    design = sim.controller.design
    err = _nrmse(yaw, _design_step(design.closed_loop("yaw"), amp, n), amp)
    print(f"{vehicle} yaw step: NRMSE {100 * err:.4f} %")
    assert err < NRMSE_TOL, f"{vehicle} yaw: normalised RMS error {err:.2e}"


def test_the_runtime_uses_exactly_the_designed_gains(make_sim):
    sim, _ = _hovering_sim(make_sim, "cf2x")
    ctrl = sim.controller
    design = design_controller(sim.params, physics_hz=sim.physics_hz, position_hz=sim.scenario.sim.control_hz)
    assert ctrl.design is design
    np.testing.assert_array_equal(ctrl.const[kernels.K_GAINS : kernels.K_GAINS + 9], design.attitude_gains.ravel())
    np.testing.assert_array_equal(ctrl.pos_gains, design.position_gains)


def test_a_cascade_for_a_step_its_rotors_cannot_follow_is_refused():
    params = load_vehicle("quad150")
    ok = CascadeController(params, 2, reference_step=ReferenceStep.from_limits([0.5] * 3, [1.0] * 3))
    assert ok.design is design_controller(params)
    with pytest.raises(ConfigError, match=r"quad150.yaml: z: the controller cannot follow"):
        CascadeController(params, 2, reference_step=ReferenceStep.from_limits([0.5] * 3, [1.0, 1.0, 10.0], yaw=0.0))


def test_the_design_predicts_the_rotor_speed_a_yaw_step_asks_for(make_sim):
    """quad150's yaw loop is designed to use the rotor range up to max_rotor_speed for the 0.5 rad
    yaw step; the runtime's largest rotor command for that step (alone) is what the linear model
    predicts, a little less because the attitude error is sin(0.5) rather than 0.5."""
    sim, start = _hovering_sim(make_sim, "quad150")
    step = sim.controller.design.saturation.step.yaw
    predicted = sim.controller.design.saturation.alone["yaw"]
    sim.set_targets(start, yaw=np.array([step]))
    peak = 0.0
    for _ in range(sim.physics_hz):
        sim.step(1)
        peak = max(peak, float(sim.controller.rotor_commands.max()))
    measured = peak / sim.params.max_rotor_speed
    assert measured <= predicted
    assert measured > 0.97 * predicted
    assert measured < 1.0  # below the limit: the mixer did not have to scale yaw down


@pytest.mark.parametrize("vehicle", ["quad150", "cf2x"])
def test_payload_of_20_percent_settles_within_1cm(make_sim, vehicle):
    sim, start = _hovering_sim(make_sim, vehicle)
    body = sim.world.agent_bodies[0]
    sim.world.set_body_mass(body, 1.2 * sim.params.mass)
    sim.step(20 * sim.physics_hz)
    err = np.linalg.norm(sim.state.positions[0] - start[0])
    assert sim.exit_status is ExitStatus.RUNNING
    assert err < 0.01
    # without integral action the steady error would be 0.2 g / kp_z, over twice the 1 cm: the test has teeth
    kp_z = sim.controller.design.position_gains[2, 0]
    assert 0.2 * sim.scenario.sim.gravity / kp_z > 0.02


def test_shaped_references_respect_limits(make_sim):
    sim = make_sim(physics_scenario(start_z=1.0, **{"limits.velocity": [0.15, 0.15, 0.1], "limits.acceleration": 0.5}))
    w = sim.params.hover_rotor_speed()
    sim.controller.rotor_speeds[:] = w
    start = sim.state.positions.copy()
    sim.set_targets(start + [[1.0, -0.5, 0.3]])
    v_seen = np.zeros(3)
    a_seen = np.zeros(3)
    for _ in range(15 * sim.scenario.sim.control_hz):
        sim.step()
        v_seen = np.maximum(v_seen, np.abs(sim.shaper.v[0]))
        a_seen = np.maximum(a_seen, np.abs(sim.shaper.a[0]))
    assert np.all(v_seen <= np.array([0.15, 0.15, 0.1]) + 1e-9)
    assert np.all(a_seen <= 0.5 + 1e-9)
    assert np.allclose(sim.shaper.p[0], start[0] + [1.0, -0.5, 0.3], atol=1e-6)
    assert np.linalg.norm(sim.state.positions[0] - sim.shaper.p[0]) < 0.02


def _velocity_step(make_sim, axis: int, prefilter: bool) -> tuple[np.ndarray, np.ndarray, object]:
    """Velocity (n,) m/s and its shaped reference (n,) m/s, per control period, after a 0.15 m/s
    velocity command on ``axis`` from hover (velocity limit 0.15 m/s, acceleration limit 1 m/s^2)."""
    sim = make_sim(physics_scenario(start_z=1.0, **{"limits.velocity": 0.15, "limits.acceleration": 1.0}))
    if not prefilter:
        sim.controller.prefilter = None
    w = sim.params.hover_rotor_speed(sim.scenario.sim.gravity)
    sim.controller.rotor_speeds[:] = w
    sim.controller.rotor_commands[:] = w
    sim.set_targets(sim.state.positions.copy())
    sim.step(2 * sim.physics_hz)
    command = np.zeros((1, 3))
    command[0, axis] = 0.15
    sim.set_targets(command, velocities=True)
    n = 2 * sim.scenario.sim.control_hz
    v, v_ref = np.empty(n), np.empty(n)
    for k in range(n):
        sim.step()
        v[k] = sim.state.velocities[0, axis]
        v_ref[k] = sim.shaper.v[0, axis]
    return v, v_ref, sim.controller.design


@pytest.mark.parametrize("axis", [0, 2])
def test_shaped_velocity_step_follows_the_prefiltered_design_model(make_sim, axis):
    """A shaped velocity step is tracked as the design's acceleration path predicts (the
    two-degree-of-freedom prefilter), not with the overshoot of the position loop catching up."""
    v, v_ref, design = _velocity_step(make_sim, axis, prefilter=True)
    hz = design.position_hz
    path = design.acceleration_path("xyz"[axis])  # discrete, at the control period
    assert path.dt == pytest.approx(1.0 / hz)
    model = np.asarray(control.forced_response(path, np.arange(v.size) / hz, v_ref).outputs).ravel()
    rms = float(np.sqrt(np.mean((v - model) ** 2)))
    raw, _, _ = _velocity_step(make_sim, axis, prefilter=False)
    print(
        f"axis {'xyz'[axis]}: RMS from the model {rms:.2e} m/s; peak {v.max() / 0.15:.3f} x the command "
        f"with the prefilter, {raw.max() / 0.15:.3f} x without"
    )
    assert rms < 0.005 * 0.15  # references fed one period ahead: 0.03 x 0.15
    assert v.max() < raw.max() - 0.03 * 0.15  # the prefilter takes the position loop's overshoot out
    assert v.max() < 1.3 * 0.15  # what is left is the acceleration path's own
    assert abs(v[-1] - 0.15) < 0.01
