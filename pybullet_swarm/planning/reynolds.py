"""Reynolds flocking with a migratory urge: separation, alignment and cohesion over sensed neighbours.

Each agent (decentralised: its own ``Observation`` only) commands a velocity, the weighted sum of

* separation ``w_s * sum_j (p_i - p_j) / |p_i - p_j|^2`` over neighbours closer than
  ``separation_radius`` (a push away from each, stronger the closer it is),
* alignment ``w_a * (mean_j v_j - v_i)`` (towards the neighbours' mean velocity),
* cohesion ``w_c * (mean_j p_j - p_i)`` (towards the neighbours' centroid),
* migration ``migration_speed * u``, u the unit horizontal direction to the current waypoint of
  the route (slowing down within ``slow_radius`` of the last one),

where the three rules use the neighbours within ``radius`` (the neighbourhood of the course
report; it cannot see further than the scenario's ``agents.sensing_radius``). The flock flies
in 3-D but inside an altitude band: outside ``altitude_band`` a term ``altitude_gain * (band -
z)`` pulls the agent back. Agents below half the band's floor (on the ground, taking off)
climb vertically before any horizontal term acts. The sum is scaled down, direction kept,
to the per-axis velocity limits.

Waypoints. Every agent keeps its own index into the route (``RouteLayout.route``) and moves on when the
centroid of itself and its sensed neighbours is within ``switch_radius`` (default three
quarters of the task's ``pass_radius``) of the current waypoint, so that the task (judging the
swarm's centroid against ``pass_radius``) has counted it when the flock turns.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, ClassVar

import numpy as np
import pydantic
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.planning.base import Command, Observation
from pybullet_swarm.planning.views.route import RouteInfo
from pybullet_swarm.planning.params import ParamRuleError, Params


def separation(position: NDArray[np.float64], neighbours: NDArray[np.float64], radius: float) -> NDArray[np.float64]:
    """Separation (3,) m^-1: sum of (p - p_j) / |p - p_j|^2 over neighbours (k, 3) m closer than radius m."""
    d = np.asarray(position, dtype=float) - np.asarray(neighbours, dtype=float).reshape(-1, 3)
    d2 = np.sum(d * d, axis=1)
    near = (d2 < radius * radius) & (d2 > 1e-12)
    return np.sum(d[near] / d2[near, None], axis=0) if np.any(near) else np.zeros(3)


def alignment(velocity: NDArray[np.float64], neighbour_velocities: NDArray[np.float64]) -> NDArray[np.float64]:
    """Alignment (3,) m/s: the neighbours' mean velocity (k, 3) m/s minus the agent's own."""
    v = np.asarray(neighbour_velocities, dtype=float).reshape(-1, 3)
    return v.mean(axis=0) - np.asarray(velocity, dtype=float) if len(v) else np.zeros(3)


def cohesion(position: NDArray[np.float64], neighbours: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cohesion (3,) m: from the agent to the centroid of its neighbours (k, 3) m."""
    p = np.asarray(neighbours, dtype=float).reshape(-1, 3)
    return p.mean(axis=0) - np.asarray(position, dtype=float) if len(p) else np.zeros(3)


def migration(
    position: NDArray[np.float64], waypoint: NDArray[np.float64], speed: float, *, slow_radius: float = 0.0
) -> NDArray[np.float64]:
    """Migratory urge (3,) m/s: ``speed`` along the horizontal direction to ``waypoint`` (3,) m,
    scaled by distance / ``slow_radius`` within ``slow_radius`` (0: never slows)."""
    d = np.asarray(waypoint, dtype=float) - np.asarray(position, dtype=float)
    d[2] = 0.0
    dist = float(np.linalg.norm(d))
    if dist < 1e-9:
        return np.zeros(3)
    s = speed * (min(1.0, dist / slow_radius) if slow_radius > 0.0 else 1.0)
    return d * (s / dist)


def altitude_hold(z: float, band: tuple[float, float], gain: float) -> float:
    """Vertical velocity m/s pulling altitude z m back into the band (lo, hi) m; 0 inside it."""
    lo, hi = band
    return gain * (lo - z) if z < lo else (gain * (hi - z) if z > hi else 0.0)


def scale_to_limits(v: NDArray[np.float64], v_max: NDArray[np.float64]) -> NDArray[np.float64]:
    """Velocity v (3,) m/s scaled down (direction kept) so that every axis is within v_max (3,) m/s."""
    v = np.asarray(v, dtype=float)
    lim = np.asarray(v_max, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(np.abs(v) > lim, lim / np.abs(v), 1.0)
    return v * float(np.min(ratio))


Altitude = Annotated[float, Field(gt=0.0, le=1e4)]


class ReynoldsParams(Params):
    """Parameters of the ``reynolds`` planner (scenario ``planner.params``)."""

    radius: float = Field(
        1.0, gt=0.0, le=1e4, description="m, neighbourhood radius of separation, alignment and cohesion"
    )
    separation_radius: float = Field(0.6, ge=0.0, le=1e4, description="m, only neighbours closer than this repel")
    w_separation: float = Field(0.15, ge=0.0, le=100.0, description="m^2/s, separation weight")
    w_alignment: float = Field(0.5, ge=0.0, le=100.0, description="alignment weight (dimensionless)")
    w_cohesion: float = Field(0.2, ge=0.0, le=100.0, description="1/s, cohesion weight")
    migration_speed: float | None = Field(
        None, ge=0.0, le=100.0, description="m/s, speed of the migratory urge (null: 0.8 x the horizontal limit)"
    )
    altitude_band: Annotated[list[Altitude], Field(min_length=2, max_length=2)] = Field(
        default_factory=lambda: [0.8, 1.2], description="[lo, hi] m, the flock flies between these altitudes"
    )
    altitude_gain: float = Field(1.0, ge=0.0, le=100.0, description="1/s, pull back into the altitude band")
    switch_radius: float | None = Field(
        None,
        gt=0.0,
        le=1e4,
        description="m, move on to the next waypoint when the local centroid is this "
        "close (null: 0.75 x the task's pass_radius)",
    )
    slow_radius: float = Field(
        0.5, ge=0.0, le=1e4, description="m, slow down within this distance of the last waypoint"
    )

    @pydantic.model_validator(mode="after")
    def _band(self) -> ReynoldsParams:
        lo, hi = self.altitude_band
        if lo > hi:
            raise ParamRuleError("altitude_band", f"must be [lo, hi] m with lo <= hi, got [{lo:g}, {hi:g}]")
        return self


class RouteFollower:
    """An agent's own progress along the route (shared by the flocking and formation planners).

    Args:
        route: (W, 3) m, waypoints.
        switch_radius: m, move on when the tracked point is this close (horizontally).
    """

    def __init__(self, route: NDArray[np.float64], switch_radius: float) -> None:
        self.route = np.asarray(route, dtype=float).reshape(-1, 3)
        self.switch_radius = float(switch_radius)
        self.index = 0

    @property
    def last(self) -> bool:
        """True when the current waypoint is the last."""
        return self.index >= len(self.route) - 1

    def current(self, point: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """The current waypoint (3,) m after advancing past those ``point`` (3,) m has reached."""
        if len(self.route) == 0:
            return None
        while not self.last and np.hypot(*(point[:2] - self.route[self.index, :2])) <= self.switch_radius:
            self.index += 1
        return self.route[self.index]


def switch_radius_from(info: RouteInfo, value: float | None) -> float:
    """The waypoint switch radius m: ``value``, else 0.75 x the task's pass radius (0.2 m without one)."""
    if value is not None:
        return float(value)
    return 0.75 * float(info.layout.pass_radius)


class ReynoldsPlanner:
    """Decentralised Reynolds flocking with a migratory urge along the route (``RouteLayout.route``).

    Args:
        params: validated ``ReynoldsParams`` (default: the defaults).
    """

    name: ClassVar[str] = "reynolds"
    centralized: ClassVar[bool] = False
    Params: ClassVar[type[ReynoldsParams]] = ReynoldsParams

    def __init__(self, params: ReynoldsParams | None = None) -> None:
        self.params = params if params is not None else ReynoldsParams()

    def reset(self, agent_id: int, rng: np.random.Generator, info: RouteInfo) -> None:
        """Start a run as agent ``agent_id``."""
        p = self.params
        self.agent_id = agent_id
        self.v_max = np.where(np.isfinite(info.v_max), info.v_max, 1e9)  # (3,) m/s
        v_h = float(min(info.v_max[0], info.v_max[1]))
        self.migration_speed = (
            p.migration_speed if p.migration_speed is not None else (0.8 * v_h if math.isfinite(v_h) else 0.5)
        )
        self.route = RouteFollower(info.layout.route, switch_radius_from(info, p.switch_radius))

    def velocity(self, obs: Observation) -> NDArray[np.float64]:
        """The commanded velocity (3,) m/s for this observation."""
        p = self.params
        pos, vel = obs.position, obs.velocity
        d = obs.neighbour_positions - pos
        near = np.sum(d * d, axis=1) <= p.radius * p.radius
        nb_p, nb_v = obs.neighbour_positions[near], obs.neighbour_velocities[near]
        v = np.zeros(3)
        v[2] = altitude_hold(float(pos[2]), (p.altitude_band[0], p.altitude_band[1]), p.altitude_gain)
        if pos[2] < 0.5 * p.altitude_band[0]:  # taking off: climb first
            return scale_to_limits(v, self.v_max)
        v += p.w_separation * separation(pos, nb_p, p.separation_radius)
        v += p.w_alignment * alignment(vel, nb_v)
        v += p.w_cohesion * cohesion(pos, nb_p)
        local = np.vstack([pos[None], obs.neighbour_positions]).mean(axis=0)
        wp = self.route.current(local)
        if wp is not None:
            v += migration(pos, wp, self.migration_speed, slow_radius=p.slow_radius if self.route.last else 0.0)
        return scale_to_limits(v, self.v_max)

    def plan(self, obs: Observation, medium: Any | None) -> Command:
        """A VELOCITY command."""
        return Command.velocity(self.velocity(obs))


from pybullet_swarm.planning.registry import register_planner  # noqa: E402

register_planner(
    "reynolds",
    ReynoldsPlanner,
    "decentralised Reynolds flocking (separation, alignment, cohesion "
    "within a neighbourhood radius) with a migratory urge along the route, in an altitude band",
    ("route", "flock"),
    default_for=("route",),
)
