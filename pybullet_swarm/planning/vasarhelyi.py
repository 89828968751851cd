"""Vásárhelyi et al.'s flocking model (Science Robotics 2018, "Optimized flocking of autonomous drones
in confined environments"), decentralised, in the horizontal plane.

Each agent i (its own ``Observation`` only: own state and the neighbours it hears) commands the
desired velocity

    v_d = v_flock v_i / |v_i| + sum_j v_rep_ij + sum_j v_frict_ij + sum_s v_shill_is

cut to ``v_max`` (direction kept), where, with r_ij = |p_i - p_j| and v_ij = |v_i - v_j|:

* self-propulsion at the preferred speed ``v_flock`` along the agent's own velocity;
* repulsion, a half spring: ``v_rep_ij = p_rep (r0_rep - r_ij) (p_i - p_j) / r_ij`` for r_ij < r0_rep;
* alignment (velocity "friction"): ``v_frict_ij = C_frict (v_ij - v_frictmax_ij) (v_j - v_i) / v_ij``
  where ``v_ij > v_frictmax_ij = max(v_frict, D(r_ij - r0_frict, a_frict, p_frict))``: neighbours may
  differ in velocity by as much as a braking curve allows at their distance;
* shill agents: every wall and pillar is replaced by a virtual agent s at its nearest point,
  moving at ``v_shill`` away from the obstacle (into the arena), and
  ``v_shill_is = (v_is - v_shillmax_is) (v_s - v_i) / v_is`` where ``v_is > v_shillmax_is =
  D(r_is - r0_shill, a_shill, p_shill)``: the agent slows to a stop at the wall at most as the
  braking curve allows.

The braking curve ``D(r, a, p)`` is 0 for r <= 0, ``r p`` while ``r p < a / p`` and
``sqrt(2 a r - a^2 / p^2)`` beyond: the speed from which an agent can still stop within r,
braking with gain p up close and at acceleration a further away. The eleven parameters are the
paper's names; their defaults are the paper's optimised set for v_flock = 6 m/s with every length
and speed multiplied by 0.1 (gains in 1/s unchanged, accelerations x 0.1; docs/science/flocking.md).

The model is horizontal; altitude is held at the task's ``flock_altitude`` by ``altitude_gain``,
and an agent below half of it climbs before any horizontal term acts. Acceleration is limited by
the reference shaper (``limits.acceleration``) and each axis by ``limits.velocity``.

Named heuristic (start heading): an agent slower than ``MIN_SPEED`` has no direction to propel
along, and propels along a heading drawn once from its own generator.
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

#: m/s, an agent slower than this propels along its start heading
MIN_SPEED = 0.02


def braking_curve(r: NDArray[np.float64] | float, a: float, p: float) -> NDArray[np.float64]:
    """D(r, a, p) m/s of distances r m: 0 for r <= 0, r p up to r p = a / p, sqrt(2 a r - a^2 / p^2) beyond."""
    r = np.asarray(r, dtype=float)
    lin = r * p
    sq = np.sqrt(np.maximum(2.0 * a * r - (a / p) ** 2, 0.0))
    return np.where(r <= 0.0, 0.0, np.where(lin < a / p, lin, sq))


def repulsion(
    position: NDArray[np.float64], neighbours: NDArray[np.float64], r0_rep: float, p_rep: float
) -> NDArray[np.float64]:
    """Sum (d,) m/s of p_rep (r0_rep - r_ij) (p_i - p_j) / r_ij over neighbours (k, d) m closer than r0_rep."""
    d = np.asarray(position, dtype=float)[None] - np.asarray(neighbours, dtype=float)
    r = np.linalg.norm(d, axis=1)
    near = (r < r0_rep) & (r > 1e-9)
    return (p_rep * (r0_rep - r[near]) / r[near]) @ d[near] if np.any(near) else np.zeros(d.shape[1])


def _excess_velocity(dv: NDArray[np.float64], allowed: NDArray[np.float64], gain: float = 1.0) -> NDArray[np.float64]:
    """Sum (d,) m/s of gain (|dv_j| - allowed_j) dv_j / |dv_j| over the velocity differences dv (k, d) m/s larger
    than ``allowed`` (k,) m/s: the friction form shared by alignment and the shill agents."""
    v = np.linalg.norm(dv, axis=1)
    act = (v > allowed) & (v > 1e-12)
    if not np.any(act):
        return np.zeros(dv.shape[1])
    return (gain * (v[act] - allowed[act]) / v[act]) @ dv[act]


def alignment(
    velocity: NDArray[np.float64],
    neighbour_velocities: NDArray[np.float64],
    distances: NDArray[np.float64],
    *,
    r0_frict: float,
    c_frict: float,
    v_frict: float,
    p_frict: float,
    a_frict: float,
) -> NDArray[np.float64]:
    """Sum (d,) m/s of C_frict (v_ij - v_frictmax) (v_j - v_i) / v_ij over neighbours with velocities
    (k, d) m/s at distances (k,) m whose velocity differs by more than v_frictmax."""
    dv = np.asarray(neighbour_velocities, dtype=float) - np.asarray(velocity, dtype=float)[None]
    allowed = np.maximum(v_frict, braking_curve(np.asarray(distances, dtype=float) - r0_frict, a_frict, p_frict))
    return _excess_velocity(dv, allowed, c_frict)


def shill(
    position: NDArray[np.float64],
    velocity: NDArray[np.float64],
    points: NDArray[np.float64],
    directions: NDArray[np.float64],
    distances: NDArray[np.float64],
    *,
    r0_shill: float,
    v_shill: float,
    p_shill: float,
    a_shill: float,
) -> NDArray[np.float64]:
    """Sum (d,) m/s of (v_is - v_shillmax) (v_s - v_i) / v_is over shill agents at ``points`` (m, d) m,
    moving at v_shill along unit ``directions`` (m, d), ``distances`` (m,) m from the agent.

    ``position`` is not used: the distances are given (0 for an agent past a wall).
    """
    v_s = v_shill * np.asarray(directions, dtype=float)
    dv = v_s - np.asarray(velocity, dtype=float)[None]
    allowed = braking_curve(np.asarray(distances, dtype=float) - r0_shill, a_shill, p_shill)
    return _excess_velocity(dv, allowed)


class VasarhelyiParams(Params):
    """Parameters of the ``vasarhelyi`` planner (scenario ``planner.params``); the paper's names.

    Defaults: the paper's optimised set for v_flock = 6 m/s scaled by 0.1 in length and speed.
    """

    v_flock: float | None = Field(
        None, gt=0.0, le=100.0, description="m/s, preferred flocking speed (null: the task's v_flock, else 0.6)"
    )
    v_max: float | None = Field(
        None, gt=0.0, le=100.0, description="m/s, desired velocities are cut to this (null: 4/3 v_flock)"
    )
    r0_rep: float = Field(2.5, ge=0.0, le=1e3, description="m, repulsion acts between agents closer than this")
    p_rep: float = Field(0.13, ge=0.0, le=100.0, description="1/s, gain of the repulsion's half spring")
    r0_frict: float = Field(8.53, ge=0.0, le=1e3, description="m, stopping-point offset of the alignment")
    C_frict: float = Field(0.05, ge=0.0, le=10.0, description="coefficient of velocity alignment (-)")
    v_frict: float = Field(0.063, ge=0.0, le=100.0, description="m/s, velocity slack of the alignment")
    p_frict: float = Field(3.2, gt=0.0, le=100.0, description="1/s, gain of the alignment's braking curve")
    a_frict: float = Field(0.416, gt=0.0, le=100.0, description="m/s^2, acceleration of the alignment's braking curve")
    r0_shill: float = Field(0.03, ge=0.0, le=1e3, description="m, stopping-point offset of walls and obstacles")
    v_shill: float = Field(1.36, ge=0.0, le=100.0, description="m/s, speed of the virtual shill agents")
    p_shill: float = Field(3.55, gt=0.0, le=100.0, description="1/s, gain of the walls' braking curve")
    a_shill: float = Field(0.302, gt=0.0, le=100.0, description="m/s^2, acceleration of the walls' braking curve")
    altitude_gain: float = Field(1.0, ge=0.0, le=100.0, description="1/s, pull towards the flight altitude")

    #: the model's eleven parameters and the ranges a tuning study searches by default (low, high, log)
    TUNED: ClassVar[dict[str, tuple[float, float, bool]]] = {
        "r0_rep": (0.5, 5.0, False),
        "p_rep": (0.02, 1.0, True),
        "r0_frict": (0.5, 15.0, False),
        "C_frict": (0.005, 0.5, True),
        "v_frict": (0.005, 0.3, True),
        "p_frict": (0.5, 10.0, True),
        "a_frict": (0.05, 2.0, True),
        "r0_shill": (0.0, 1.0, False),
        "v_shill": (0.2, 3.0, False),
        "p_shill": (0.5, 10.0, True),
        "a_shill": (0.05, 2.0, True),
    }


class VasarhelyiPlanner:
    """Decentralised Vásárhelyi flocking in a walled arena with pillars.

    Args:
        params: validated ``VasarhelyiParams`` (default: the defaults).
    """

    name: ClassVar[str] = "vasarhelyi"
    centralized: ClassVar[bool] = False
    Params: ClassVar[type[VasarhelyiParams]] = VasarhelyiParams

    def __init__(self, params: VasarhelyiParams | None = None) -> None:
        self.params = params if params is not None else VasarhelyiParams()

    def reset(self, agent_id: int, rng: np.random.Generator, info: FlockInfo) -> None:
        """Start a run as agent ``agent_id``: the arena, the speeds and a start heading."""
        p = self.params
        self.agent_id = agent_id
        self.arena = ArenaGeometry.from_info(info)
        self.v_flock, self.v_cap, self.altitude, self.axis_limits = flight_limits(info, p.v_flock, p.v_max)
        heading = rng.uniform(0.0, 2.0 * math.pi)
        self.start_heading = np.array([math.cos(heading), math.sin(heading)])

    def horizontal(self, obs: Observation) -> NDArray[np.float64]:
        """The model's desired horizontal velocity (2,) m/s, cut to v_max."""
        p = self.params
        pos, vel = obs.position[:2], obs.velocity[:2]
        speed = float(np.linalg.norm(vel))
        v = self.v_flock * (vel / speed if speed > MIN_SPEED else self.start_heading)
        nb_p = obs.neighbour_positions[:, :2]
        if len(nb_p):
            v = v + repulsion(pos, nb_p, p.r0_rep, p.p_rep)
            dist = np.linalg.norm(nb_p - pos[None], axis=1)
            v = v + alignment(
                vel,
                obs.neighbour_velocities[:, :2],
                dist,
                r0_frict=p.r0_frict,
                c_frict=p.C_frict,
                v_frict=p.v_frict,
                p_frict=p.p_frict,
                a_frict=p.a_frict,
            )
        wp, wn, wd = self.arena.walls(pos)
        pp, pn, pd = self.arena.pillar_points(pos)
        v = v + shill(
            pos,
            vel,
            np.vstack([wp, pp]),
            np.vstack([wn, pn]),
            np.concatenate([wd, pd]),
            r0_shill=p.r0_shill,
            v_shill=p.v_shill,
            p_shill=p.p_shill,
            a_shill=p.a_shill,
        )
        return cap_speed(v, self.v_cap)

    def velocity(self, obs: Observation) -> NDArray[np.float64]:
        """The commanded velocity (3,) m/s: the model horizontally, altitude hold vertically."""
        out = np.zeros(3)
        out[2] = altitude_velocity(float(obs.position[2]), self.altitude, self.params.altitude_gain)
        if obs.position[2] >= 0.5 * self.altitude:  # below it: taking off, climb first
            out[:2] = self.horizontal(obs)
        return scale_to_limits(out, self.axis_limits)

    def plan(self, obs: Observation, medium: Any | None) -> Command:
        """A VELOCITY command."""
        return Command.velocity(self.velocity(obs))


from pybullet_swarm.planning.registry import register_planner  # noqa: E402

register_planner(
    "vasarhelyi",
    VasarhelyiPlanner,
    "decentralised flocking of Vásárhelyi et al. 2018: self-propulsion, half-spring repulsion, "
    "alignment under a braking curve, shill agents at walls and pillars",
    ("flock",),
    default_for=("flock",),
)
