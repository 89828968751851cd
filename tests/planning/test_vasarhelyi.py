"""Each term of the vasarhelyi planner against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pybullet_swarm.planning.base import Observation, TaskInfo
from pybullet_swarm.planning.views.route import FlockLayout
from pybullet_swarm.planning.vasarhelyi import (
    VasarhelyiParams,
    VasarhelyiPlanner,
    alignment,
    braking_curve,
    repulsion,
    shill,
)


def test_braking_curve_pieces() -> None:
    # a = 1 m/s^2, p = 2 1/s: linear while r p < a / p = 0.5 (r < 0.25 m), then sqrt(2 a r - a^2 / p^2)
    d = braking_curve(np.array([-1.0, 0.0, 0.1, 0.25, 1.0]), 1.0, 2.0)
    assert d.tolist() == pytest.approx([0.0, 0.0, 0.2, 0.5, math.sqrt(1.75)])


def test_repulsion_is_a_half_spring() -> None:
    nb = np.array([[1.0, 0.0], [0.0, 3.0]])  # the second is beyond r0_rep
    assert repulsion(np.zeros(2), nb, 2.0, 0.5).tolist() == pytest.approx([-0.5, 0.0])


def test_alignment_acts_beyond_the_velocity_slack() -> None:
    kw = dict(r0_frict=5.0, c_frict=0.5, v_frict=0.2, p_frict=2.0, a_frict=1.0)
    v = alignment(np.zeros(2), np.array([[1.0, 0.0]]), np.array([1.0]), **kw)
    assert v.tolist() == pytest.approx([0.5 * (1.0 - 0.2), 0.0])
    # 1 m beyond r0_frict the braking curve allows sqrt(1.75) m/s > 1 m/s of difference: no term
    kw["r0_frict"] = 0.0
    assert alignment(np.zeros(2), np.array([[1.0, 0.0]]), np.array([1.0]), **kw).tolist() == [0.0, 0.0]


def test_shill_brakes_towards_the_wall() -> None:
    # 1 m from the wall x = 0 flying at it at 1 m/s; the shill agent moves inwards at 0.5 m/s
    kw = dict(r0_shill=1.0, v_shill=0.5, p_shill=2.0, a_shill=1.0)
    v = shill(
        np.array([1.0, 0.0]),
        np.array([-1.0, 0.0]),
        np.array([[0.0, 0.0]]),
        np.array([[1.0, 0.0]]),
        np.array([1.0]),
        **kw,
    )
    assert v.tolist() == pytest.approx([1.5, 0.0])  # (v_is - D(0)) (v_s - v_i) / v_is
    kw["r0_shill"] = 0.0  # 1 m of braking room allows sqrt(1.75) m/s of the 1.5 m/s
    v = shill(
        np.array([1.0, 0.0]),
        np.array([-1.0, 0.0]),
        np.array([[0.0, 0.0]]),
        np.array([[1.0, 0.0]]),
        np.array([1.0]),
        **kw,
    )
    assert v.tolist() == pytest.approx([1.5 - math.sqrt(1.75), 0.0])
    v = shill(
        np.array([1.0, 0.0]),
        np.array([-0.5, 0.0]),
        np.array([[0.0, 0.0]]),
        np.array([[1.0, 0.0]]),
        np.array([1.0]),
        **kw,
    )
    assert v.tolist() == [0.0, 0.0]  # 1 m/s relative: within what the braking curve allows


def _obs(
    position: list[float], velocity: list[float], nb_p: list[list[float]] = [], nb_v: list[list[float]] = []
) -> Observation:
    k = len(nb_p)
    return Observation(
        0,
        10.0,
        np.array(position, float),
        np.array(velocity, float),
        0.0,
        -1,
        np.arange(k),
        np.array(nb_p, float).reshape(k, 3),
        np.array(nb_v, float).reshape(k, 3),
        None,  # a flock has no objects to see
    )


def _planner(**params: float) -> VasarhelyiPlanner:
    pl = VasarhelyiPlanner(VasarhelyiParams(**params))
    info = TaskInfo(
        arena_size=np.array([1000.0, 1000.0]),
        n_agents=2,
        agent_radius=0.1,
        v_max=np.full(3, 5.0),
        layout=FlockLayout(
            route=np.zeros((0, 3)),
            pass_radius=0.3,
            circuit=(500.0, 500.0, 250.0),
            altitude=1.0,
            v_flock=0.5,
            r_coll=0.3,
            connection_range_m=5.0,
        ),
    )
    pl.reset(0, np.random.default_rng(0), info)
    return pl


def test_alone_in_the_middle_it_self_propels_at_v_flock() -> None:
    v = _planner().velocity(_obs([500.0, 500.0, 1.0], [0.3, 0.0, 0.0]))
    assert v.tolist() == pytest.approx([0.5, 0.0, 0.0])


def test_sum_of_terms_is_cut_to_v_max() -> None:
    pl = _planner(r0_rep=2.0, p_rep=10.0, v_max=1.0)
    v = pl.velocity(_obs([500.0, 500.0, 1.0], [0.3, 0.0, 0.0], [[500.5, 500.0, 1.0]], [[0.3, 0.0, 0.0]]))
    # propulsion 0.5 forwards, repulsion 10 (2 - 0.5) = 15 backwards: cut to 1 m/s, backwards
    assert v.tolist() == pytest.approx([-1.0, 0.0, 0.0])


def test_takes_off_before_flocking() -> None:
    v = _planner().velocity(_obs([500.0, 500.0, 0.1], [0.0, 0.0, 0.0]))
    assert v[:2].tolist() == [0.0, 0.0] and v[2] == pytest.approx(0.9)
