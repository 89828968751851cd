"""Formation keeping with a graph Laplacian: x_dot = -k L (x - b), plus migration along the route.

The communication graph (``graph``: ``star`` around agent 0, the leader, as in the course
report; ``ring``; ``complete``; or an explicit symmetric adjacency matrix) gives the Laplacian
``L = D - A``. Agent i only uses the graph neighbours it senses (``Observation`` neighbours that
are also graph neighbours; an edge to an agent out of sensing range is dropped for that tick)
and commands, per axis,

    v_i = -k sum_j L_ij (x_j - b_j) = -k sum_{j ~ i} A_ij ((x_i - b_i) - (x_j - b_j))

with ``b`` the task's formation slots (``TaskInfo.extra["formation_slots"]``, centred). On the
kinematic model ``x_dot = v`` the formation error ``e = (x - b) - mean(x - b)`` then decays as
``exp(-k lambda_2 t)`` (slowest mode), lambda_2 the graph's algebraic connectivity.

Migration. Each agent estimates the formation's reference point as the mean of ``x_j - b_j``
over itself and its sensed graph neighbours (all equal in formation) and adds
``migration_speed`` towards the current waypoint of the route (horizontal; slowing down within
``slow_radius`` of the last one); altitude is held at the waypoint's z (or ``altitude``).
Because the migration term is the same for everyone in formation, it moves the formation
without deforming it.

Safety. Real airframes lag their commands and dodge obstacles; a short-range separation term
(as in the flocking planner, ``w_separation`` within ``separation_radius``) keeps formation mates
apart while the Laplacian pulls them back into their slots. Set ``w_separation: 0`` for the pure
controller.
"""
from __future__ import annotations

import dataclasses
import enum
import math
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.planning.base import Command, Observation, TaskInfo, params_from_mapping
from pybullet_swarm.planning.reynolds import (RouteFollower, _positive, migration, scale_to_limits, separation,
                                              switch_radius_from)


class Graph(str, enum.Enum):
    """Named communication graphs."""

    STAR = "star"           # agent 0 (the leader) talks to everyone, the others only to it
    RING = "ring"           # i talks to i - 1 and i + 1 (mod n)
    COMPLETE = "complete"   # everyone talks to everyone


def adjacency(graph: str | list[list[float]] | NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """Adjacency matrix (n, n) of a named graph or a validated explicit one.

    Raises:
        ValueError: unknown name, wrong shape, asymmetric, negative weights, self-loops, or a
            disconnected graph (no formation could be reached).
    """
    if isinstance(graph, str):
        try:
            kind = Graph(graph)
        except ValueError:
            raise ValueError(f"planner.params.graph must be one of {[g.value for g in Graph]} or an n x n "
                             f"adjacency matrix, got {graph!r}") from None
        A = np.zeros((n, n))
        if kind is Graph.STAR:
            A[0, 1:] = A[1:, 0] = 1.0
        elif kind is Graph.RING:
            for i in range(n):
                if n > 1:
                    A[i, (i + 1) % n] = A[(i + 1) % n, i] = 1.0
        else:
            A[:] = 1.0
            np.fill_diagonal(A, 0.0)
    else:
        try:
            A = np.asarray(graph, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"planner.params.graph must be a name or an n x n matrix of numbers, got {graph!r}") from None
        if A.shape != (n, n):
            raise ValueError(f"planner.params.graph must be a {n} x {n} adjacency matrix (agents.count = {n}), "
                             f"got shape {A.shape}")
        if not np.all(np.isfinite(A)) or np.any(A < 0):
            raise ValueError("planner.params.graph must hold finite weights >= 0")
        if not np.allclose(A, A.T):
            raise ValueError("planner.params.graph must be symmetric (undirected links)")
        if np.any(np.diag(A) != 0):
            raise ValueError("planner.params.graph must have a zero diagonal (no self-links)")
    if n > 1 and algebraic_connectivity(laplacian(A)) < 1e-9:
        raise ValueError("planner.params.graph is not connected: the formation cannot be reached")
    return A


def laplacian(A: NDArray[np.float64]) -> NDArray[np.float64]:
    """Graph Laplacian ``L = D - A`` (n, n) of an adjacency matrix (n, n)."""
    A = np.asarray(A, dtype=float)
    return np.diag(A.sum(axis=1)) - A


def algebraic_connectivity(L: NDArray[np.float64]) -> float:
    """Second smallest eigenvalue of a symmetric Laplacian (n, n) (0 for one agent)."""
    w = np.linalg.eigvalsh(np.asarray(L, dtype=float))
    return float(w[1]) if len(w) > 1 else 0.0


def formation_error(positions: NDArray[np.float64], slots: NDArray[np.float64]) -> NDArray[np.float64]:
    """Formation error (n, 3) m: ``(x - b) - mean(x - b)`` for positions and slots (n, 3) m."""
    e = np.asarray(positions, dtype=float) - np.asarray(slots, dtype=float)
    return e - e.mean(axis=0)


def laplacian_velocities(L: NDArray[np.float64], positions: NDArray[np.float64], slots: NDArray[np.float64],
                         gain: float = 1.0) -> NDArray[np.float64]:
    """Consensus velocities (n, 3) m/s: ``-gain L (x - b)`` for positions and slots (n, 3) m."""
    return -gain * (np.asarray(L, dtype=float) @ (np.asarray(positions, dtype=float) - np.asarray(slots, dtype=float)))


@dataclasses.dataclass(frozen=True)
class LaplacianParams:
    """Parameters of the ``laplacian`` planner (scenario ``planner.params``).

    Attributes:
        graph: ``star``, ``ring``, ``complete`` or an n x n symmetric adjacency matrix.
        gain: 1/s, k in v = -k L (x - b).
        migration_speed: m/s (None: 0.7 x the horizontal limit).
        altitude: m, flight altitude (None: each waypoint's z).
        altitude_gain: 1/s.
        separation_radius: m, formation mates closer than this repel.
        w_separation: m^2/s, separation weight (0: the pure Laplacian controller).
        switch_radius: m, move on when the estimated reference point is this close to the waypoint
            (None: 0.75 x the task's pass_radius).
        slow_radius: m, slow down within this distance of the last waypoint.
        takeoff_height: m, below this an agent climbs vertically before it moves sideways.
    """

    graph: Any = "star"
    gain: float = 0.8
    migration_speed: float | None = None
    altitude: float | None = None
    altitude_gain: float = 1.0
    separation_radius: float = 0.4
    w_separation: float = 0.12
    switch_radius: float | None = None
    slow_radius: float = 0.5
    takeoff_height: float = 0.3

    def __post_init__(self) -> None:
        _positive("gain", self.gain, allow_zero=False)
        for name in ("altitude_gain", "separation_radius", "w_separation", "slow_radius", "takeoff_height"):
            _positive(name, getattr(self, name))
        if self.migration_speed is not None:
            _positive("migration_speed", self.migration_speed)
        if self.altitude is not None:
            _positive("altitude", self.altitude, allow_zero=False)
        if self.switch_radius is not None:
            _positive("switch_radius", self.switch_radius, allow_zero=False)

    @classmethod
    def from_mapping(cls, data: dict[str, Any]) -> LaplacianParams:
        """Parameters from ``planner.params``; unknown names are refused with ValueError."""
        return params_from_mapping(cls, data, "planner.params", "the laplacian planner")


class LaplacianPlanner:
    """Decentralised Laplacian formation keeping with migration along ``TaskInfo.route``."""

    name: ClassVar[str] = "laplacian"
    centralized: ClassVar[bool] = False

    def __init__(self, **params: Any) -> None:
        self.params = LaplacianParams.from_mapping(params)

    def reset(self, agent_id: int, rng: np.random.Generator, info: TaskInfo) -> None:
        """Start a run as agent ``agent_id``: build the graph and read the slots."""
        p = self.params
        slots = info.extra.get("formation_slots")
        if slots is None:
            raise ConfigError("the laplacian planner needs a formation: add task.formation (slots, or the default "
                              "five-robot formation for 5 agents)", field="task.formation")
        self.slots = np.asarray(slots, dtype=float).reshape(-1, 3)   # (n, 3) m, centred
        n = info.n_agents
        self.A = adjacency(p.graph, n)
        self.L = laplacian(self.A)
        self.agent_id = agent_id
        self.v_max = np.where(np.isfinite(info.v_max), info.v_max, 1e9)
        v_h = float(min(info.v_max[0], info.v_max[1]))
        self.migration_speed = p.migration_speed if p.migration_speed is not None else (
            0.7 * v_h if math.isfinite(v_h) else 0.5)
        self.route = RouteFollower(info.route, switch_radius_from(info, p.switch_radius))

    def velocity(self, obs: Observation) -> NDArray[np.float64]:
        """The commanded velocity (3,) m/s for this observation."""
        p, i = self.params, self.agent_id
        pos = obs.position
        ids = obs.neighbour_ids
        links = self.A[i, ids] > 0.0 if len(ids) else np.zeros(0, dtype=bool)
        mates, mate_pos = ids[links], obs.neighbour_positions[links]
        w = self.A[i, mates]
        own = pos - self.slots[i]                                   # where i puts the reference point
        theirs = mate_pos - self.slots[mates]                        # (k, 3)
        v = -p.gain * np.sum(w[:, None] * (own[None, :] - theirs), axis=0) if len(mates) else np.zeros(3)
        ref = np.vstack([own[None], theirs]).mean(axis=0)            # estimated reference point
        wp = self.route.current(ref)
        if wp is not None:
            v += migration(ref, wp, self.migration_speed, slow_radius=p.slow_radius if self.route.last else 0.0)
        z_target = p.altitude if p.altitude is not None else (float(wp[2]) if wp is not None else float(pos[2]))
        v[2] += p.altitude_gain * (z_target + self.slots[i, 2] - pos[2])
        if p.w_separation > 0.0:
            v += p.w_separation * separation(pos, obs.neighbour_positions, p.separation_radius)
        if pos[2] < p.takeoff_height:   # taking off: climb first
            v[:2] = 0.0
        return scale_to_limits(v, self.v_max)

    def plan(self, obs: Observation, medium: Any | None) -> Command:
        """A VELOCITY command."""
        return Command.velocity(self.velocity(obs))


from pybullet_swarm.planning.registry import register_planner  # noqa: E402

register_planner("laplacian", LaplacianPlanner, "decentralised formation keeping x' = -k L (x - b) over a "
                 "communication graph (star, ring, complete, adjacency) with migration along the route", ("route",))
