"""The olfati_saber planner's functions against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pybullet_swarm.planning.base import Observation, TaskInfo
from pybullet_swarm.planning.views.route import FlockLayout
from pybullet_swarm.planning.olfati_saber import (
    OlfatiSaberParams,
    OlfatiSaberPlanner,
    bump,
    phi,
    phi_alpha,
    phi_beta,
    pillar_beta,
    sigma_grad,
    sigma_norm,
    sigma_norm_of,
    wall_beta,
)


def test_sigma_norm_and_its_gradient() -> None:
    z = np.array([3.0, 4.0])
    assert float(sigma_norm(z, 0.1)) == pytest.approx((math.sqrt(3.5) - 1.0) / 0.1)
    assert sigma_grad(z, 0.1).tolist() == pytest.approx((z / math.sqrt(3.5)).tolist())


def test_bump_function() -> None:
    assert bump(np.array([0.1, 0.6, 1.0, 1.2, -0.1]), 0.2).tolist() == pytest.approx([1.0, 0.5, 0.0, 0.0, 0.0])


def test_phi_and_the_lattice_equilibrium() -> None:
    assert float(phi(0.0, 5.0, 5.0)) == pytest.approx(0.0)  # a = b: c = 0, phi(0) = 0
    assert float(phi(1.0, 5.0, 5.0)) == pytest.approx(5.0 / math.sqrt(2.0))
    d_a, r_a = sigma_norm_of(2.5, 0.1), sigma_norm_of(3.0, 0.1)
    assert float(phi_alpha(np.array(d_a), r_a, d_a, 5.0, 5.0, 0.2)) == pytest.approx(0.0)
    assert float(phi_alpha(np.array(r_a + 0.1), r_a, d_a, 5.0, 5.0, 0.2)) == 0.0  # beyond the range
    assert float(phi_beta(np.array(0.0), 1.0, 0.9)) == pytest.approx(-1.0 - 1.0 / math.sqrt(2.0))


def test_beta_agents_of_a_wall_and_a_pillar() -> None:
    qh, ph = wall_beta(np.array([1.0, 2.0]), np.array([1.0, 1.0]), np.array([0.0, 2.0]), np.array([1.0, 0.0]))
    assert qh.tolist() == pytest.approx([0.0, 2.0]) and ph.tolist() == pytest.approx([0.0, 1.0])
    qh, ph = pillar_beta(np.array([2.0, 0.0]), np.array([1.0, 1.0]), np.zeros(2), 1.0)
    assert qh.tolist() == pytest.approx([1.0, 0.0]) and ph.tolist() == pytest.approx([0.0, 0.5])


def _planner() -> OlfatiSaberPlanner:
    pl = OlfatiSaberPlanner(OlfatiSaberParams())
    info = TaskInfo(
        arena_size=np.array([100.0, 100.0]),
        n_agents=1,
        agent_radius=0.1,
        v_max=np.full(3, 5.0),
        layout=FlockLayout(
            route=np.zeros((0, 3)),
            pass_radius=0.3,
            circuit=(50.0, 50.0, 10.0),
            altitude=1.0,
            v_flock=0.5,
            r_coll=0.3,
            connection_range_m=5.0,
        ),
    )
    pl.reset(0, np.random.default_rng(0), info)
    return pl


def _obs(t: float, p: list[float], v: list[float]) -> Observation:
    e3, e = np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    return Observation(0, t, np.array(p, float), np.array(v, float), 0.0, -1, e, e3, e3, None)


def test_on_the_virtual_leader_the_input_is_zero() -> None:
    pl = _planner()
    q, p = pl.leader(0.0)
    assert q.tolist() == pytest.approx([60.0, 50.0]) and p.tolist() == pytest.approx([0.0, 0.5])
    assert pl.control(_obs(0.0, [60.0, 50.0, 1.0], [0.0, 0.5, 0.0])).tolist() == pytest.approx([0.0, 0.0])


def test_gamma_term_pulls_towards_the_leader() -> None:
    pl = _planner()
    p = OlfatiSaberParams()
    u = pl.control(_obs(0.0, [59.0, 50.0, 1.0], [0.0, 0.0, 0.0]))
    assert u.tolist() == pytest.approx([p.c1_gamma * 1.0, p.c2_gamma * 0.5])
