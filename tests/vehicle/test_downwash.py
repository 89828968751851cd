"""Rotor wake: the flow against its published laws, the forces against closed forms and Neural-Swarm's
measurements, the vehicle files, and in flight."""

from __future__ import annotations

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
from pybullet_swarm.vehicle.downwash import (
    BOX_DRAG,
    JET_B,
    JET_S,
    JET_START,
    JET_Z0,
    PROFILE_A,
    RHO_AIR,
    Downwash,
    DownwashParams,
    _rotor_loss,
)

G = 9.81
GF = G / 1000.0  # N per gram-force

#: Shi et al., "Neural-Swarm" (ICRA 2020), Fig. 3: force on a 34 g Crazyflie straight below another,
#: gram-force, read off the figure, by vertical distance m
NEURAL_SWARM = {0.2: 10.0, 0.3: 8.0, 0.4: 6.0, 0.5: 4.0, 0.7: 0.0}
NS_MASS = 0.034  # kg, their Crazyflies with markers and battery
#: what the model gives there (both vehicles at hover thrust), gram-force: documented in docs/science/wake.md
MODEL_AT_NS = {0.2: 8.25, 0.3: 7.88, 0.4: 7.44, 0.5: 6.98, 0.7: 6.13}


def model_gf(dz: float) -> float:
    cf = load_vehicle("cf2x").downwash_params
    w = NS_MASS * G
    return cf.force_on_vehicle(dz, upper_thrust=w, lower_thrust=w) / GF


@pytest.mark.parametrize("dz", [0.2, 0.3, 0.4])
def test_neural_swarm_points_within_2_gram_force(dz: float):
    """Crazyflie pairs at hover thrust (34 g each): the model's force within 2 gf of Neural-Swarm's points."""
    f = model_gf(dz)
    assert f == pytest.approx(MODEL_AT_NS[dz], abs=0.01)
    assert abs(f - NEURAL_SWARM[dz]) <= 2.0


@pytest.mark.xfail(strict=True, reason="the jet decays as 1 / (z - z0), z0 = -5.8 l: 7.0 and 6.1 gf against 4 and 0")
@pytest.mark.parametrize("dz", [0.5, 0.7])
def test_neural_swarm_far_points_within_2_gram_force(dz: float):
    """Not met: at 0.5 and 0.7 m the published jet still carries 2.7-3 m/s on the lower rotors, a force of 7.0
    and 6.1 gf where Neural-Swarm reads about 4 and 0 (residuals 3.0 and 6.1 gf)."""
    f = model_gf(dz)
    assert f == pytest.approx(MODEL_AT_NS[dz], abs=0.01)  # the measured residual, as documented
    assert abs(f - NEURAL_SWARM[dz]) <= 2.0


@pytest.mark.parametrize("vehicle", ["cf2x", "quad150"])
@pytest.mark.parametrize("thrust_per_weight", [1.0, 1.6])
def test_far_field_follows_the_jet_scaling(vehicle: str, thrust_per_weight: float):
    """Below 2.5 l every airframe's centreline velocity over U_H and half-width over l collapse onto Bauersfeld
    et al.'s normalised jet: Uc (z - z0) / (U_H l) = B and b / (z - z0) = S, whatever the size and thrust;
    1 / z decay and linear growth, and the profile halves at b."""
    p = load_vehicle(vehicle)
    dw = p.downwash_params
    thrust = thrust_per_weight * p.mass * G
    ell = 2.0 * p.arm_length
    uh = math.sqrt(thrust / (2.0 * RHO_AIR * 4.0 * math.pi * dw.rotor_radius**2))
    assert dw.hover_velocity(thrust) == pytest.approx(uh)
    for z_l in (JET_START, 4.0, 10.0, 30.0):
        z = z_l * ell
        uc, b = dw.centreline(z, thrust)
        assert uc * (z - JET_Z0 * ell) / (uh * ell) == pytest.approx(JET_B, rel=1e-12)
        assert b / (z - JET_Z0 * ell) == pytest.approx(JET_S, rel=1e-12)
        assert dw.velocity(b, z, thrust) == pytest.approx(0.5 * uc, rel=1e-12)
    # the near field: momentum theory at the disc (U_H) and the blend is continuous where the jet begins
    uc0, _ = dw.centreline(1e-9, thrust)
    assert uc0 == pytest.approx(uh, rel=1e-6)
    z_f = JET_START * ell
    below, above = dw.centreline(z_f * (1 - 1e-9), thrust), dw.centreline(z_f * (1 + 1e-9), thrust)
    assert below == pytest.approx(above, rel=1e-6)


@pytest.mark.parametrize("vehicle", ["cf2x", "quad150"])
def test_the_jet_carries_about_the_thrust_as_momentum_flux(vehicle: str):
    """A free jet carries the momentum flux of the thrust that made it: integrated over the profile, the far
    field's flux rho pi Uc^2 b^2 / (3 A) is the same at every depth and 0.6-1 times the thrust (0.72 cf2x,
    0.67 quad150): the fitted constants are physically consistent with these airframes."""
    p = load_vehicle(vehicle)
    dw = p.downwash_params
    thrust = p.mass * G
    fluxes = []
    for z in (0.3, 1.0, 3.0):
        uc, b = dw.centreline(z, thrust)
        rho = np.linspace(0.0, 40.0 * b, 400001)
        u = uc / (1.0 + PROFILE_A * (rho / b) ** 2) ** 2
        numeric = np.trapezoid(RHO_AIR * u * u * 2.0 * np.pi * rho, rho)
        assert numeric == pytest.approx(RHO_AIR * math.pi * uc**2 * b**2 / (3.0 * PROFILE_A), rel=1e-4)
        fluxes.append(numeric / thrust)
    assert max(fluxes) - min(fluxes) < 1e-3
    assert 0.6 < fluxes[0] < 1.0


def test_rotor_loss_is_blade_element_momentum_theory():
    """At constant rotor speed: no inflow, no loss; a small inflow V loses c q / (q + 4) of the thrust (c = V / v_h,
    linear in V); the loss grows with the inflow and never exceeds the thrust."""
    q = load_vehicle("cf2x").downwash_params.blade_ratio
    assert _rotor_loss(0.0, q) == 0.0
    c = 1e-6
    assert _rotor_loss(c, q) / c == pytest.approx(q / (q + 4.0), rel=1e-4)
    cs = np.linspace(0.0, 5.0, 200)
    loss = np.array([_rotor_loss(float(x), q) for x in cs])
    assert np.all(np.diff(loss) >= 0.0) and loss[-1] <= 1.0
    # by hand at c = 0.5: 2 x^2 + (1 + q) x - (2 + q / 2) = 0, kept thrust x (0.5 + x)
    x = (-(1 + q) + math.sqrt((1 + q) ** 2 + 8 * (2 + q / 2))) / 4
    assert _rotor_loss(0.5, q) == pytest.approx(1 - x * (0.5 + x), rel=1e-12)


@pytest.mark.parametrize("vehicle", ["cf2x", "quad150"])
def test_far_below_the_force_is_the_rotor_loss_in_the_centreline_flow(vehicle: str):
    """Deep in the jet the flow is uniform over the lower vehicle (b >> arm length): each rotor loses
    T_k loss(Uc / v_h) with v_h = sqrt(T_k / (2 rho pi r^2))."""
    p = load_vehicle(vehicle)
    dw = p.downwash_params
    w = p.mass * G
    dz = 20.0
    uc, _ = dw.centreline(dz, w)
    vh = math.sqrt(0.25 * w / (2 * RHO_AIR * math.pi * dw.rotor_radius**2))
    expected = w * _rotor_loss(uc / vh, dw.blade_ratio)
    assert dw.force_on_vehicle(dz, upper_thrust=w, lower_thrust=w) == pytest.approx(expected, rel=2e-3)


@pytest.mark.parametrize(("dz", "offset"), [(25.0, 0.0), (0.4, 0.0), (0.4, 0.1), (0.02, 0.0)])
def test_box_drag_is_the_top_face_drag(dz: float, offset: float):
    """F = 1/2 rho C_d <V^2> A over the top face: against a fine numerical mean of V^2 over the face (the
    kernel's 3 x 3 Gauss points), and far below, where the flow is uniform, the closed form with Uc."""
    dw = load_vehicle("quad150").downwash_params
    thrust, size = 0.16 * G, 0.1
    f = dw.force_on_box(dz, size, thrust=thrust, offset=offset)
    xs = np.linspace(-size / 2, size / 2, 401)
    X, Y = np.meshgrid(xs + offset, xs)
    uc, b = dw.centreline(dz, thrust)
    v = uc / (1.0 + PROFILE_A * (X**2 + Y**2) / b**2) ** 2
    mean_v2 = np.trapezoid(np.trapezoid(v * v, xs, axis=1), xs) / size**2
    assert f == pytest.approx(0.5 * RHO_AIR * BOX_DRAG * size**2 * mean_v2, rel=0.03)
    if dz > 10:
        assert f == pytest.approx(0.5 * RHO_AIR * BOX_DRAG * size**2 * uc**2, rel=1e-3)
    assert f > 0.0


def _forces(points, thrusts, vehicle="quad150", quats=None, boxes=None):
    p = load_vehicle(vehicle)
    n = len(points)
    state = np.zeros((n, 13))
    state[:, :3] = points
    state[:, 6] = 1.0
    if quats is not None:
        state[:, 3:7] = quats
    w = np.sqrt(np.asarray(thrusts, dtype=float)[:, None] / (4.0 * p.kf)) * np.ones((n, 4))
    force = np.zeros((n, 3))
    dw = Downwash(p.downwash_params)
    if boxes is None:
        dw.add_to(state, w, force)
        return force, None, dw
    poses = np.zeros((len(boxes), 7))
    poses[:, :3] = boxes
    poses[:, 6] = 1.0
    bf = np.zeros((len(boxes), 3))
    dw.add_to(state, w, force, poses, np.full((len(boxes), 3), 0.05), bf)
    return force, bf, dw


def test_only_bodies_below_feel_a_wake_and_wakes_add_up():
    w = 0.15 * G
    level, _, _ = _forces([[1.0, 1.0, 1.0], [1.2, 1.0, 1.0]], [w, w])
    assert np.all(level == 0.0)
    f, _, dw = _forces([[1.0, 1.0, 1.0], [1.0, 1.0, 1.3], [1.0, 1.0, 1.6]], [w, w, w])
    one = load_vehicle("quad150").downwash_params
    assert -f[0, 2] == pytest.approx(
        one.force_on_vehicle(0.3, upper_thrust=w, lower_thrust=w)
        + one.force_on_vehicle(0.6, upper_thrust=w, lower_thrust=w)
    )
    assert f[2, 2] == 0.0 and np.all(f[:, :2] == 0.0)
    np.testing.assert_allclose(dw.last, -f[:, 2])
    still, _, _ = _forces([[1.0, 1.0, 1.0], [1.0, 1.0, 1.3]], [w, 0.0])
    assert np.all(still == 0.0)  # still rotors: no wake
    far, _, _ = _forces([[1.0, 1.0, 1.0], [3.0, 1.0, 1.3]], [w, w])
    assert np.all(far == 0.0)


def test_the_wake_follows_the_upper_vehicles_thrust_axis():
    """An upper vehicle tilted 20 deg about x blows along its thrust axis: a vehicle on that axis gets more than
    one straight below it, and the force on the lower vehicle is along its own thrust axis."""
    w = 0.15 * G
    tilt = math.radians(20.0)
    q = [math.sin(tilt / 2), 0.0, 0.0, math.cos(tilt / 2)]  # about x: thrust axis (0, -sin, cos), flow to +y
    level = [0.0, 0.0, 0.0, 1.0]
    dz = 0.6
    on_axis, _, _ = _forces([[0.0, dz * math.tan(tilt), 0.0], [0.0, 0.0, dz]], [w, w], quats=[level, q])
    plumb, _, _ = _forces([[0.0, 0.0, 0.0], [0.0, 0.0, dz]], [w, w], quats=[level, q])
    assert -on_axis[0, 2] > 1.5 * -plumb[0, 2] > 0.0
    assert on_axis[0, 0] == 0.0 and on_axis[0, 1] == pytest.approx(0.0, abs=1e-12)


def test_boxes_below_a_vehicle_are_pushed_down_and_others_not():
    w = 0.16 * G
    f, bf, _ = _forces(
        [[1.0, 1.0, 1.0]], [w], boxes=[[1.0, 1.0, 1.0 - 0.015 - 0.05], [1.0, 1.0, 1.2], [2.5, 1.0, 0.05]]
    )
    assert bf is not None
    one = load_vehicle("quad150").downwash_params
    assert -bf[0, 2] == pytest.approx(one.force_on_box(0.015, 0.1, thrust=w))
    assert -bf[0, 2] > 0.2 * 0.15 * G  # a carrier's own box: a fifth of its weight and more
    assert np.all(bf[1:] == 0.0) and np.all(f == 0.0)


@pytest.mark.parametrize("fraction", [0.2, 0.1])
def test_the_wake_column_ends_where_the_force_falls_to_the_fraction(fraction: float):
    p = load_vehicle("quad150")
    dw = p.downwash_params
    depth, width = dw.column(fraction, mass=p.mass, load=0.01)
    w = p.mass * G

    def force(dz: float, off: float = 0.0) -> float:
        return dw.force_on_vehicle(dz, upper_thrust=(p.mass + 0.01) * G, lower_thrust=w, offset=off)

    assert force(depth - 0.01) > fraction * w > force(depth + 0.01)
    assert depth > 0.3 and width > p.arm_length
    assert max(force(float(z), width + 0.01) for z in np.arange(0.01, depth, 0.01)) < fraction * w
    with pytest.raises(ValueError, match="fraction"):
        dw.column(1.5, mass=p.mass)


def test_vehicle_files_give_rotor_size_and_solidity_and_refuse_the_old_constants(tmp_path: Path):
    d = load_vehicle("quad150").downwash_params
    assert d == DownwashParams(rotor_radius=0.03175, arm_length=0.053, kf=1.088e-7, solidity=0.12)
    raw = yaml.safe_load((urdf_dir() / "quad150.yaml").read_text())
    (tmp_path / "quad150.urdf").write_text((urdf_dir() / "quad150.urdf").read_text())
    del raw["rotor_solidity"], raw["rotor_radius"]
    (tmp_path / "bare.yaml").write_text(yaml.safe_dump(raw))
    assert load_vehicle(tmp_path / "bare.yaml").downwash_params.rotor_radius == pytest.approx(0.6 * 0.053)
    raw["downwash_alpha"] = 2267.18  # the old empirical model's constants are gone
    (tmp_path / "old.yaml").write_text(yaml.safe_dump(raw))
    with pytest.raises(ConfigError, match="downwash_alpha"):
        load_vehicle(tmp_path / "old.yaml")
    del raw["downwash_alpha"]
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


@pytest.mark.parametrize(("vehicle", "d", "dz"), [("quad150", 0.05, 0.3), ("cf2x", 0.02, 0.3), ("cf2x", 0.0, 0.6)])
def test_a_vehicle_hovering_under_another_carries_the_predicted_downwash(vehicle, d, dz):
    """At rest the lower vehicle's thrust is its weight plus the wake's force (nothing else acts on it: no drag,
    no ground effect), and that force is the model's at the separation where it settled, for the two
    thrusts the vehicles have. After 25 s the slowest pole of the z loop (-2.2 rad/s, cf2x) has decayed by
    exp(-55): what is left of the transient is far below the tolerance."""
    p = load_vehicle(vehicle)
    dw = p.downwash_params
    sim, thrust = stacked(vehicle, d, dz, downwash=True)
    with sim:
        pos = sim.state.positions
        weight = p.mass * sim.scenario.sim.gravity
        assert thrust[1] == pytest.approx(weight, rel=1e-6)  # the upper vehicle is not affected
        sep_d = float(np.hypot(*(pos[1, :2] - pos[0, :2])))
        sep_dz = float(pos[1, 2] - pos[0, 2])
        predicted = dw.force_on_vehicle(sep_dz, upper_thrust=thrust[1], lower_thrust=thrust[0], offset=sep_d)
        assert predicted > 0.15 * weight  # a sizeable force: this is not a test of nothing
        assert thrust[0] - thrust[1] == pytest.approx(predicted, rel=2e-3)
        assert abs(sim.state.velocities[0, 2]) < 1e-4


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
