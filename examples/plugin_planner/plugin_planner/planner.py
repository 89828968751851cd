"""``follow_route``: each agent flies to the route's next waypoint and keeps its distance from the others.

A decentralised planner for ``route`` tasks, from pybullet_swarm's public protocol only. Every
agent holds its own index into the route (``info.layout.route``, a ``RouteLayout`` every agent is
told before the run) and moves on to the next waypoint once the centroid of itself and the
neighbours it senses is within ``switch_radius`` of the present one horizontally (with every agent
in sensing range, that is the swarm's centroid: the route task's ``centroid`` criterion passes the
waypoint at the same moment).

Its velocity command is the sum of three terms, clipped to the vehicle's limits:

- migration: towards the waypoint at ``speed`` m/s, slowing down within ``slow_radius`` of the last one;
- separation: away from each neighbour closer than ``separation_radius``, growing as it comes closer;
- altitude: a proportional hold of the waypoint's altitude.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.planning.base import Command, Observation
from pybullet_swarm.planning.params import Params
from pybullet_swarm.planning.views.route import RouteInfo


class FollowRouteParams(Params):
    """Parameters of ``follow_route`` (``planner.params`` in a scenario)."""

    speed: float = Field(0.25, gt=0.0, le=5.0, description="m/s, cruise speed towards the waypoint")
    switch_radius: float = Field(0.25, gt=0.0, le=10.0, description="m, centroid this close: next waypoint")
    slow_radius: float = Field(0.5, ge=0.0, le=10.0, description="m, slow down this close to the last waypoint")
    separation_radius: float = Field(0.6, gt=0.0, le=10.0, description="m, neighbours closer than this repel")
    w_separation: float = Field(0.2, ge=0.0, le=10.0, description="m^2/s, strength of the repulsion")
    altitude_gain: float = Field(1.0, gt=0.0, le=10.0, description="1/s, proportional altitude hold")


class FollowRoute:
    """Decentralised route following with separation (one instance per agent).

    Args:
        params: validated parameters (default: the defaults).
    """

    name: ClassVar[str] = "follow_route"
    centralized: ClassVar[bool] = False
    description: ClassVar[str] = "decentralised: fly to the route's next waypoint, keep apart from neighbours"
    tasks: ClassVar[tuple[str, ...]] = ("route",)
    Params: ClassVar[type[FollowRouteParams]] = FollowRouteParams

    def __init__(self, params: FollowRouteParams | None = None) -> None:
        self.params = params if params is not None else FollowRouteParams()
        self.index = 0

    def reset(self, agent_id: int, rng: np.random.Generator, info: RouteInfo) -> None:
        """Start a run as agent ``agent_id`` at the route's first waypoint."""
        self.agent_id = agent_id
        self.route = np.asarray(info.layout.route, dtype=float).reshape(-1, 3)  # (W, 3) m
        self.v_max = np.where(np.isfinite(info.v_max), info.v_max, 1e9)  # (3,) m/s
        self.index = 0

    def activity(self) -> str:
        """Which waypoint the agent is flying to."""
        return f"waypoint {self.index + 1}/{len(self.route)}" if self.index < len(self.route) else "route done"

    def plan(self, obs: Observation, medium: Any | None) -> Command:
        """A velocity command (3,) m/s."""
        return Command.velocity(self.velocity(obs))

    def velocity(self, obs: Observation) -> NDArray[np.float64]:
        """The commanded velocity (3,) m/s for this observation."""
        p = self.params
        pos = obs.position
        centroid = np.vstack([pos[None], obs.neighbour_positions]).mean(axis=0)
        while self.index < len(self.route) - 1 and _horizontal(centroid, self.route[self.index]) <= p.switch_radius:
            self.index += 1
        goal = self.route[min(self.index, len(self.route) - 1)]
        v = np.zeros(3)
        to_goal = goal[:2] - pos[:2]
        dist = float(np.hypot(*to_goal))
        last = self.index >= len(self.route) - 1
        speed = p.speed * min(1.0, dist / p.slow_radius) if last and p.slow_radius > 0 else p.speed
        if dist > 1e-6:
            v[:2] = speed * to_goal / dist
        v[:2] += p.w_separation * _separation(pos, obs.neighbour_positions, p.separation_radius)
        v[2] = p.altitude_gain * (goal[2] - pos[2])
        return np.clip(v, -self.v_max, self.v_max)


def _horizontal(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """m, horizontal distance between two points (3,) m."""
    return float(np.hypot(a[0] - b[0], a[1] - b[1]))


def _separation(pos: NDArray[np.float64], others: NDArray[np.float64], radius: float) -> NDArray[np.float64]:
    """(2,) 1/m, away from each neighbour (k, 3) m closer than ``radius`` horizontally, as 1/d - 1/radius."""
    d = pos[None, :2] - others[:, :2]
    r = np.hypot(d[:, 0], d[:, 1])
    near = (r < radius) & (r > 1e-6)
    if not np.any(near):
        return np.zeros(2)
    w = (1.0 / r[near] - 1.0 / radius) / r[near]
    return np.sum(d[near] * w[:, None], axis=0)
