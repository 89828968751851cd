"""Olfati-Saber's flocking algorithms (IEEE TAC 2006, "Flocking for multi-agent dynamic systems: algorithms
and theory"), algorithm 2 (alpha agents and a gamma agent) with algorithm 3's beta agents, decentralised
in the horizontal plane.

Agent i's control input (an acceleration) is ``u_i = u_alpha + u_beta + u_gamma``:

* ``u_alpha = c1_alpha sum_j phi_alpha(||q_j - q_i||_sigma) n_ij + c2_alpha sum_j a_ij (p_j - p_i)`` over the
  neighbours within ``r`` (gradient of the lattice potential and velocity consensus);
* ``u_beta = c1_beta sum_k phi_beta(||qh_k - q_i||_sigma) nh_ik + c2_beta sum_k b_ik (ph_k - p_i)`` over the
  beta agents within ``r_beta``: the projection qh_k of the agent on each wall and pillar, moving with
  ph_k (the agent's velocity projected on the wall; scaled by mu = R / |q - y| and projected for a pillar);
* ``u_gamma = -c1_gamma (q_i - q_r) - c2_gamma (p_i - p_r)`` towards the virtual leader (q_r, p_r).

with the sigma-norm ``||z||_sigma = (sqrt(1 + eps |z|^2) - 1) / eps``, its gradient ``n_ij =
sigma_eps(q_j - q_i) = (q_j - q_i) / sqrt(1 + eps |q_j - q_i|^2)``, the bump function ``rho_h(z)`` (1 on
[0, h), ``(1 + cos(pi (z - h) / (1 - h))) / 2`` on [h, 1], 0 beyond), ``phi(z) = ((a + b) sigma_1(z + c) +
(a - b)) / 2`` with ``sigma_1(z) = z / sqrt(1 + z^2)`` and ``c = |a - b| / sqrt(4 a b)``,
``phi_alpha(z) = rho_h(z / r_alpha) phi(z - d_alpha)``, ``a_ij = rho_h(||q_j - q_i||_sigma / r_alpha)``,
``phi_beta(z) = rho_h(z / d_beta) (sigma_1(z - d_beta) - 1)`` and ``b_ik = rho_h(||qh_k - q_i||_sigma /
d_beta)``; r_alpha, d_alpha, d_beta are the sigma-norms of r, d, d_beta.

Defaults are the paper's constants (a = b = 5, h = 0.2 for alpha and 0.9 for beta, eps = 0.1,
r = 1.2 d, d_beta = 0.6 d, r_beta = 1.2 d_beta) with the lattice spacing d scaled to our arena
(2.5 m instead of 7 m); the gains are ours (c2 = 2 sqrt(c1) for each pair), see
docs/science/flocking.md.

The virtual leader flies the task's circuit (``FlockLayout.circuit``: centre and radius m)
at v_flock; every agent computes it from the time alone. Velocity commands integrate the input
over the planner period, ``v_cmd = v_i + u_i dt``, cut to ``v_max``. Altitude is held as in
``vasarhelyi``.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.planning.arena import ArenaGeometry, altitude_velocity, cap_speed, flight_limits
from pybullet_swarm.planning.base import Command, Observation
from pybullet_swarm.planning.views.route import FlockInfo
from pybullet_swarm.planning.params import Params
from pybullet_swarm.planning.reynolds import scale_to_limits

#: s, planner period assumed at the first tick (later: the time between ticks)
FIRST_DT = 0.1


def sigma_norm(z: NDArray[np.float64], eps: float) -> NDArray[np.float64]:
    """||z||_sigma (...,) of vectors z (..., d): (sqrt(1 + eps |z|^2) - 1) / eps."""
    z = np.asarray(z, dtype=float)
    return (np.sqrt(1.0 + eps * np.sum(z * z, axis=-1)) - 1.0) / eps


def sigma_norm_of(x: float, eps: float) -> float:
    """The sigma-norm of a length x."""
    return (math.sqrt(1.0 + eps * x * x) - 1.0) / eps


def sigma_grad(z: NDArray[np.float64], eps: float) -> NDArray[np.float64]:
    """sigma_eps(z) (..., d) = z / sqrt(1 + eps |z|^2), the gradient of the sigma-norm."""
    z = np.asarray(z, dtype=float)
    return z / np.sqrt(1.0 + eps * np.sum(z * z, axis=-1, keepdims=True))


def bump(z: NDArray[np.float64] | float, h: float) -> NDArray[np.float64]:
    """rho_h(z): 1 on [0, h), (1 + cos(pi (z - h) / (1 - h))) / 2 on [h, 1], 0 elsewhere."""
    z = np.asarray(z, dtype=float)
    mid = 0.5 * (1.0 + np.cos(np.pi * (z - h) / (1.0 - h)))
    return np.where((z >= 0.0) & (z < h), 1.0, np.where((z >= h) & (z <= 1.0), mid, 0.0))


def sigma_1(z: NDArray[np.float64] | float) -> NDArray[np.float64]:
    """z / sqrt(1 + z^2)."""
    z = np.asarray(z, dtype=float)
    return z / np.sqrt(1.0 + z * z)


def phi(z: NDArray[np.float64] | float, a: float, b: float) -> NDArray[np.float64]:
    """The uneven sigmoid ((a + b) sigma_1(z + c) + (a - b)) / 2, c = |a - b| / sqrt(4 a b)."""
    c = abs(a - b) / math.sqrt(4.0 * a * b)
    return 0.5 * ((a + b) * sigma_1(np.asarray(z, dtype=float) + c) + (a - b))


def phi_alpha(
    z: NDArray[np.float64], r_alpha: float, d_alpha: float, a: float, b: float, h: float
) -> NDArray[np.float64]:
    """rho_h(z / r_alpha) phi(z - d_alpha) of sigma-distances z."""
    return bump(np.asarray(z, dtype=float) / r_alpha, h) * phi(np.asarray(z, dtype=float) - d_alpha, a, b)


def phi_beta(z: NDArray[np.float64], d_beta: float, h: float) -> NDArray[np.float64]:
    """rho_h(z / d_beta) (sigma_1(z - d_beta) - 1) of sigma-distances z (repulsive only)."""
    z = np.asarray(z, dtype=float)
    return bump(z / d_beta, h) * (sigma_1(z - d_beta) - 1.0)


def wall_beta(
    q: NDArray[np.float64], p: NDArray[np.float64], point: NDArray[np.float64], normal: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Beta agent (position, velocity) of a wall through ``point`` with unit ``normal``: P q + (I - P) y, P p."""
    proj = np.eye(len(q)) - np.outer(normal, normal)
    return proj @ q + (np.eye(len(q)) - proj) @ point, proj @ p


def pillar_beta(
    q: NDArray[np.float64], p: NDArray[np.float64], centre: NDArray[np.float64], radius: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Beta agent (position, velocity) of a round obstacle: mu q + (1 - mu) y, mu P p, mu = R / |q - y|."""
    d = q - centre
    dist = float(np.linalg.norm(d))
    if dist < 1e-9:
        return centre.copy(), np.zeros_like(p)
    mu = radius / dist
    a = d / dist
    return mu * q + (1.0 - mu) * centre, mu * ((np.eye(len(q)) - np.outer(a, a)) @ p)


class OlfatiSaberParams(Params):
    """Parameters of the ``olfati_saber`` planner (scenario ``planner.params``); the paper's names."""

    a: float = Field(5.0, gt=0.0, le=1e3, description="phi's gain on the attractive side (paper: 5)")
    b: float = Field(5.0, gt=0.0, le=1e3, description="phi's gain on the repulsive side (paper: 5)")
    h_alpha: float = Field(0.2, ge=0.0, lt=1.0, description="bump function's plateau for alpha agents (paper: 0.2)")
    h_beta: float = Field(0.9, ge=0.0, lt=1.0, description="bump function's plateau for beta agents (paper: 0.9)")
    epsilon: float = Field(0.1, gt=0.0, le=10.0, description="sigma-norm's parameter (paper: 0.1)")
    d: float = Field(2.5, gt=0.0, le=1e3, description="m, lattice spacing (paper: 7 m on an open plane)")
    r: float | None = Field(None, gt=0.0, le=1e3, description="m, interaction range (null: 1.2 d, the paper's kappa)")
    d_beta: float | None = Field(None, gt=0.0, le=1e3, description="m, distance kept from obstacles (null: 0.6 d)")
    r_beta: float | None = Field(None, gt=0.0, le=1e3, description="m, obstacles' range (null: 1.2 d_beta)")
    c1_alpha: float = Field(0.3, ge=0.0, le=100.0, description="gain of the lattice gradient, 1/s^2 per sigma-unit")
    c2_alpha: float = Field(1.1, ge=0.0, le=100.0, description="1/s, gain of the velocity consensus")
    c1_beta: float = Field(1.5, ge=0.0, le=100.0, description="gain of the obstacles' gradient")
    c2_beta: float = Field(2.45, ge=0.0, le=100.0, description="1/s, gain of the obstacles' velocity term")
    c1_gamma: float = Field(0.05, ge=0.0, le=100.0, description="1/s^2, pull towards the virtual leader")
    c2_gamma: float = Field(0.45, ge=0.0, le=100.0, description="1/s, velocity matching with the virtual leader")
    v_flock: float | None = Field(
        None, gt=0.0, le=100.0, description="m/s, the virtual leader's speed (null: the task's v_flock, else 0.6)"
    )
    v_max: float | None = Field(None, gt=0.0, le=100.0, description="m/s, commands are cut to this (null: 4/3 v_flock)")
    altitude_gain: float = Field(1.0, ge=0.0, le=100.0, description="1/s, pull towards the flight altitude")


class OlfatiSaberPlanner:
    """Decentralised Olfati-Saber flocking (algorithms 2 and 3) in a walled arena with pillars.

    Args:
        params: validated ``OlfatiSaberParams`` (default: the defaults).
    """

    name: ClassVar[str] = "olfati_saber"
    centralized: ClassVar[bool] = False
    Params: ClassVar[type[OlfatiSaberParams]] = OlfatiSaberParams

    def __init__(self, params: OlfatiSaberParams | None = None) -> None:
        self.params = params if params is not None else OlfatiSaberParams()

    def reset(self, agent_id: int, rng: np.random.Generator, info: FlockInfo) -> None:
        """Start a run as agent ``agent_id``: the arena, the leader's circuit and the sigma-distances."""
        p = self.params
        self.agent_id = agent_id
        self.arena = ArenaGeometry.from_info(info)
        self.v_flock, self.v_cap, self.altitude, self.axis_limits = flight_limits(info, p.v_flock, p.v_max)
        cx, cy, radius = info.layout.circuit
        self.centre = np.array([cx, cy], dtype=float)
        self.radius = float(radius)
        r = p.r if p.r is not None else 1.2 * p.d
        d_beta = p.d_beta if p.d_beta is not None else 0.6 * p.d
        self.r = float(r)
        self.r_beta = float(p.r_beta if p.r_beta is not None else 1.2 * d_beta)
        self.r_alpha = sigma_norm_of(r, p.epsilon)
        self.d_alpha = sigma_norm_of(p.d, p.epsilon)
        self.d_beta_sigma = sigma_norm_of(d_beta, p.epsilon)
        self.last_t: float | None = None

    def leader(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The virtual leader's position (2,) m and velocity (2,) m/s at time t s (anticlockwise circuit)."""
        w = self.v_flock / self.radius
        c, s = math.cos(w * t), math.sin(w * t)
        return self.centre + self.radius * np.array([c, s]), self.v_flock * np.array([-s, c])

    def beta_agents(
        self, q: NDArray[np.float64], v: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Positions (m, 2) m and velocities (m, 2) m/s of the beta agents within r_beta of the agent."""
        qs, ps = [], []
        points, normals, dist = self.arena.walls(q)
        for k in np.nonzero(dist < self.r_beta)[0]:
            qh, ph = wall_beta(q, v, points[k], normals[k])
            qs.append(qh)
            ps.append(ph)
        _, _, pdist = self.arena.pillar_points(q)
        for k in np.nonzero(pdist < self.r_beta)[0]:
            qh, ph = pillar_beta(q, v, self.arena.pillars[k, :2], float(self.arena.pillars[k, 2]))
            qs.append(qh)
            ps.append(ph)
        if not qs:
            return np.zeros((0, 2)), np.zeros((0, 2))
        return np.array(qs), np.array(ps)

    def control(self, obs: Observation) -> NDArray[np.float64]:
        """The input u_i (2,) m/s^2 = u_alpha + u_beta + u_gamma."""
        p = self.params
        q, v = obs.position[:2], obs.velocity[:2]
        u = np.zeros(2)
        nb_q, nb_v = obs.neighbour_positions[:, :2], obs.neighbour_velocities[:, :2]
        if len(nb_q):
            dq = nb_q - q[None]
            near = np.linalg.norm(dq, axis=1) < self.r
            dq, dv = dq[near], nb_v[near] - v[None]
            z = sigma_norm(dq, p.epsilon)
            u += p.c1_alpha * phi_alpha(z, self.r_alpha, self.d_alpha, p.a, p.b, p.h_alpha) @ sigma_grad(dq, p.epsilon)
            u += p.c2_alpha * bump(z / self.r_alpha, p.h_alpha) @ dv
        qh, ph = self.beta_agents(q, v)
        if len(qh):
            dq = qh - q[None]
            z = sigma_norm(dq, p.epsilon)
            u += p.c1_beta * phi_beta(z, self.d_beta_sigma, p.h_beta) @ sigma_grad(dq, p.epsilon)
            u += p.c2_beta * bump(z / self.d_beta_sigma, p.h_beta) @ (ph - v[None])
        q_r, p_r = self.leader(obs.time_s)
        u += -p.c1_gamma * (q - q_r) - p.c2_gamma * (v - p_r)
        return u

    def velocity(self, obs: Observation) -> NDArray[np.float64]:
        """The commanded velocity (3,) m/s: v + u dt horizontally (cut to v_max), altitude hold vertically."""
        dt = FIRST_DT if self.last_t is None else max(obs.time_s - self.last_t, 1e-3)
        self.last_t = obs.time_s
        out = np.zeros(3)
        out[2] = altitude_velocity(float(obs.position[2]), self.altitude, self.params.altitude_gain)
        if obs.position[2] >= 0.5 * self.altitude:  # below it: taking off, climb first
            out[:2] = cap_speed(obs.velocity[:2] + self.control(obs) * dt, self.v_cap)
        return scale_to_limits(out, self.axis_limits)

    def plan(self, obs: Observation, medium: Any | None) -> Command:
        """A VELOCITY command."""
        return Command.velocity(self.velocity(obs))


from pybullet_swarm.planning.registry import register_planner  # noqa: E402

register_planner(
    "olfati_saber",
    OlfatiSaberPlanner,
    "decentralised flocking of Olfati-Saber 2006 (algorithms 2 and 3): sigma-norm lattice, velocity "
    "consensus, a virtual leader on the task's circuit, beta agents at walls and pillars",
    ("flock",),
)
