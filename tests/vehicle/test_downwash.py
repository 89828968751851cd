"""Downwash: the kernel against the model's closed form, the vehicle files' constants, and in flight."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.experiment.simulation import Simulation
from pybullet_swarm.resources import urdf_dir
from pybullet_swarm.vehicle import load_vehicle
from pybullet_swarm.vehicle.downwash import Downwash, DownwashParams, downwash_all_pairs, downwash_sweep

# quad150's constants as its vehicle file gives them
R, ALPHA, ZETA, ETA, MIN_W, K = 0.03175, 12595.4, 0.16, -0.151, 0.053, 0.5
MASS, G0 = 0.150, 9.81


def closed_form(d: float, dz: float, thrust: float, k: float = K) -> float:
    """N, downward force on a quad150 dz m below and d m beside a quad150 of ``thrust`` N, by hand
    (``k`` the momentum fraction)."""
    if dz <= 0.0:
        return 0.0
    beta = max(ZETA * dz + ETA, MIN_W)
    fitted = ALPHA / (MASS * G0) * (R / (4.0 * dz)) ** 2  # per newton of the upper thrust
    bound = k * (1.0 - math.exp(-2.0 * R**2 / beta**2))
    return thrust * min(fitted, bound) * math.exp(-0.5 * d**2 / beta**2)


def kernel_force(
    points: list[list[float]], thrust: float = 1.0, vehicle: str = "quad150", k: float | None = None
) -> np.ndarray:
    """Vertical force (n,) N the kernel puts on agents at ``points`` whose rotors all give ``thrust``."""
    p = load_vehicle(vehicle)
    dw = p.downwash_params if k is None else dataclasses.replace(p.downwash_params, momentum_fraction=k)
    state = np.zeros((len(points), 13))
    state[:, :3] = points
    w = np.full((len(points), 4), math.sqrt(thrust / (4.0 * p.kf)))
    force = np.zeros((len(points), 3))
    Downwash(dw, kf=p.kf, mass=p.mass).add_to(state, w, force)
    assert np.all(force[:, :2] == 0.0)  # the model gives a vertical force only
    return force[:, 2]


def test_quad150_file_gives_the_constants_of_the_closed_form():
    d = load_vehicle("quad150").downwash_params
    assert (d.rotor_radius, d.alpha, d.zeta, d.eta, d.min_width, d.momentum_fraction) == (R, ALPHA, ZETA, ETA, MIN_W, K)
    cf = load_vehicle("cf2x").downwash_params  # gym-pybullet-drones' Crazyflie constants
    assert (cf.rotor_radius, cf.alpha, cf.zeta, cf.eta) == (0.0231348, 2267.18, 0.16, -0.11)


@pytest.mark.parametrize(
    ("d", "dz", "k", "expected"),
    [
        (0.0, 0.30, K, 0.25607),  # directly above, near wake: the bound k (1 - exp(-2 r^2 / min_width^2))
        (0.05, 0.30, K, 0.16410),  # 5 cm off: times exp(-d^2 / (2 min_width^2))
        (0.0, 1.50, K, 0.11236),  # wider wake (beta = zeta dz + eta = 0.089 m): a smaller share through the discs
        (0.10, 2.00, K, 0.028605),  # wide wake (beta = 0.169 m), 10 cm off
        (0.0, 1.20, 1.0, 0.37450),  # with k = 1 the fitted alpha (r / 4 dz)^2 is the smaller at 1.2 m
    ],
)
def test_force_on_the_lower_vehicle_is_the_closed_form(d, dz, k, expected):
    f = kernel_force([[1.0, 1.0, 1.0], [1.0 + d, 1.0, 1.0 + dz]], thrust=1.0, k=k)
    assert closed_form(d, dz, 1.0, k) == pytest.approx(expected, rel=1e-4)  # the hand numbers
    assert -f[0] == pytest.approx(closed_form(d, dz, 1.0, k), rel=1e-12)
    assert f[1] == 0.0  # the upper vehicle feels nothing


def test_with_these_constants_the_fit_is_above_the_momentum_bound_everywhere():
    """gym-pybullet-drones' alpha (r / 4 dz)^2 exceeds what the wake's momentum allows at every
    separation (by 1.3 times at least, where the width starts to grow): the bound sets the force."""
    for vehicle in ("quad150", "cf2x"):
        p = load_vehicle(vehicle)
        dw = p.downwash_params
        dz = np.linspace(0.005, 20.0, 20001)
        beta = dw.width(dz)
        fitted = dw.alpha / (p.mass * 9.81) * (dw.rotor_radius / (4 * dz)) ** 2
        bound = dw.momentum_fraction * (1 - np.exp(-2 * dw.rotor_radius**2 / beta**2))
        assert np.min(fitted / bound) > 1.25
        assert fitted[np.searchsorted(dz, 0.1)] > 25  # 0.1 m below: 25+ times the upper thrust


@pytest.mark.parametrize("fraction", [0.2, 0.05, 0.02])
def test_the_wake_depth_is_where_the_force_straight_below_falls_to_the_fraction(fraction: float):
    """``DownwashParams.depth``: by hand, where the wake is wider than the airframe (beta > min_width) and the
    momentum bound holds, k (1 - exp(-2 r^2 / beta^2)) = fraction gives beta, and dz = (beta - eta) / zeta."""
    p = load_vehicle("quad150")
    beta = math.sqrt(-2.0 * R**2 / math.log(1.0 - fraction / K))
    assert beta > MIN_W
    expected = (beta - ETA) / ZETA
    depth = p.downwash_params.depth(fraction, mass=p.mass)
    assert depth == pytest.approx(expected, abs=1e-5)
    assert closed_form(0.0, depth * 0.99, 1.0) > fraction > closed_form(0.0, depth * 1.01, 1.0)
    with pytest.raises(ValueError, match="fraction"):
        p.downwash_params.depth(1.5, mass=p.mass)


def test_force_scales_with_the_upper_thrust_and_adds_over_vehicles_above():
    one = kernel_force([[1.0, 1.0, 1.0], [1.0, 1.0, 1.3]], thrust=1.4715)
    assert -one[0] == pytest.approx(closed_form(0.0, 0.3, 1.4715), rel=1e-12)
    three = kernel_force([[1.0, 1.0, 1.0], [1.0, 1.0, 1.3], [1.05, 1.0, 1.6]], thrust=1.0)
    assert -three[0] == pytest.approx(closed_form(0.0, 0.3, 1.0) + closed_form(0.05, 0.6, 1.0), rel=1e-12)
    assert -three[1] == pytest.approx(closed_form(0.05, 0.3, 1.0), rel=1e-12)
    assert three[2] == 0.0
    assert np.all(kernel_force([[1.0, 1.0, 1.0], [1.0, 1.0, 1.3]], thrust=0.0) == 0.0)  # still rotors: no wake


def test_level_below_and_far_vehicles_feel_nothing():
    level = kernel_force([[1.0, 1.0, 1.0], [1.1, 1.0, 1.0]])
    assert np.all(level == 0.0)
    # level flight a hair apart in height, side by side: the near wake is the airframe's width
    hair = kernel_force([[1.0, 1.0, 1.0], [1.2, 1.0, 1.0 + 1e-9]])
    assert closed_form(0.2, 1e-9, 1.0) < 1e-3
    assert np.all(hair == 0.0)  # below the cut-off
    reach = load_vehicle("quad150").downwash_params.reach()
    assert reach == pytest.approx(2 * R * math.sqrt(K / (math.e * 1e-3)))
    # the worst height for a pair at the reach: a wake of width d / sqrt(2)
    dz = (reach / math.sqrt(2.0) - ETA) / ZETA
    inside = kernel_force([[1.0, 1.0, 1.0], [1.0 + 0.99 * reach, 1.0, 1.0 + dz]])
    assert -inside[0] == pytest.approx(closed_form(0.99 * reach, dz, 1.0), rel=1e-12)
    assert 0.99e-3 < -inside[0] < 1e-3 / 0.99**2  # about 1e-3 of the upper thrust at the cut-off
    far = kernel_force([[1.0, 1.0, 1.0], [1.0 + 1.01 * reach, 1.0, 1.0 + dz]])
    assert np.all(far == 0.0)
    # out of the wake at its height (d > beta sqrt(2 ln(k / 1e-3))): skipped, the force would be below 1e-3
    edge = MIN_W * math.sqrt(2.0 * math.log(K / 1e-3))
    assert closed_form(1.01 * edge, 0.3, 1.0) < 1e-3
    assert np.all(kernel_force([[1.0, 1.0, 1.0], [1.0 + 1.01 * edge, 1.0, 1.3]]) == 0.0)
    near = kernel_force([[1.0, 1.0, 1.0], [1.0 + 0.99 * edge, 1.0, 1.3]])
    assert -near[0] == pytest.approx(closed_form(0.99 * edge, 0.3, 1.0), rel=1e-12)
    # the bound holds at every distance and height: F <= k T 4 r^2 / (e d^2)
    d = np.linspace(0.06, 1.2, 40)
    for dz in (0.01, 0.3, 1.0, 1.3, 3.0):
        f = np.array([closed_form(x, dz, 1.0) for x in d])
        assert np.all(f <= K * 4 * R**2 / (math.e * d**2) * (1 + 1e-12))


def test_sweep_and_all_pairs_kernels_agree():
    rng = np.random.default_rng(5)
    p = load_vehicle("cf2x")
    n = 200
    state = np.zeros((n, 13))
    state[:, :2] = rng.uniform(0.0, 1.5, size=(n, 2))
    state[:, 2] = rng.uniform(0.5, 2.0, size=n)
    w = rng.uniform(0.5, 0.9, size=(n, 4)) * p.max_rotor_speed
    c = p.downwash_params.const(kf=p.kf, mass=p.mass)
    a, b = np.zeros((n, 3)), np.zeros((n, 3))
    downwash_all_pairs(state, w, c, a)
    downwash_sweep(state, w, c, b)
    assert np.count_nonzero(a[:, 2]) > n // 2  # most agents have someone above within reach
    np.testing.assert_allclose(b, a, rtol=1e-12, atol=0.0)


def test_a_vehicle_file_without_constants_gets_the_crazyflie_constants_scaled(tmp_path: Path):
    raw = yaml.safe_load((urdf_dir() / "quad150.yaml").read_text())
    for key in [k for k in raw if k.startswith("downwash_") or k == "rotor_radius"]:
        del raw[key]
    (tmp_path / "quad150.urdf").write_text((urdf_dir() / "quad150.urdf").read_text())
    (tmp_path / "bare.yaml").write_text(yaml.safe_dump(raw))
    d = load_vehicle(tmp_path / "bare.yaml").downwash_params
    r = 0.6 * 0.053  # default rotor radius
    assert d == DownwashParams(r, 2267.18 * 0.150 / 0.027, 0.16, -0.11 * r / 0.0231348, 0.053, 0.5)
    raw["downwash_zeta"] = 0.2  # a field given replaces its default only
    (tmp_path / "zeta.yaml").write_text(yaml.safe_dump(raw))
    assert load_vehicle(tmp_path / "zeta.yaml").downwash_params == DownwashParams(
        r, 2267.18 * 0.150 / 0.027, 0.2, -0.11 * r / 0.0231348, 0.053, 0.5
    )
    raw["rotor_radius"] = 0.04  # rotors 0.053 * sqrt(2) = 7.5 cm apart cannot be 8 cm wide
    (tmp_path / "big.yaml").write_text(yaml.safe_dump(raw))
    with pytest.raises(ConfigError, match="rotors would overlap"):
        load_vehicle(tmp_path / "big.yaml")


# ------------------------------------------------------------------------------------------ in flight
def stacked(vehicle: str, d: float, dz: float, downwash: bool) -> tuple[Simulation, np.ndarray]:
    """Two agents that end up holding one dz above and d beside the other (they start apart: the
    scenario refuses overlapping footprints) after 25 s, with the closed-loop cascade."""
    low, up = [1.5, 1.5, 1.0], [1.5 + d, 1.5, 1.0 + dz]
    sc = load_scenario(
        "hover",
        {
            "agents.count": 2,
            "agents.vehicle": vehicle,
            "agents.start": [low, [1.9, 1.5, 1.0 + dz]],
            "task.time_limit_s": 1000.0,
            "task.waypoints": [{"t_s": 0.0, "position": [0.0, 0.0, 0.0]}],
            "sim.downwash": downwash,
        },
    )
    sim = Simulation(sc)
    sim.set_targets(np.array([low, up]))
    sim.step(25 * sim.physics_hz)
    p = load_vehicle(vehicle)
    thrust = p.kf * np.sum(sim.controller.rotor_speeds**2, axis=1)  # N, steady rotor thrust of each agent
    return sim, thrust


def vehicle_file(tmp_path: Path, name: str, **fields: float) -> str:
    """A copy of a bundled vehicle with ``fields`` changed, beside a copy of its URDF."""
    raw = yaml.safe_load((urdf_dir() / f"{name}.yaml").read_text())
    raw.update(fields)
    (tmp_path / raw["urdf"]).write_text((urdf_dir() / raw["urdf"]).read_text())
    (tmp_path / f"{name}.yaml").write_text(yaml.safe_dump(raw))
    return str(tmp_path / f"{name}.yaml")


@pytest.mark.parametrize(
    ("vehicle", "d", "dz", "k"), [("quad150", 0.05, 0.3, None), ("cf2x", 0.02, 0.3, None), ("cf2x", 0.02, 0.3, 1.0)]
)
def test_a_vehicle_hovering_under_another_carries_the_predicted_downwash(tmp_path, vehicle, d, dz, k):
    """At rest the lower vehicle's thrust is its weight plus the downwash (nothing else acts on it:
    no drag, no ground effect), so its thrust exceeds the upper one's by the model's force at the
    separation where it settled, computed from the vehicle's constants by hand. After 25 s the
    slowest pole of the z loop (-2.2 rad/s, cf2x) has decayed by exp(-55): what is left of the
    transient is far below the 1e-4 tolerance."""
    path = vehicle if k is None else vehicle_file(tmp_path, vehicle, downwash_momentum_fraction=k)
    p = load_vehicle(path)
    dw = p.downwash_params
    sim, thrust = stacked(path, d, dz, downwash=True)
    with sim:
        pos = sim.state.positions
        weight = p.mass * sim.scenario.sim.gravity
        assert thrust[1] == pytest.approx(weight, rel=1e-6)  # the upper vehicle is not affected
        sep_d = float(np.hypot(*(pos[1, :2] - pos[0, :2])))
        sep_dz = float(pos[1, 2] - pos[0, 2])
        beta = max(dw.zeta * sep_dz + dw.eta, dw.min_width)
        peak = min(
            dw.alpha / (p.mass * 9.81) * (dw.rotor_radius / (4 * sep_dz)) ** 2,
            dw.momentum_fraction * (1.0 - math.exp(-2 * dw.rotor_radius**2 / beta**2)),
        )
        predicted = thrust[1] * peak * math.exp(-0.5 * sep_d**2 / beta**2)
        assert predicted > 0.15 * weight  # a sizeable force: this is not a test of nothing
        assert thrust[0] - thrust[1] == pytest.approx(predicted, rel=1e-4)
        assert abs(sim.state.velocities[0, 2]) < 1e-4
        kp = sim.controller.pos_gains[2, 0]
        carried = sim.controller.POSITION_INTEGRAL_LIMIT[2]  # m/s^2, the most the z integrator may carry
        if predicted / p.mass > carried:
            # with k = 1 the downwash on cf2x (4.26 m/s^2) is more than the z integrator may carry:
            # the proportional term takes the rest, so the lower vehicle sinks by (F/m - 4) / kp, 7 mm
            sink = (predicted / p.mass - carried) / kp
            assert k == 1.0 and 0.005 < sink < 0.01
            assert 1.0 - pos[0, 2] == pytest.approx(sink, rel=1e-3)
        else:
            assert pos[0, 2] == pytest.approx(1.0, abs=1e-5)  # the integrator carries it


def test_without_downwash_the_lower_vehicle_holds_at_its_weight():
    sim, thrust = stacked("quad150", 0.05, 0.3, downwash=False)
    with sim:
        weight = 0.150 * sim.scenario.sim.gravity
        np.testing.assert_allclose(thrust, weight, rtol=1e-9)
        assert sim.state.positions[0, 2] == pytest.approx(1.0, abs=1e-6)


def test_a_crash_is_put_down_to_a_contact_to_the_wake_or_to_neither():
    """Crashes without avoidance on the construction suite came with no agent-agent contact before them, from
    an agent hovering above the one that fell: ``crash_cause`` tells an agent-agent contact within
    ``CRASH_LOOKBACK_S`` from the wake (downwash of at least ``WAKE_CAUSE_FRACTION`` of the weight at a
    recording instant in that time) from neither. The downwash each vehicle carried is the model's."""
    from pybullet_swarm.experiment.simulation import WAKE_CAUSE_FRACTION
    from pybullet_swarm.types import Event

    sim, thrust = stacked("quad150", 0.05, 0.3, downwash=True)
    with sim:
        assert sim.downwash is not None
        assert sim.downwash.last[0] == pytest.approx(thrust[0] - thrust[1], rel=1e-3)  # what held it down
        assert sim.downwash.last[1] == 0.0
        assert sim.downwash.last[0] > WAKE_CAUSE_FRACTION * sim.weight
        cause, why = sim._crash_cause(0)
        assert cause == "wake" and "no agent-agent contact" in why
        assert sim._crash_cause(1)[0] == "other"
        sim.events.append(Event(sim.time - 1.0, "agent_agent", "agent1", "agent0"))
        cause, why = sim._crash_cause(1)
        assert cause == "agent_agent_contact" and "contact with agent0" in why
        sim.events[-1] = Event(sim.time - 4.0, "agent_agent", "agent1", "agent0")  # too long before
        assert sim._crash_cause(1)[0] == "other"
