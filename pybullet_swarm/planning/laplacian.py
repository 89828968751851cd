"""Formation keeping with a graph Laplacian: x_dot = -k L (x - b), plus migration along the route.

The communication graph (``graph``: ``star`` around agent 0, the leader, as in the course
report; ``ring``; ``complete``; or an explicit symmetric adjacency matrix) gives the Laplacian
``L = D - A``. Agent i only uses the graph neighbours it senses (``Observation`` neighbours that
are also graph neighbours; an edge to an agent out of sensing range is dropped for that tick)
and commands, per axis,

    v_i = -k sum_j L_ij (x_j - b_j) = -k sum_{j ~ i} A_ij ((x_i - b_i) - (x_j - b_j))

with ``b`` the task's formation slots (``RouteLayout.formation_slots``, centred). On the
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

import enum
import math
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
import pydantic
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.planning.base import Command, Observation
from pybullet_swarm.planning.views.route import RouteInfo
from pybullet_swarm.planning.params import ParamRuleError, Params, PlanContext
from pybullet_swarm.planning.reynolds import RouteFollower, migration, scale_to_limits, separation, switch_radius_from


class Graph(str, enum.Enum):
    """Named communication graphs."""

    STAR = "star"  # agent 0 (the leader) talks to everyone, the others only to it
    RING = "ring"  # i talks to i - 1 and i + 1 (mod n)
    COMPLETE = "complete"  # everyone talks to everyone


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
            raise ValueError(
                f"planner.params.graph must be one of {[g.value for g in Graph]} or an n x n "
                f"adjacency matrix, got {graph!r}"
            ) from None
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
            raise ValueError(
                f"planner.params.graph must be a name or an n x n matrix of numbers, got {graph!r}"
            ) from None
        if A.shape != (n, n):
            raise ValueError(
                f"planner.params.graph must be a {n} x {n} adjacency matrix (agents.count = {n}), got shape {A.shape}"
            )
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


def laplacian_velocities(
    L: NDArray[np.float64], positions: NDArray[np.float64], slots: NDArray[np.float64], gain: float = 1.0
) -> NDArray[np.float64]:
    """Consensus velocities (n, 3) m/s: ``-gain L (x - b)`` for positions and slots (n, 3) m."""
    return -gain * (np.asarray(L, dtype=float) @ (np.asarray(positions, dtype=float) - np.asarray(slots, dtype=float)))


MAX_GRAPH = 2000
"""Largest explicit adjacency matrix (rows), as many as agents a scenario may have."""
Matrix = Annotated[
    list[Annotated[list[Annotated[float, Field(ge=0.0, le=1e6)]], Field(max_length=MAX_GRAPH)]],
    Field(min_length=1, max_length=MAX_GRAPH),
]


class LaplacianParams(Params):
    """Parameters of the ``laplacian`` planner (scenario ``planner.params``)."""

    graph: Literal["star", "ring", "complete"] | Matrix = Field(
        "star",
        description="communication graph: star (around agent 0), ring, complete, or an n x n symmetric "
        "adjacency matrix",
    )
    gain: float = Field(0.8, gt=0.0, le=100.0, description="1/s, k in v = -k L (x - b)")
    migration_speed: float | None = Field(
        None, ge=0.0, le=100.0, description="m/s, migration speed (null: 0.7 x the horizontal limit)"
    )
    altitude: float | None = Field(None, gt=0.0, le=1e4, description="m, flight altitude (null: each waypoint's z)")
    altitude_gain: float = Field(1.0, ge=0.0, le=100.0, description="1/s, pull to the flight altitude")
    separation_radius: float = Field(0.4, ge=0.0, le=1e4, description="m, formation mates closer than this repel")
    w_separation: float = Field(
        0.12, ge=0.0, le=100.0, description="m^2/s, separation weight (0: the pure Laplacian controller)"
    )
    switch_radius: float | None = Field(
        None,
        gt=0.0,
        le=1e4,
        description="m, move on when the estimated reference point is this close to "
        "the waypoint (null: 0.75 x the task's pass_radius)",
    )
    slow_radius: float = Field(
        0.5, ge=0.0, le=1e4, description="m, slow down within this distance of the last waypoint"
    )
    takeoff_height: float = Field(
        0.3, ge=0.0, le=1e4, description="m, below this an agent climbs vertically before it moves sideways"
    )

    @pydantic.model_validator(mode="after")
    def _graph(self) -> LaplacianParams:
        if not isinstance(self.graph, str):
            rows = len(self.graph)
            short = next((len(r) for r in self.graph if len(r) != rows), None)
            if short is not None:
                raise ParamRuleError("graph", f"must be a square n x n matrix, got {rows} rows and a row of {short}")
            try:
                adjacency(self.graph, len(self.graph))
            except ValueError as exc:
                raise ParamRuleError("graph", str(exc).removeprefix("planner.params.graph ")) from None
        return self

    def check_for(self, context: PlanContext) -> None:
        """An explicit adjacency matrix has one row per agent."""
        if not isinstance(self.graph, str) and len(self.graph) != context.n_agents:
            n = context.n_agents
            raise ParamRuleError(
                "graph", f"must be a {n} x {n} adjacency matrix (agents.count = {n}), got {len(self.graph)} rows"
            )


class LaplacianPlanner:
    """Decentralised Laplacian formation keeping with migration along the route (``RouteLayout.route``).

    Args:
        params: validated ``LaplacianParams`` (default: the defaults).
    """

    name: ClassVar[str] = "laplacian"
    centralized: ClassVar[bool] = False
    Params: ClassVar[type[LaplacianParams]] = LaplacianParams

    def __init__(self, params: LaplacianParams | None = None) -> None:
        self.params = params if params is not None else LaplacianParams()

    @classmethod
    def check_task(cls, task: Any) -> None:
        """Refuse, when the scenario is loaded, a route task without the formation this planner keeps."""
        if getattr(task, "formation", None) is None:
            raise ConfigError(
                "the laplacian planner needs a formation: add task.formation (slots, or the default "
                "five-robot formation for 5 agents)",
                field="task.formation",
            )

    def reset(self, agent_id: int, rng: np.random.Generator, info: RouteInfo) -> None:
        """Start a run as agent ``agent_id``: build the graph and read the slots."""
        p = self.params
        slots = info.layout.formation_slots
        if slots is None:
            raise ConfigError(
                "the laplacian planner needs a formation: add task.formation (slots, or the default "
                "five-robot formation for 5 agents)",
                field="task.formation",
            )
        self.slots = np.asarray(slots, dtype=float).reshape(-1, 3)  # (n, 3) m, centred
        n = info.n_agents
        self.A = adjacency(p.graph, n)
        self.L = laplacian(self.A)
        self.agent_id = agent_id
        self.v_max = np.where(np.isfinite(info.v_max), info.v_max, 1e9)
        v_h = float(min(info.v_max[0], info.v_max[1]))
        self.migration_speed = (
            p.migration_speed if p.migration_speed is not None else (0.7 * v_h if math.isfinite(v_h) else 0.5)
        )
        self.route = RouteFollower(info.layout.route, switch_radius_from(info, p.switch_radius))

    def velocity(self, obs: Observation) -> NDArray[np.float64]:
        """The commanded velocity (3,) m/s for this observation."""
        p, i = self.params, self.agent_id
        pos = obs.position
        ids = obs.neighbour_ids
        links = self.A[i, ids] > 0.0 if len(ids) else np.zeros(0, dtype=bool)
        mates, mate_pos = ids[links], obs.neighbour_positions[links]
        w = self.A[i, mates]
        own = pos - self.slots[i]  # where i puts the reference point
        theirs = mate_pos - self.slots[mates]  # (k, 3)
        v = -p.gain * np.sum(w[:, None] * (own[None, :] - theirs), axis=0) if len(mates) else np.zeros(3)
        ref = np.vstack([own[None], theirs]).mean(axis=0)  # estimated reference point
        wp = self.route.current(ref)
        if wp is not None:
            v += migration(ref, wp, self.migration_speed, slow_radius=p.slow_radius if self.route.last else 0.0)
        z_target = p.altitude if p.altitude is not None else (float(wp[2]) if wp is not None else float(pos[2]))
        v[2] += p.altitude_gain * (z_target + self.slots[i, 2] - pos[2])
        if p.w_separation > 0.0:
            v += p.w_separation * separation(pos, obs.neighbour_positions, p.separation_radius)
        if pos[2] < p.takeoff_height:  # taking off: climb first
            v[:2] = 0.0
        return scale_to_limits(v, self.v_max)

    def plan(self, obs: Observation, medium: Any | None) -> Command:
        """A VELOCITY command."""
        return Command.velocity(self.velocity(obs))


from pybullet_swarm.planning.registry import register_planner  # noqa: E402

register_planner(
    "laplacian",
    LaplacianPlanner,
    "decentralised formation keeping x' = -k L (x - b) over a "
    "communication graph (star, ring, complete, adjacency) with migration along the route",
    ("route",),
)
