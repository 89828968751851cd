"""The paper's ORCA (``planning/orca/core.py``) against hand-computed cases, and the layer with every rule off.

Two agents head-on along x, 1 m apart, each flying 0.2 m/s towards the other; spheres of combined
radius R = 0.3 m; the relative velocity v = v_A - v_B = (0.4, 0, 0) m/s.

* Horizon tau = 2 s: the VO's cut-off sphere has centre p / tau = (0.5, 0, 0) and radius
  R / tau = 0.15; v lies 0.1 from its centre, inside, on the side towards the apex, so the way out
  is straight back: n = (-1, 0, 0), u = (-(0.15 - 0.1), 0, 0) = (-0.05, 0, 0). Each agent takes
  half: A may fly at most 0.175 m/s towards B, B likewise; then the gap of 0.7 m closes at
  0.35 m/s in exactly tau.
* Horizon tau = 10 s: p / tau = (0.1, 0, 0) is behind v, so the nearest boundary is the cone's
  side, at angle asin(R / d) = asin(0.3) from the line of centres: |u| = |v| R / d = 0.12 m/s, and
  with v on the line of centres the side is the agent's right (the core's convention):
  n = (-R / d, -sqrt(1 - (R / d)^2), 0) for A, heading +x (right = -y).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from pybullet_swarm.planning.orca import (
    FLAG_FREE,
    OrcaParams,
    Rule,
    Shape,
    bounding_boxes,
    neighbour_table,
    orca_plane,
    orca_velocities,
    solve_velocity,
)
from pybullet_swarm.planning.params import extensions
from pybullet_swarm.rng import named_rng

D = 1.0  # m, distance of the two centres
R = 0.3  # m, combined radius
S = 0.2  # m/s, each agent's speed towards the other
V_MAX = np.full(3, 0.5)  # m/s per axis
P_AB = np.array([D, 0.0, 0.0])  # B relative to A
V_A, V_B = np.array([S, 0.0, 0.0]), np.array([-S, 0.0, 0.0])


def _paper(**values: object) -> OrcaParams:
    """Every rule off, spheres without a safety margin: the paper's ORCA."""
    return OrcaParams.model_validate({"preset": "paper", "shape": "sphere", "safety_margin": 0.0, **values})


def test_head_on_inside_the_cut_off_sphere():
    n, point = orca_plane(
        P_AB, V_A - V_B, V_A, time_horizon=2.0, recovery_time=0.5, combined_radius=R, responsibility=0.5
    )
    assert n == pytest.approx([-1.0, 0.0, 0.0], abs=1e-15)
    u = 2.0 * (point - V_A)  # the whole way out; A's plane goes through v_A + u / 2
    assert u == pytest.approx([-0.05, 0.0, 0.0], abs=1e-15)
    assert point == pytest.approx([0.175, 0.0, 0.0], abs=1e-15)
    # B's plane is the mirror image: B gives up the other half
    n_b, point_b = orca_plane(-P_AB, V_B - V_A, V_B, time_horizon=2.0, recovery_time=0.5, combined_radius=R)
    assert n_b == pytest.approx(-n, abs=1e-15) and point_b == pytest.approx([-0.175, 0.0, 0.0], abs=1e-15)
    # the LP keeps as much of the preferred velocity as the plane allows
    v, feasible = solve_velocity(n[None, :], point[None, :], V_A, v_max=V_MAX)
    assert feasible and v == pytest.approx([0.175, 0.0, 0.0], abs=1e-12)
    # with both halves taken the pair touches exactly at the horizon
    assert (D - R) / (0.175 + 0.175) == pytest.approx(2.0)


def test_head_on_on_the_cone_side_turns_right():
    n, point = orca_plane(P_AB, V_A - V_B, V_A, time_horizon=10.0, recovery_time=0.5, combined_radius=R)
    sin_a = R / D
    assert n == pytest.approx([-sin_a, -math.sqrt(1.0 - sin_a**2), 0.0], abs=1e-12)
    u = 2.0 * (point - V_A)
    assert float(np.linalg.norm(u)) == pytest.approx(2 * S * sin_a, abs=1e-12)  # |v| sin(asin(R / d))
    assert u == pytest.approx(2 * S * sin_a * n, abs=1e-12)  # along the normal
    # the relative velocity v + u lies on the cone's side
    w = (V_A - V_B) + u
    assert np.linalg.norm(np.cross(P_AB, w)) / (D * np.linalg.norm(w)) == pytest.approx(sin_a, abs=1e-12)
    # the LP's answer for A is the plane's point (the preferred velocity projected onto the plane)
    v, feasible = solve_velocity(n[None, :], point[None, :], V_A, v_max=V_MAX)
    assert feasible
    assert v == pytest.approx([S - S * sin_a**2, -S * sin_a * math.sqrt(1.0 - sin_a**2), 0.0], abs=1e-12)


def test_outside_the_velocity_obstacle_the_plane_leaves_the_velocity_free():
    # slow enough that they would not touch within the horizon: u points inwards, v_A stays allowed
    n, point = orca_plane(
        P_AB, [0.2, 0.0, 0.0], [0.1, 0.0, 0.0], time_horizon=2.0, recovery_time=0.5, combined_radius=R
    )
    assert float(n @ (np.array([0.1, 0.0, 0.0]) - point)) > 0.0


def test_with_every_rule_off_the_layer_gives_the_hand_computed_velocities():
    pos = np.array([[0.0, 0.0, 1.0], [D, 0.0, 1.0]])
    vel = np.array([V_A, V_B])
    v, flags = orca_velocities(
        pos, vel, vel, params=_paper(time_horizon=2.0), sensing_radius=3.0, v_max=V_MAX, radii=np.full(2, R / 2)
    )
    assert v == pytest.approx(np.array([[0.175, 0.0, 0.0], [-0.175, 0.0, 0.0]]), abs=1e-12)
    assert not np.any(flags)
    v, _ = orca_velocities(
        pos, vel, vel, params=_paper(time_horizon=10.0), sensing_radius=3.0, v_max=V_MAX, radii=np.full(2, R / 2)
    )
    assert v[0, 1] < 0.0 < v[1, 1]  # each to its own right
    assert v[0] == pytest.approx(-v[1], abs=1e-15)


def test_without_minimal_intervention_a_free_agent_flies_the_lp_velocity():
    pos = np.array([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0]])  # out of each other's sensing radius
    pref = np.array([[0.6, 0.0, 0.0], [0.1, 0.0, 0.0]])
    common = dict(sensing_radius=1.0, v_max=V_MAX, radii=np.full(2, 0.1))
    v, flags = orca_velocities(pos, np.zeros((2, 3)), pref, params=_paper(), **common)
    assert not np.any(flags & FLAG_FREE)
    assert v == pytest.approx(np.array([[0.5, 0.0, 0.0], [0.1, 0.0, 0.0]]))  # clipped to the limits by the LP
    # the rule keeps a command that violates nothing (agent 1), not one beyond the limits (agent 0)
    v, flags = orca_velocities(pos, np.zeros((2, 3)), pref, params=_paper(minimal_intervention=True), **common)
    assert list(flags & FLAG_FREE) == [0, FLAG_FREE]


@pytest.mark.parametrize("shape", [Shape.SPHERE, Shape.BOX])
def test_with_every_rule_off_the_kernel_is_planes_and_lp_of_the_core(shape: Shape):
    """For random crowds, the compiled tick with every rule off equals one ``orca_plane`` per neighbour
    (reciprocal halves, the nearest way out) and one ``solve_velocity`` per agent."""
    rng = named_rng(0, "test_orca_core")
    n = 12
    params = OrcaParams.model_validate({"preset": "paper", "shape": shape.value})
    for _ in range(20):
        pos = rng.uniform([0.0, 0.0, 0.5], [1.5, 1.5, 1.5], size=(n, 3))
        vel = rng.uniform(-0.4, 0.4, size=(n, 3))
        pref = rng.uniform(-0.6, 0.6, size=(n, 3))
        quat = rng.normal(size=(n, 4)) * [0.05, 0.05, 0.3, 1.0]
        quat /= np.linalg.norm(quat, axis=1, keepdims=True)
        centre, half = bounding_boxes(quat, np.array([0.075, 0.075, 0.01]), rng.uniform(size=n) < 0.5, 0.1, 0.065)
        radii = rng.uniform(0.08, 0.15, size=n)
        nbr = neighbour_table(pos, 1.0, params.max_neighbours)
        v, _ = orca_velocities(
            pos,
            vel,
            pref,
            params=params,
            sensing_radius=1.0,
            v_max=V_MAX,
            radii=radii,
            boxes=(centre, half),
            neighbours=nbr,
        )
        m2 = 2.0 * params.margin
        for i in range(n):
            normals, points = [], []
            for j in nbr[i][nbr[i] >= 0]:
                common: dict[str, Any] = dict(time_horizon=params.time_horizon, recovery_time=params.recovery_time)
                if shape is Shape.SPHERE:
                    plane = orca_plane(
                        pos[j] - pos[i], vel[i] - vel[j], vel[i], combined_radius=radii[i] + radii[j] + m2, **common
                    )
                else:
                    plane = orca_plane(
                        (pos[j] + centre[j]) - (pos[i] + centre[i]),
                        vel[i] - vel[j],
                        vel[i],
                        half_extents=half[i] + half[j] + m2,
                        **common,
                    )
                normals.append(plane[0])
                points.append(plane[1])
            expected, _ = solve_velocity(np.array(normals), np.array(points), pref[i], v_max=V_MAX)
            assert v[i] == pytest.approx(expected, abs=1e-9)


def test_the_paper_preset_switches_every_rule_off_and_nothing_else():
    paper = OrcaParams.model_validate({"preset": "paper"})
    assert paper.rules == ()
    assert list(extensions(OrcaParams, "paper")) == [r.value for r in Rule]
    assert OrcaParams().rules == tuple(Rule)
    assert OrcaParams.model_validate({"preset": "paper", "lag_margin": True}).rules == (Rule.LAG_MARGIN,)


def test_every_kernel_is_cached_with_the_whole_package_as_its_stamp():
    """A kernel inlines code of the package's other files, so an edit of any of them must recompile it."""
    from pybullet_swarm.planning.orca import cache, core, kernel, rules

    files = {p.name for p in cache._PACKAGE.glob("*.py")}
    assert {"core.py", "rules.py", "kernel.py", "vec.py"} <= files
    for fn in (kernel.orca_batch, core.solve, rules.clear_paths):
        stamp = fn._cache._impl.locator.get_source_stamp()
        assert {name for name, *_ in stamp[1]} == files
