"""Tests of pybullet_swarm.control.design: the sampled-data models, placement, margins, saturation, reports."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import control
import numpy as np
import pytest
import yaml
from numpy.typing import NDArray

from pybullet_swarm.control.design import (
    REQUIRED_GAIN_MARGIN_DB,
    REQUIRED_PHASE_MARGIN_DEG,
    REQUIRED_SEPARATION,
    ControllerDesign,
    DesignSpec,
    Loop,
    ReferenceStep,
    attitude_plant,
    design_controller,
    format_table,
    place_pid,
)
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.vehicle import VehicleParams, load_vehicle

VEHICLES = ("quad150", "cf2x")
_URDF_DIR = Path(__file__).resolve().parents[2] / "urdf"
_G = 9.81  # m/s^2


def _vehicle(name: str) -> VehicleParams:
    # By file path so the test reads the checkout's parameter files directly.
    return load_vehicle(_URDF_DIR / f"{name}.yaml")


@pytest.fixture(scope="module", params=VEHICLES)
def design(request: pytest.FixtureRequest) -> ControllerDesign:
    return design_controller(_vehicle(request.param))


def _s_poles(sys: control.StateSpace) -> NDArray[np.complex128]:
    """Poles of a discrete python-control system as ln(z) / dt, rad/s."""
    return np.log(np.asarray(sys.poles(), dtype=complex)) / sys.dt


def _match(a: NDArray[np.complex128], b: NDArray[np.complex128]) -> float:
    """Largest distance between two pole sets paired greedily, relative to the largest pole."""
    rest = list(b)
    worst = 0.0
    for p in a:
        i = int(np.argmin([abs(p - q) for q in rest]))
        worst = max(worst, abs(p - rest.pop(i)))
    return worst / max(abs(np.asarray(a))).item()


# ---------------------------------------------------------------------------------------------
# Requirements and what is placed


def test_every_loop_meets_margin_requirements(design: ControllerDesign) -> None:
    for loop in Loop:
        rep = design.report(loop)
        assert rep.gain_margin_db is None or rep.gain_margin_db >= REQUIRED_GAIN_MARGIN_DB, loop
        assert rep.phase_margin_deg >= REQUIRED_PHASE_MARGIN_DEG, loop
        assert rep.bandwidth_rad_s > 0.0, loop
    assert design.meets_requirements() == []


def test_separation_of_tilt_and_position_loops(design: ControllerDesign) -> None:
    """x and y act through tilt: their bandwidth is separated from the tilt loops'; z acts through collective
    thrust: its bandwidth is separated from the motor's, 1 / tau."""
    tilt = min(design.attitude[k].bandwidth_rad_s for k in ("roll", "pitch"))
    pos = max(design.position[k].bandwidth_rad_s for k in ("x", "y"))
    assert design.separation == pytest.approx(tilt / pos)
    assert design.separation >= REQUIRED_SEPARATION
    assert design.separation >= design.spec.separation * (1 - 1e-6)
    motor = 1.0 / design.motor_time_constant
    assert design.thrust_separation == pytest.approx(motor / design.position["z"].bandwidth_rad_s)
    assert design.thrust_separation >= design.spec.separation * (1 - 1e-6)
    assert design.to_json_dict()["thrust_separation"] == pytest.approx(design.thrust_separation)


def test_placed_poles_are_poles_of_the_full_sampled_model(design: ControllerDesign) -> None:
    """The three placed poles are exactly poles of the closed loop of the full model (python-control's
    own eigenvalues of ``closed_loop``), and the reported achieved poles are all of its poles."""
    for loop in Loop:
        rep = design.report(loop)
        wn = rep.natural_frequency_rad_s
        zeta, ratio = design.spec.damping, design.spec.integral_pole_ratio
        expected = [
            wn * complex(-zeta, math.sqrt(1 - zeta**2)),
            wn * complex(-zeta, -math.sqrt(1 - zeta**2)),
            complex(-ratio * wn, 0.0),
        ]
        np.testing.assert_allclose(rep.placed_poles, expected, rtol=1e-12)
        model = _s_poles(design.closed_loop(loop))
        assert len(rep.achieved_poles) == len(model) == (7 if loop in (Loop.X, Loop.Y) else 4), loop
        assert _match(np.array(rep.achieved_poles), model) < 1e-9, loop
        for p in rep.placed_poles:
            assert min(abs(p - q) for q in model) < 1e-8 * abs(p), (loop, p)


def test_poles_not_placed_are_stable_and_faster(design: ControllerDesign) -> None:
    for loop in Loop:
        rep = design.report(loop)
        others = list(rep.achieved_poles)
        for p in rep.placed_poles:
            others.pop(int(np.argmin([abs(p - q) for q in others])))
        pair = abs(rep.placed_poles[0].real)
        assert all(q.real < 0 for q in rep.achieved_poles), loop
        assert min(-q.real for q in others) / pair == pytest.approx(rep.dominance)
        assert rep.dominance >= design.spec.dominance, loop


def test_closed_loops_have_unity_dc_gain_and_run_at_their_rates(design: ControllerDesign) -> None:
    for loop in Loop:
        closed = design.closed_loop(loop)
        assert float(np.real(closed.dcgain())) == pytest.approx(1.0, abs=1e-9), loop
        assert closed.dt == pytest.approx(1 / design.physics_hz if loop.is_attitude else 1 / design.position_hz)


def test_gains_positive_and_shaped(design: ControllerDesign) -> None:
    assert design.attitude_gains.shape == (3, 3)
    assert design.position_gains.shape == (3, 3)
    assert np.all(design.attitude_gains > 0.0)
    assert np.all(design.position_gains > 0.0)


def test_place_pid_places_three_poles_exactly() -> None:
    h, tau = 1 / 240, 0.015
    plant = attitude_plant(h, tau)
    poles = [complex(-6, 4), complex(-6, -4), complex(-3, 0)]
    kp, kd, ki = place_pid(plant, poles)
    # the characteristic polynomial of the law c = -kp th - kd w - ki I on the plant, written out
    a_cl = np.zeros((4, 4))
    a_cl[:3, :3] = plant.a - np.outer(plant.b, [kp, kd, 0.0])
    a_cl[:3, 3] = -plant.b * ki
    a_cl[3, 0], a_cl[3, 3] = h, 1.0
    z = np.linalg.eigvals(a_cl)
    for p in poles:
        assert np.min(np.abs(z - np.exp(p * h))) < 1e-10
    with pytest.raises(ValueError, match="three real conditions"):
        place_pid(plant, [complex(-6, 4), complex(-6, -4)])


# ---------------------------------------------------------------------------------------------
# The model, built independently from the runtime's order of operations


def _runtime_attitude_step(gains: NDArray[np.float64], tau: float, h: float, n: int) -> NDArray[np.float64]:
    """Unit step of one attitude axis, simulated as the kernel and Bullet do it, step by step."""
    kp, kd, ki = gains
    theta = w = applied = integral = 0.0
    alpha = 1.0 - math.exp(-h / tau)
    out = np.empty(n)
    for k in range(n):
        e = theta - 1.0
        c = -kp * e - kd * w - ki * integral  # attitude law, integral of the previous steps
        integral += e * h
        applied += (c - applied) * alpha  # motor lag, exact over a step; applied at once
        w += h * applied  # semi-implicit Euler: velocity first
        theta += h * w
        out[k] = theta
    return out


def _runtime_x_step(design: ControllerDesign, n_periods: int) -> NDArray[np.float64]:
    """Unit x step of the cascade at the position rate, simulated in the runtime's order."""
    kp_a, kd_a, ki_a = design.gains(Loop.PITCH)
    kp, kd, ki = design.gains(Loop.X)
    h, n_sub = 1 / design.physics_hz, design.substeps
    alpha = 1.0 - math.exp(-h / design.motor_time_constant)
    x = v = theta = w = applied = i_att = i_pos = theta_ref = 0.0
    out = np.empty(n_periods)
    for j in range(n_periods):
        e = x - 1.0
        theta_ref = (-kp * e - kd * v - ki * i_pos) / _G  # a_cmd / g, held for the period
        i_pos += e * h * n_sub
        for _ in range(n_sub):
            e_a = theta - theta_ref
            c = -kp_a * e_a - kd_a * w - ki_a * i_att
            i_att += e_a * h
            applied += (c - applied) * alpha
            v_next = v + h * _G * theta  # thrust tilted by the attitude at the step's start
            w += h * applied
            theta += h * w
            v = v_next
            x += h * v
        out[j] = x
    return out


@pytest.mark.parametrize("vehicle", VEHICLES)
def test_sampled_models_equal_the_runtime_order_of_operations(vehicle: str) -> None:
    d = design_controller(_vehicle(vehicle))
    n = 480
    t = np.arange(n + 1) / d.physics_hz
    model = np.asarray(control.step_response(d.closed_loop("roll"), T=t).outputs).ravel()[1:]
    np.testing.assert_allclose(
        model, _runtime_attitude_step(d.gains("roll"), d.motor_time_constant, 1 / d.physics_hz, n), atol=1e-11
    )
    m = 400
    t = np.arange(m + 1) / d.position_hz
    model = np.asarray(control.step_response(d.closed_loop("x"), T=t).outputs).ravel()[1:]
    np.testing.assert_allclose(model, _runtime_x_step(d, m), atol=1e-10)


def test_the_motor_lag_changes_the_model() -> None:
    """The model has teeth: the same gains on a plant with a 3x slower motor give another response."""
    d = design_controller(_vehicle("quad150"))
    fast = _runtime_attitude_step(d.gains("roll"), d.motor_time_constant, 1 / 240, 240)
    slow = _runtime_attitude_step(d.gains("roll"), 3 * d.motor_time_constant, 1 / 240, 240)
    assert np.sqrt(np.mean((fast - slow) ** 2)) > 0.02


# ---------------------------------------------------------------------------------------------
# Margins and bandwidth, against an independent frequency sweep


def test_margins_agree_with_a_dense_frequency_sweep(design: ControllerDesign) -> None:
    """The reported margins are those of L(e^{jwT}) on a dense grid up to and including the Nyquist
    frequency (upper gain margin, not the lower one of the conditionally stable loop)."""
    for loop in (Loop.ROLL, Loop.YAW, Loop.X, Loop.Z):
        sys = control.tf(design.open_loop(loop))  # polynomials, evaluated independently of the design's solver
        num, den = np.asarray(sys.num[0][0], dtype=float), np.asarray(sys.den[0][0], dtype=float)
        nyq = math.pi / sys.dt
        w = np.append(np.logspace(math.log10(nyq) - 3, math.log10(nyq), 400001)[:-1], nyq)
        z = np.exp(1j * w * sys.dt)
        resp = np.polyval(num, z) / np.polyval(den, z)
        mag = np.abs(resp)
        gain_cross = np.nonzero(np.diff(np.sign(mag - 1.0)))[0]
        pm = 180.0 + np.degrees(np.angle(resp[gain_cross]))
        phase_cross = list(np.nonzero((np.diff(np.sign(resp.imag)) != 0) & (resp.real[:-1] < 0.0))[0])
        gm = [-20.0 * np.log10(mag[i]) for i in phase_cross]
        if resp[-1].real < 0:  # L is real at the Nyquist frequency
            gm.append(-20.0 * np.log10(mag[-1]))
        rep = design.report(loop)
        assert rep.phase_margin_deg == pytest.approx(pm.min(), abs=0.02), loop
        assert rep.gain_margin_db == pytest.approx(min(g for g in gm if g > 0), abs=0.02), loop
        assert min(gm) < -10.0  # PID on a double integrator: conditionally stable, lower margin too


def test_bandwidth_is_where_the_closed_loop_falls_3_db(design: ControllerDesign) -> None:
    for loop in (Loop.ROLL, Loop.X, Loop.Z):
        sys = design.closed_loop(loop)
        bw = design.report(loop).bandwidth_rad_s
        mags = np.abs(np.asarray(sys(np.exp(1j * np.array([0.999 * bw, bw, 1.001 * bw]) * sys.dt))).ravel())
        assert mags[0] > 1 / math.sqrt(2) > mags[2], loop
        assert mags[1] == pytest.approx(1 / math.sqrt(2), rel=1e-6)
        w = np.linspace(1e-3, 0.999 * bw, 2000)
        assert np.all(np.abs(np.asarray(sys(np.exp(1j * w * sys.dt))).ravel()) > 1 / math.sqrt(2)), loop


def test_position_bandwidth_below_separation_limit(design: ControllerDesign) -> None:
    limit = min(design.attitude[k].bandwidth_rad_s for k in ("roll", "pitch")) / design.spec.separation
    assert all(design.position[k].bandwidth_rad_s <= limit * (1 + 1e-9) for k in ("x", "y"))
    z_limit = 1.0 / (design.motor_time_constant * design.spec.separation)
    assert design.position["z"].bandwidth_rad_s <= z_limit * (1 + 1e-9)


# ---------------------------------------------------------------------------------------------
# Saturation: where mass, inertia, kf and the rotor speed limit enter


def test_a_vertical_acceleration_step_asks_for_the_closed_form_rotor_speed() -> None:
    p = _vehicle("cf2x")
    d = design_controller(p, step=ReferenceStep(acceleration=(0.0, 0.0, 2.0), position=(0.0, 0.0, 0.0), yaw=0.0))
    sat = d.saturation
    # the thrust command steps at once to m (g + a): every rotor at sqrt(m (g + a) / (4 kf))
    assert sat.alone["z"] == pytest.approx(math.sqrt(p.mass * (_G + 2.0) / (4 * p.kf)) / p.max_rotor_speed, rel=1e-12)
    assert sat.hover_fraction == pytest.approx(p.hover_rotor_speed(_G) / p.max_rotor_speed, rel=1e-12)
    assert sat.peak_fraction == pytest.approx(sat.alone["z"], rel=1e-12)
    # the step may go either way: a descent step of 2 m/s^2 slows every rotor to sqrt(m (g - a) / (4 kf))
    assert sat.min_fraction == pytest.approx(math.sqrt(p.mass * (_G - 2.0) / (4 * p.kf)) / p.max_rotor_speed, rel=1e-12)


def test_the_yaw_loop_takes_the_headroom_the_rotor_speed_limit_leaves() -> None:
    """quad150's weak yaw authority (km / kf = 1.9 cm) limits the yaw loop: with the default 0.5 rad
    yaw step it is slower than the tilt loops and, with the z loop before it, uses the rotor range up
    to its ends (thrust-to-weight 2: the hover speed squared is half of max_rotor_speed squared, so
    both ends bind at once); with a small yaw step, or twice the drag torque per rotor, it is faster."""
    p = _vehicle("quad150")
    d = design_controller(p)
    assert d.natural_frequency["yaw"] < 0.8 * d.natural_frequency["roll"]
    assert d.saturation.peak_fraction == pytest.approx(1.0, abs=0.01)
    assert d.saturation.min_fraction == pytest.approx(0.0, abs=0.1)
    assert d.saturation.ok and d.saturation.peak_channel in ("yaw", "z")
    small = design_controller(p, step=ReferenceStep(yaw=0.05))
    assert small.natural_frequency["yaw"] == pytest.approx(small.natural_frequency["roll"])
    stronger = dataclasses.replace(p, km=2 * p.km)
    assert design_controller(stronger).natural_frequency["yaw"] > d.natural_frequency["yaw"] * 1.2


def test_a_heavier_airframe_gets_a_slower_tilt_loop() -> None:
    """Inertia enters where it matters: 30x the inertia needs 30x the torque for the same tilt
    step, so the tilt loop is slowed down until the rotors stay within their range."""
    p = _vehicle("quad150")
    d = design_controller(p)
    heavy = dataclasses.replace(p, inertia=tuple(30 * j for j in p.inertia))
    dh = design_controller(heavy)
    assert dh.natural_frequency["roll"] < 0.9 * d.natural_frequency["roll"]
    assert dh.saturation.ok and dh.meets_requirements() == []


def _write_vehicle(tmp_path: Path, name: str, **changes: float) -> Path:
    raw = yaml.safe_load((_URDF_DIR / "quad150.yaml").read_text())
    raw.update(changes)
    raw["urdf"] = str(_URDF_DIR / "quad150.urdf")
    path = tmp_path / name
    path.write_text(yaml.safe_dump(raw))
    return path


def test_a_design_that_saturates_is_refused_naming_the_file_and_the_loop(tmp_path: Path) -> None:
    # thrust-to-weight 1.08: hovering works, a 1 m/s^2 climb step (1.1 g) does not
    weak = load_vehicle(_write_vehicle(tmp_path, "weak.yaml", max_rotor_speed=2600.0 * math.sqrt(1.08 / 2.0)))
    with pytest.raises(ConfigError) as err:
        design_controller(weak)
    assert err.value.source == "weak.yaml"
    assert err.value.field == "z"
    assert "% of max_rotor_speed" in str(err.value)
    ok = design_controller(weak, step=ReferenceStep(acceleration=(0.2, 0.2, 0.2), position=(0.0, 0.0, 0.0), yaw=0.05))
    assert ok.saturation.ok
    with pytest.raises(ConfigError, match=r"heavy.yaml: z: cannot hover"):
        design_controller(load_vehicle(_write_vehicle(tmp_path, "heavy.yaml", mass=0.4)))


def test_a_scenario_step_is_checked_against_the_designed_gains() -> None:
    d = design_controller(_vehicle("quad150"))
    shaped = ReferenceStep.from_limits([0.5, 0.5, 0.5], [1.0, 1.0, 1.0])
    rep = d.check_step(shaped)  # the bundled scenarios' limits: within the design's own step
    assert rep.ok and rep.peak_fraction < d.saturation.peak_fraction
    with pytest.raises(ConfigError, match=r"^quad150.yaml: z: the controller cannot follow the reference step"):
        d.check_step(ReferenceStep.from_limits([0.5, 0.5, 0.5], [1.0, 1.0, 10.0], yaw=0.0))
    too_fast = d.saturation_for(ReferenceStep.from_limits([0.5, 0.5, 0.5], [1.0, 1.0, 10.0], yaw=0.0))
    # hover w^2 plus the 10 m/s^2 climb step is (g + 10) / g of it; the tilt steps add the rest
    p = _vehicle("quad150")
    assert too_fast.peak_shares["hover"] == pytest.approx(p.mass * _G / (4 * p.kf * p.max_rotor_speed**2), rel=1e-9)
    assert too_fast.peak_shares["z"] == pytest.approx(too_fast.peak_shares["hover"] * 10.0 / _G, rel=1e-9)
    assert sum(too_fast.peak_shares.values()) == pytest.approx(too_fast.peak_fraction**2, rel=1e-9)


def test_reference_step_from_scenario_limits() -> None:
    shaped = ReferenceStep.from_limits([0.5, 0.5, 0.3], [1.0, 1.0, 0.5])
    assert shaped.acceleration == (1.0, 1.0, 0.5) and shaped.position == (0.0, 0.0, 0.0)
    raw = ReferenceStep.from_limits(None, 1.0)
    assert raw.acceleration == (0.0, 0.0, 0.0) and raw.position == (0.1, 0.1, 0.1)
    with pytest.raises(ValueError, match="acceleration"):
        ReferenceStep(acceleration=(-1.0, 0.0, 0.0))


# ---------------------------------------------------------------------------------------------
# Reports


def test_json_contract(design: ControllerDesign) -> None:
    data = design.to_json_dict()
    assert {"vehicle", "attitude", "position", "separation", "saturation", "requirements_met"} <= set(data)
    assert set(data["attitude"]) == {"roll", "pitch", "yaw"}
    assert set(data["position"]) == {"x", "y", "z"}
    for group in ("attitude", "position"):
        for name, rep in data[group].items():
            assert {
                "gain_margin_db",
                "phase_margin_deg",
                "bandwidth_rad_s",
                "placed_poles",
                "achieved_poles",
                "gains",
            } <= set(rep)
            assert len(rep["placed_poles"]) == 3
            assert all(len(p) == 2 and all(type(v) is float for v in p) for p in rep["achieved_poles"])
            assert rep["achieved_poles"] == [[p.real, p.imag] for p in design.report(name).achieved_poles]
    assert data["requirements_met"] is True and data["saturation"]["ok"] is True
    assert json.loads(json.dumps(data, allow_nan=False)) == data


def test_table_lists_every_loop_with_its_poles(design: ControllerDesign) -> None:
    table = format_table(design)
    lines = [line for line in table.splitlines() if line.strip()]
    for loop in Loop:
        assert sum(line.split()[0] == loop.value for line in lines) == 2  # gains row and poles row
    assert "placed" in table and "achieved" in table and "saturation" in table
    assert "all met" in table


# ---------------------------------------------------------------------------------------------
# Configuration, caching


def test_rates_must_divide() -> None:
    with pytest.raises(ValueError, match=r"50.*240|240.*50"):
        design_controller(_vehicle("quad150"), physics_hz=240.0, position_hz=50.0)


def test_other_dividing_rates_are_accepted() -> None:
    d = design_controller(_vehicle("cf2x"), physics_hz=480.0, position_hz=60.0)
    assert d.meets_requirements() == []
    assert d.substeps == 8


def test_design_is_cached() -> None:
    p = _vehicle("quad150")
    a = design_controller(p)
    assert design_controller(p, physics_hz=240, position_hz=48, spec=DesignSpec(), step=ReferenceStep()) is a
    with pytest.raises(ValueError):
        a.attitude_gains[0, 0] = 1.0  # the shared cached arrays are read-only


def test_bad_spec_is_refused() -> None:
    with pytest.raises(ValueError, match="damping"):
        DesignSpec(damping=1.2)


def test_violations_are_reported() -> None:
    d = design_controller(_vehicle("quad150"))
    assert d.meets_requirements() == []
    problems = dataclasses.replace(d, separation=1.0, motor_time_constant=1.0).meets_requirements()
    assert any(msg.startswith("separation 1.00") for msg in problems)
    assert any(msg.startswith("thrust separation") for msg in problems)


def test_payload_is_rejected_by_the_sampled_altitude_loop(design: ControllerDesign) -> None:
    """A 20 % payload (constant -0.2 g) leaves no steady-state altitude error."""
    plant = design.sampled_plant("z")
    a_cl, _ = plant.closed(design.gains("z"))
    # the payload enters as an acceleration on the velocity: over one period, v += T d, z += ~T^2 d
    dist = np.zeros(a_cl.shape[0])
    h, n = 1 / design.physics_hz, design.substeps
    dist[0], dist[1] = h * h * n * (n + 1) / 2, n * h  # semi-implicit Euler over n physics steps
    x = np.zeros(a_cl.shape[0])
    zs = []
    for _ in range(int(40.0 * design.position_hz)):
        x = a_cl @ x + dist * (-0.2 * _G)
        zs.append(x[0])
    zs_arr = np.array(zs)  # m
    assert zs_arr.min() < -0.01  # the payload does push it down...
    assert abs(zs_arr[-1]) < 1e-3 * abs(zs_arr.min())  # ...and the integral brings it back


# ---------------------------------------------------------------------------------------------
# Plots


def test_plot_design_writes_pngs(tmp_path: Path) -> None:
    from pybullet_swarm.plotting.design_plots import plot_design

    paths = plot_design(design_controller(_vehicle("cf2x")), tmp_path / "plots")
    assert [p.name for p in paths] == ["bode.png", "step_response.png"]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_designs_handed_to_another_process_are_used_as_they_are() -> None:
    import pickle

    from pybullet_swarm.control import design as d

    made = d.design_controller(load_vehicle("cf2x"), physics_hz=240.0, position_hz=48.0, gravity=9.7)
    shipped = pickle.loads(pickle.dumps(d.known_designs()))  # what a worker process receives
    saved = dict(d._DESIGNS)
    try:
        d._DESIGNS.clear()
        d.add_designs(shipped)
        again = d.design_controller(load_vehicle("cf2x"), physics_hz=240.0, position_hz=48.0, gravity=9.7)
        assert again is next(v for v in shipped.values() if v.vehicle == "cf2x" and v.airframe.gravity == 9.7)
        assert np.array_equal(again.attitude_gains, made.attitude_gains)
    finally:
        d._DESIGNS.clear()
        d._DESIGNS.update(saved)
