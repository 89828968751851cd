"""Tests of pybullet_swarm.control.design: requirements, model construction, sampled-data behaviour."""
from __future__ import annotations

import json
from pathlib import Path

import control
import numpy as np
import pytest
import scipy.linalg
from numpy.typing import NDArray

from pybullet_swarm.control.design import (
    REQUIRED_GAIN_MARGIN_DB,
    REQUIRED_PHASE_MARGIN_DEG,
    REQUIRED_SEPARATION,
    ControllerDesign,
    DesignSpec,
    Loop,
    design_controller,
    format_table,
    pid_gains,
)
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


def _upper_margins(loop_tf: control.TransferFunction) -> tuple[float | None, float]:
    """Upper gain margin dB (None if infinite) and smallest phase margin deg, from python-control."""
    gm, pm, *_ = control.stability_margins(loop_tf, returnall=True)
    gm = np.atleast_1d(gm)
    upper = gm[np.isfinite(gm) & (gm > 1.0)]
    return (float(20 * np.log10(upper.min())) if upper.size else None), float(np.min(pm))


# ---------------------------------------------------------------------------------------------
# Requirements


def test_every_loop_meets_margin_requirements(design: ControllerDesign) -> None:
    for loop in Loop:
        rep = design.report(loop)
        assert rep.gain_margin_db is None or rep.gain_margin_db >= REQUIRED_GAIN_MARGIN_DB, loop
        assert rep.phase_margin_deg >= REQUIRED_PHASE_MARGIN_DEG, loop
        assert rep.bandwidth_rad_s > 0.0, loop
    assert design.meets_requirements() == []


def test_separation_of_attitude_and_position_loops(design: ControllerDesign) -> None:
    att = min(design.attitude[k].bandwidth_rad_s for k in ("roll", "pitch", "yaw"))
    pos = max(design.position[k].bandwidth_rad_s for k in ("x", "y", "z"))
    assert design.separation == pytest.approx(att / pos)
    assert design.separation >= REQUIRED_SEPARATION
    assert design.separation >= design.spec.separation * (1 - 1e-9)


def test_closed_loops_stable_with_unity_dc_gain(design: ControllerDesign) -> None:
    for loop in Loop:
        closed = design.closed_loop(loop)
        assert np.all(np.real(closed.poles()) < 0.0), loop
        assert float(np.real(closed.dcgain())) == pytest.approx(1.0, abs=1e-9), loop


def test_gains_positive_and_shaped(design: ControllerDesign) -> None:
    assert design.attitude_gains.shape == (3, 3)
    assert design.position_gains.shape == (3, 3)
    assert np.all(design.attitude_gains > 0.0)
    assert np.all(design.position_gains > 0.0)
    # The integral must matter: its zero ki/kp is a sizeable fraction of the loop's natural
    # frequency sqrt(kp) (about 0.19 of it for the default pole pattern).
    for kp, _kd, ki in (*design.attitude_gains, *design.position_gains):
        assert ki / kp > 0.1 * np.sqrt(kp)


def test_json_contract(design: ControllerDesign) -> None:
    data = design.to_json_dict()
    assert set(data) == {"vehicle", "attitude", "position", "separation"}
    assert set(data["attitude"]) == {"roll", "pitch", "yaw"}
    assert set(data["position"]) == {"x", "y", "z"}
    for group in ("attitude", "position"):
        for rep in data[group].values():
            assert set(rep) == {"gain_margin_db", "phase_margin_deg", "bandwidth_rad_s"}
            assert rep["gain_margin_db"] is None or type(rep["gain_margin_db"]) is float
            assert type(rep["phase_margin_deg"]) is float
            assert type(rep["bandwidth_rad_s"]) is float
    assert type(data["vehicle"]) is str and type(data["separation"]) is float
    assert json.loads(json.dumps(data, allow_nan=False)) == data


def test_x_step_response_settles(design: ControllerDesign) -> None:
    t = np.linspace(0.0, 60.0, 3001)  # s
    y = np.squeeze(control.step_response(design.closed_loop("x"), T=t).outputs)  # m
    assert abs(y[-1] - 1.0) < 0.01
    assert np.all(np.abs(y[t > 45.0] - 1.0) < 0.01)


def test_table_lists_every_loop(design: ControllerDesign) -> None:
    table = format_table(design)
    for loop in Loop:
        assert any(line.split()[0] == loop.value for line in table.splitlines() if line.strip())
    assert "all met" in table


# ---------------------------------------------------------------------------------------------
# Configuration, caching, speed


def test_rates_must_divide() -> None:
    with pytest.raises(ValueError, match=r"50.*240|240.*50"):
        design_controller(_vehicle("quad150"), physics_hz=240.0, position_hz=50.0)


def test_other_dividing_rates_are_accepted() -> None:
    d = design_controller(_vehicle("cf2x"), physics_hz=480.0, position_hz=60.0)
    assert d.meets_requirements() == []


def test_design_is_cached() -> None:
    p = _vehicle("quad150")
    a = design_controller(p)
    assert design_controller(p, physics_hz=240, position_hz=48, spec=DesignSpec()) is a
    with pytest.raises(ValueError):
        a.attitude_gains[0, 0] = 1.0  # the shared cached arrays are read-only


def test_a_fresh_spec_is_designed_anew_and_still_meets_the_requirements() -> None:
    spec = DesignSpec(wn_rel_tol=1.1e-3)  # not used elsewhere, so not cached
    d = design_controller(_vehicle("cf2x"), spec=spec)
    assert d is not design_controller(_vehicle("cf2x"))
    assert d.meets_requirements() == []


def test_bad_spec_is_refused() -> None:
    with pytest.raises(ValueError, match="damping"):
        DesignSpec(damping=1.2)


def test_violations_are_reported() -> None:
    d = design_controller(_vehicle("quad150"), spec=DesignSpec(separation=1.0))
    problems = d.meets_requirements()
    assert any(msg.startswith("separation") for msg in problems)


# ---------------------------------------------------------------------------------------------
# The models, built independently


def test_pid_gains_place_the_pole_pattern() -> None:
    wn, zeta, ratio = 3.0, 0.8, 0.4
    kp, kd, ki = pid_gains(wn, zeta, ratio)
    poles = np.sort_complex(np.roots([1.0, kd, kp, ki]))  # s^3 + kd s^2 + kp s + ki of u = -kp e - kd de - ki ie
    wanted = np.sort_complex(np.array([wn * (-zeta + 1j * np.sqrt(1 - zeta**2)),
                                       wn * (-zeta - 1j * np.sqrt(1 - zeta**2)), -ratio * wn]))
    np.testing.assert_allclose(poles, wanted, atol=1e-9)


@pytest.mark.parametrize("vehicle", VEHICLES)
def test_hand_built_roll_plant_gives_same_margins(vehicle: str) -> None:
    params = _vehicle(vehicle)
    d = design_controller(params)
    kp, kd, ki = d.attitude_gains[0]
    tau = params.motor_time_constant
    pade_num, pade_den = control.pade(0.5 / 240.0, d.spec.pade_order)
    plant = control.tf([1.0], [1.0, 0.0, 0.0]) * control.tf([1.0], [tau, 1.0]) * control.tf(pade_num, pade_den)
    loop = control.tf([kd, kp, ki], [1.0, 0.0]) * plant

    gm_db, pm_deg = _upper_margins(loop)
    rep = d.attitude["roll"]
    assert rep.phase_margin_deg == pytest.approx(pm_deg, abs=1e-6)
    assert rep.gain_margin_db is not None and gm_db is not None
    assert rep.gain_margin_db == pytest.approx(gm_db, abs=1e-6)
    w = np.logspace(-1, 3, 50)  # rad/s
    np.testing.assert_allclose(d.open_loop("roll")(1j * w), loop(1j * w), rtol=1e-9)

    # The Pade model is faithful at crossover: the exact delay gives nearly the same phase margin.
    w = np.logspace(0, 2, 20001)  # rad/s
    s = 1j * w
    exact = (kp + kd * s + ki / s) / (s**2 * (tau * s + 1.0)) * np.exp(-s * 0.5 / 240.0)
    wc = w[np.argmin(np.abs(np.abs(exact) - 1.0))]
    pm_exact = 180.0 + np.degrees(np.angle(exact[w == wc][0]))
    assert pm_exact == pytest.approx(pm_deg, abs=0.2)


def test_closed_loop_matches_block_diagram(design: ControllerDesign) -> None:
    """closed_loop() equals the block diagram: PI on the error, D on the measurement (inner loop)."""
    for loop in (Loop.ROLL, Loop.X, Loop.Z):
        kp, kd, ki = design.gains(loop)
        plant = design.plant(loop)
        inner = control.feedback(plant, control.tf([kd, 0.0], [1.0]))  # rate feedback kd s
        diagram = control.feedback(control.tf([kp, ki], [1.0, 0.0]) * inner, 1)
        w = np.logspace(-2, 2, 40)  # rad/s
        np.testing.assert_allclose(design.closed_loop(loop)(1j * w), diagram(1j * w), rtol=1e-6)


def test_margins_agree_with_frequency_sweep(design: ControllerDesign) -> None:
    """The reported margins are those of L(jw) on a dense grid (upper gain margin, not the lower one)."""
    w = np.logspace(-3, 3.5, 200001)  # rad/s
    for loop in (Loop.ROLL, Loop.X, Loop.Z):
        resp = design.open_loop(loop)(1j * w)
        mag = np.abs(resp)
        gain_cross = np.nonzero(np.diff(np.sign(mag - 1.0)))[0]
        pm = 180.0 + np.degrees(np.angle(resp[gain_cross]))
        phase_cross = np.nonzero((np.diff(np.sign(resp.imag)) != 0) & (resp.real[:-1] < 0.0))[0]
        gm_db = -20.0 * np.log10(mag[phase_cross])
        rep = design.report(loop)
        assert rep.phase_margin_deg == pytest.approx(pm.min(), abs=0.05), loop
        assert rep.gain_margin_db == pytest.approx(gm_db[gm_db > 0].min(), abs=0.05), loop
        assert gm_db.min() < -10.0  # PID on a double integrator: conditionally stable, lower margin too


def test_position_bandwidth_below_separation_limit(design: ControllerDesign) -> None:
    limit = min(r.bandwidth_rad_s for r in design.attitude.values()) / design.spec.separation
    assert all(r.bandwidth_rad_s <= limit * (1 + 1e-9) for r in design.position.values())


# ---------------------------------------------------------------------------------------------
# Sampled-data simulation of the runtime law against the continuous model


def _zoh(a: NDArray[np.float64], b: NDArray[np.float64], dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Exact zero-order-hold discretisation of x' = a x + b u over dt s."""
    n, m = b.shape
    block = np.zeros((n + m, n + m))
    block[:n, :n], block[:n, n:] = a, b
    e = scipy.linalg.expm(block * dt)
    return e[:n, :n], e[:n, n:]


def _simulate_x_cascade(design: ControllerDesign, t_end: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unit x step of the sampled cascade; returns times (n,) s and x (n,) m.

    Pitch loop at physics_hz, x loop at position_hz, motor lag and rigid body in continuous time.
    Linearised: x'' = g theta, so theta_ref = a_cmd / g.
    """
    tau = design.motor_time_constant
    # state [x m, v m/s, theta rad, w rad/s, alpha rad/s^2]; input alpha_cmd rad/s^2
    a = np.zeros((5, 5))
    a[0, 1], a[1, 2], a[2, 3], a[3, 4], a[4, 4] = 1.0, _G, 1.0, 1.0, -1.0 / tau
    b = np.array([[0.0], [0.0], [0.0], [0.0], [1.0 / tau]])
    dt = 1.0 / design.physics_hz
    ad, bd = _zoh(a, b, dt)
    ratio = round(design.physics_hz / design.position_hz)
    kp_a, kd_a, ki_a = design.gains(Loop.PITCH)
    kp_p, kd_p, ki_p = design.gains(Loop.X)
    state = np.zeros(5)
    int_att = int_pos = theta_ref = 0.0
    n = int(round(t_end / dt))
    xs = np.empty(n + 1)
    xs[0] = 0.0
    for k in range(n):
        if k % ratio == 0:
            e = state[0] - 1.0
            int_pos += e * dt * ratio
            theta_ref = (-kp_p * e - kd_p * state[1] - ki_p * int_pos) / _G
        e = state[2] - theta_ref
        int_att += e * dt
        alpha_cmd = -kp_a * e - kd_a * state[3] - ki_a * int_att
        state = ad @ state + bd[:, 0] * alpha_cmd
        xs[k + 1] = state[0]
    return np.arange(n + 1) * dt, xs


def test_sampled_cascade_matches_closed_loop_model(design: ControllerDesign) -> None:
    t, x_sim = _simulate_x_cascade(design, t_end=12.0)
    x_model = np.squeeze(control.step_response(design.closed_loop("x"), T=t).outputs)
    assert np.max(np.abs(x_sim - x_model)) < 0.02


def test_sampled_altitude_loop_rejects_payload(design: ControllerDesign) -> None:
    """A 20 % payload (constant -0.2 g) leaves no steady-state altitude error."""
    tau = design.motor_time_constant
    # state [z m, v m/s, a m/s^2 (thrust acceleration above hover)]; inputs [a_cmd, payload] m/s^2
    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0 / tau]])
    b = np.array([[0.0, 0.0], [0.0, 1.0], [1.0 / tau, 0.0]])
    dt = 1.0 / design.position_hz
    ad, bd = _zoh(a, b, dt)
    payload = -0.2 * _G  # m/s^2
    kp, kd, ki = design.gains(Loop.Z)
    state, integral = np.zeros(3), 0.0
    zs = []
    for _ in range(int(40.0 / dt)):
        integral += state[0] * dt
        a_cmd = -kp * state[0] - kd * state[1] - ki * integral
        state = ad @ state + bd @ np.array([a_cmd, payload])
        zs.append(state[0])
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
