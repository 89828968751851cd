"""World-frame wrenches on a steeply tilted body against the closed form of one Bullet step.

PyBullet's ``applyExternalForce``/``applyExternalTorque`` take a frame flag, and whether a force
or torque is read in the link frame or the world frame has changed between versions. Near hover
both frames nearly agree, so only a body held far from level tells them apart.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pybullet_swarm.control.rotations import quat_to_matrix
from pybullet_swarm.vehicle import load_vehicle
from pybullet_swarm.world.world import World

H = 1.0 / 240.0  # s, physics period
G = 9.81  # m/s^2


def _quat(axis: np.ndarray, angle: float) -> np.ndarray:
    """Quaternion (x, y, z, w) of a rotation by ``angle`` rad about ``axis``."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.append(a * math.sin(angle / 2), math.cos(angle / 2))


def _quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    (x1, y1, z1, w1), (x2, y2, z2, w2) = p, q
    return np.array(
        [
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        ]
    )


def _one_step(vehicle: str, quat: np.ndarray, force: np.ndarray, torque: np.ndarray) -> tuple[np.ndarray, ...]:
    """Velocity (3,) m/s and angular velocity (3,) rad/s after one step of a body at rest, and R (3, 3)."""
    p = load_vehicle(vehicle)
    with World(physics_hz=1 / H, gravity=G) as world:
        world.add_agents(p.urdf_path, np.array([[0.0, 0.0, 5.0]]), mass=p.mass, inertia=p.inertia)
        world.reset_agent(0, (0.0, 0.0, 5.0), tuple(quat))
        state = np.zeros((1, 13))
        world.read_agent_states(state)  # the force acts at the centre of mass read here
        rot = quat_to_matrix(state[:, 3:7])[0]
        world.apply_agent_wrenches(force.reshape(1, 3), torque.reshape(1, 3))
        world.step()
        world.read_agent_states(state)
    return state[0, 7:10], state[0, 10:13], rot


@pytest.mark.parametrize("vehicle", ["quad150", "cf2x"])
@pytest.mark.parametrize("tilt_deg", [60.0, 75.0, 120.0])
def test_world_frame_wrench_on_a_tilted_body_follows_the_closed_form(vehicle: str, tilt_deg: float) -> None:
    p = load_vehicle(vehicle)
    # tilted by tilt_deg about a horizontal axis between x and y, then yawed by 30 deg
    quat = _quat_mul(_quat([0, 0, 1], math.radians(30.0)), _quat([1, 2, 0], math.radians(tilt_deg)))
    weight = p.mass * G
    force = weight * np.array([0.4, -0.3, 1.5])  # N, world frame
    torque = 1e-3 * np.array([0.6, -1.1, 0.4]) * p.inertia[0] / 3.0e-4  # N m, world frame
    vel, omega, rot = _one_step(vehicle, quat, force, torque)
    assert math.degrees(math.acos(rot[2, 2])) == pytest.approx(tilt_deg, abs=1e-6)  # held that far over

    # semi-implicit Euler from rest: v = (F / m - g z) h; w = I_world^-1 tau h, I_world = R J R^T
    expected_v = (force / p.mass - np.array([0.0, 0.0, G])) * H
    inertia_world = rot @ np.diag(p.inertia) @ rot.T
    expected_w = np.linalg.solve(inertia_world, torque) * H
    np.testing.assert_allclose(vel, expected_v, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(omega, expected_w, rtol=1e-6, atol=1e-12)

    # the check has teeth: the same vectors read in the body frame give other motions
    link_v = (rot @ force / p.mass - np.array([0.0, 0.0, G])) * H
    link_w = np.linalg.solve(inertia_world, rot @ torque) * H
    assert np.linalg.norm(link_v - expected_v) > 0.3 * np.linalg.norm(expected_v)
    assert np.linalg.norm(link_w - expected_w) > 0.3 * np.linalg.norm(expected_w)


def test_thrust_along_the_tilted_body_axis_accelerates_along_it() -> None:
    """The simulation's own wrench: thrust T along body z at 60 deg tilt gives (T/m) R e_z - g z."""
    p = load_vehicle("quad150")
    quat = _quat([1, 0, 0], math.radians(60.0))
    thrust = 2.0 * p.mass * G  # N, the vehicle's maximum
    rot = quat_to_matrix(quat.reshape(1, 4))[0]
    vel, omega, _ = _one_step("quad150", quat, thrust * rot[:, 2], np.zeros(3))
    accel = vel / H
    np.testing.assert_allclose(accel, thrust / p.mass * rot[:, 2] - [0.0, 0.0, G], rtol=1e-9, atol=1e-9)
    # at 60 deg, half of the thrust holds the weight: no vertical acceleration, 2 g * sin 60 sideways
    assert accel[2] == pytest.approx(0.0, abs=1e-9)
    assert np.hypot(accel[0], accel[1]) == pytest.approx(2.0 * G * math.sin(math.radians(60.0)), rel=1e-9)
    np.testing.assert_allclose(omega, 0.0, atol=1e-12)  # applied at the centre of mass: no torque
