"""PyBullet world: connection, bodies, wrenches, state reads, contacts, ray casts, rendering.

This module is the only importer of ``pybullet``. Callers hold integer handles (agent indices,
body handles) and numpy arrays; the client id never leaves this class.
"""

from __future__ import annotations

import contextlib
import dataclasses
import enum
import itertools
import os
import sys
from pathlib import Path
from typing import Any, Iterable, Iterator, Sequence

import numpy as np
from numpy.typing import NDArray


@contextlib.contextmanager
def _quiet_stdout(stream: Any = None) -> Iterator[None]:
    """Silence what Bullet's C code prints on a stream of the process (default stdout), e.g.
    'processing base_link' or its build-time banner."""
    stream = sys.stdout if stream is None else stream
    try:
        fd = stream.fileno()
    except (AttributeError, OSError, ValueError):
        yield
        return
    stream.flush()
    saved = os.dup(fd)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), fd)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)


with _quiet_stdout(), _quiet_stdout(sys.stderr):
    import pybullet as pb


_NO_PAIRS: frozenset[tuple[int, int]] = frozenset()


@dataclasses.dataclass(frozen=True)
class _AgentPairTest:
    """The candidate pairs of two agents of a broad phase over a horizon, for a sphere test every step.

    Attributes:
        which: (p,) their places in the candidate list.
        rows_a, rows_b: (p,) rows of their agents in the state array.
        limit2: (p,) m^2, squared sum of their bounding radii and the slack.
        n_pairs: length of the candidate list.
    """

    which: NDArray[np.int64]
    rows_a: NDArray[np.int64]
    rows_b: NDArray[np.int64]
    limit2: NDArray[np.float64]
    n_pairs: int


#: a broad phase over a horizon: the state version it ran at, the pairs that may overlap before the horizon
#: ends, the ghost bodies' base positions (k, 3) m then, how far (k,) m each may move, and the sphere test of
#: the candidate pairs of two agents
_GhostPlan = tuple[int, list[tuple[int, int]], NDArray[np.float64], NDArray[np.float64], _AgentPairTest | None]


class BodyKind(str, enum.Enum):
    """What a Bullet body is, for classifying contacts."""

    GROUND = "ground"
    AGENT = "agent"
    BOX = "box"
    OBSTACLE = "obstacle"
    WALL = "wall"


class World:
    """A private PyBullet client holding the ground, the agents and any task bodies.

    Args:
        physics_hz: physics rate, Hz (the Bullet time step is its inverse).
        gravity: magnitude of gravity, m/s^2 (acting along -z).
        gui: open the Bullet GUI instead of the headless DIRECT mode.
        ghost_horizon: physics steps one broad phase of the ghost pairs serves (``ghost_overlaps``); 1: a broad
            phase every step.
    """

    #: m/s^2, the largest acceleration the ghost broad phase allows a body between two of its runs: ten times
    #: gravity, more than three times what the rotors of the bundled vehicles give (thrust-to-weight about 2)
    #: with gravity added; contacts with the ground, walls and resting boxes stop a body, they do not speed it up
    GHOST_MAX_ACCELERATION = 100.0

    def __init__(
        self, *, physics_hz: float = 240.0, gravity: float = 9.81, gui: bool = False, ghost_horizon: int = 1
    ) -> None:
        if int(ghost_horizon) < 1:
            raise ValueError(f"ghost_horizon must be at least 1 physics step, got {ghost_horizon}")
        self.physics_hz = float(physics_hz)
        self.gui = gui
        self.ghost_horizon = int(ghost_horizon)
        self._cid = pb.connect(pb.GUI if gui else pb.DIRECT)
        if self._cid < 0:
            raise RuntimeError("could not connect to a PyBullet physics server")
        cid = self._cid
        pb.setGravity(0.0, 0.0, -float(gravity), physicsClientId=cid)
        pb.setTimeStep(1.0 / self.physics_hz, physicsClientId=cid)
        pb.setPhysicsEngineParameter(numSubSteps=0, deterministicOverlappingPairs=1, physicsClientId=cid)
        if gui:
            pb.configureDebugVisualizer(pb.COV_ENABLE_GUI, 0, physicsClientId=cid)
        self._agents: list[int] = []
        self._kind: dict[int, BodyKind] = {}
        self._names: dict[int, str] = {}
        self.ground: int | None = None
        # Bound C functions, to keep the per-step Python work small.
        self._get_pose = pb.getBasePositionAndOrientation
        self._get_vel = pb.getBaseVelocity
        self._apply_force = pb.applyExternalForce
        self._apply_torque = pb.applyExternalTorque
        self._step = pb.stepSimulation
        self._contacts = pb.getContactPoints
        self._closest = pb.getClosestPoints
        self._poses: list[Any] = []
        self._version = 0  # changes whenever a body may have moved (a step, a teleport)
        self._states: NDArray[np.float64] | None = None  # (n, 13), the array of the last read_agent_states
        self._ghost_pairs: set[tuple[int, int]] = set()
        self._ghosts: _GhostIndex | None = None  # built from _ghost_pairs when first needed
        self._ghost_plan: _GhostPlan | None = None  # the last broad phase over a horizon
        self.ghost_bound_exceeded = 0  # broad phases that found a body beyond its bound (see _plan_ghosts)
        self._reach: dict[int, float] = {}  # m, per body: farthest point of its shape from its base position
        self._box_sizes: dict[int, tuple[float, float, float]] = {}  # m, edges of every dynamic box
        self._held: dict[int, tuple[int, int]] = {}  # constraint of ``attach`` -> (child, parent)

    # ------------------------------------------------------------------ bodies
    def add_ground(self) -> int:
        """Add an infinite ground plane at z = 0; returns its body handle."""
        shape = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=self._cid)
        visual = -1
        if self.gui:
            visual = pb.createVisualShape(pb.GEOM_PLANE, rgbaColor=[0.85, 0.85, 0.85, 1], physicsClientId=self._cid)
        body = pb.createMultiBody(0.0, shape, visual, physicsClientId=self._cid)
        pb.changeDynamics(body, -1, lateralFriction=0.8, physicsClientId=self._cid)
        self.ground = body
        self._register(body, BodyKind.GROUND, "ground")
        return body

    def add_box(
        self,
        center: Sequence[float],
        size: Sequence[float],
        *,
        mass: float = 0.0,
        kind: BodyKind = BodyKind.OBSTACLE,
        name: str = "",
        yaw: float = 0.0,
        color: Sequence[float] = (0.6, 0.6, 0.6, 1.0),
        friction: float = 0.8,
    ) -> int:
        """Add a box (static when mass is 0); returns its body handle."""
        half = [0.5 * float(s) for s in size]
        cid = self._cid
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=cid)
        visual = pb.createVisualShape(pb.GEOM_BOX, halfExtents=half, rgbaColor=list(color), physicsClientId=cid)
        orn = pb.getQuaternionFromEuler([0.0, 0.0, yaw])
        body = pb.createMultiBody(
            float(mass), shape, visual, basePosition=list(map(float, center)), baseOrientation=orn, physicsClientId=cid
        )
        pb.changeDynamics(body, -1, lateralFriction=friction, physicsClientId=cid)
        if mass > 0.0:
            self._box_sizes[body] = (float(size[0]), float(size[1]), float(size[2]))
            # resting boxes fall asleep and cost nothing until something touches them
            pb.changeDynamics(body, -1, activationState=pb.ACTIVATION_STATE_ENABLE_SLEEPING, physicsClientId=cid)
        self._register(body, kind, name or f"{kind.value}{body}")
        return body

    def wake(self, body: int) -> None:
        """Wake a sleeping body up (before attaching it, for example)."""
        pb.changeDynamics(body, -1, activationState=pb.ACTIVATION_STATE_WAKE_UP, physicsClientId=self._cid)

    def add_cylinder(
        self,
        center: Sequence[float],
        radius: float,
        height: float,
        *,
        name: str = "",
        kind: BodyKind = BodyKind.OBSTACLE,
        color: Sequence[float] = (0.5, 0.5, 0.5, 1.0),
    ) -> int:
        """Add a static vertical cylinder (a pillar); returns its body handle."""
        cid = self._cid
        shape = pb.createCollisionShape(
            pb.GEOM_CYLINDER, radius=float(radius), height=float(height), physicsClientId=cid
        )
        visual = pb.createVisualShape(
            pb.GEOM_CYLINDER, radius=float(radius), length=float(height), rgbaColor=list(color), physicsClientId=cid
        )
        body = pb.createMultiBody(0.0, shape, visual, basePosition=list(map(float, center)), physicsClientId=cid)
        self._register(body, kind, name or f"{kind.value}{body}")
        return body

    def add_walls(self, size_xy: Sequence[float], height: float, thickness: float = 0.02) -> list[int]:
        """Add four static walls around the arena [0, Lx] x [0, Ly]; returns their handles."""
        lx, ly = float(size_xy[0]), float(size_xy[1])
        t, h = thickness, float(height)
        specs = [
            ((lx / 2, -t / 2, h / 2), (lx + 2 * t, t, h)),
            ((lx / 2, ly + t / 2, h / 2), (lx + 2 * t, t, h)),
            ((-t / 2, ly / 2, h / 2), (t, ly, h)),
            ((lx + t / 2, ly / 2, h / 2), (t, ly, h)),
        ]
        return [
            self.add_box(c, s, kind=BodyKind.WALL, name=f"wall{i}", color=(0.7, 0.7, 0.75, 0.4))
            for i, (c, s) in enumerate(specs)
        ]

    def add_agents(
        self,
        urdf: Path,
        positions: NDArray[np.float64],
        *,
        mass: float,
        inertia: Sequence[float],
        yaws: NDArray[np.float64] | None = None,
        contact_stiffness: float = 2000.0,
        contact_damping: float = 40.0,
    ) -> None:
        """Load one URDF per agent at ``positions`` (n, 3) m; mass and inertia override the file's.

        Each agent is one rigid body (fixed links merged), with no velocity damping so that the
        only forces are gravity, the rotor wrench and contacts.
        """
        cid = self._cid
        n = positions.shape[0]
        yaws = np.zeros(n) if yaws is None else yaws
        flags = pb.URDF_MERGE_FIXED_LINKS | pb.URDF_USE_INERTIA_FROM_FILE
        for i in range(n):
            orn = pb.getQuaternionFromEuler([0.0, 0.0, float(yaws[i])])
            with _quiet_stdout():
                body = pb.loadURDF(
                    str(urdf), basePosition=positions[i].tolist(), baseOrientation=orn, flags=flags, physicsClientId=cid
                )
            # Low friction and compliant contacts (as with propeller guards): a bump pushes an
            # airframe aside instead of levering it over in one physics step.
            pb.changeDynamics(
                body,
                -1,
                mass=float(mass),
                localInertiaDiagonal=[float(v) for v in inertia],
                linearDamping=0.0,
                angularDamping=0.0,
                lateralFriction=0.2,
                contactStiffness=contact_stiffness,
                contactDamping=contact_damping,
                physicsClientId=cid,
            )
            self._agents.append(body)
            self._register(body, BodyKind.AGENT, f"agent{i}")
        self._poses = [self._get_pose(b, cid)[0] for b in self._agents]

    def set_agent_collisions(self, enabled: bool) -> None:
        """Enable or disable contact response between agents; disabled, every pair of agents is a ghost
        pair (``set_ghost_pair``): they pass through each other and their overlaps are still reported."""
        for a, b in itertools.combinations(self._agents, 2):
            self.set_ghost_pair(a, b, not enabled)

    def _register(self, body: int, kind: BodyKind, name: str) -> None:
        self._kind[body] = kind
        self._names[body] = name

    def body_kind(self, body: int) -> BodyKind:
        """Kind of a body handle."""
        return self._kind[body]

    def body_name(self, body: int) -> str:
        """Name of a body handle."""
        return self._names[body]

    @property
    def agent_bodies(self) -> tuple[int, ...]:
        """Body handles of the agents, in agent order."""
        return tuple(self._agents)

    @property
    def n_agents(self) -> int:
        """Number of agents."""
        return len(self._agents)

    # ------------------------------------------------------------------- state
    def read_agent_states(self, out: NDArray[np.float64]) -> None:
        """Read every agent's state into ``out`` (n, 13): position m, quaternion (x, y, z, w),
        linear velocity m/s and angular velocity rad/s, both in the world frame."""
        cid = self._cid
        gp, gv = self._get_pose, self._get_vel
        poses: list[Any] = []
        keep = poses.append
        flat: list[float] = []
        for b in self._agents:
            pos, orn = gp(b, cid)
            vel, ang = gv(b, cid)
            keep(pos)
            flat += pos
            flat += orn
            flat += vel
            flat += ang
        self._poses = poses
        out.reshape(-1)[:] = flat
        self._states = out

    def apply_agent_wrenches(self, forces: NDArray[np.float64], torques: NDArray[np.float64]) -> None:
        """Apply one world-frame force at the centre of mass and one torque per agent.

        Forces (n, 3) N and torques (n, 3) N m act during the next physics step only; the
        points of application come from the last ``read_agent_states``.
        """
        cid = self._cid
        af, at = self._apply_force, self._apply_torque
        wf = pb.WORLD_FRAME
        for b, f, pos, t in zip(self._agents, forces.tolist(), self._poses, torques.tolist()):
            af(b, -1, f, pos, wf, cid)
            at(b, -1, t, wf, cid)

    @property
    def dynamic_boxes(self) -> dict[int, tuple[float, float, float]]:
        """Every box with a mass (a task's movable object): body handle -> edges (3,) m."""
        return dict(self._box_sizes)

    def apply_body_forces(self, bodies: Sequence[int], forces: NDArray[np.float64]) -> None:
        """Apply one world-frame force (k, 3) N at the centre of mass of each of ``bodies``, for the next step."""
        cid, af, wf, gp = self._cid, self._apply_force, pb.WORLD_FRAME, self._get_pose
        for b, f in zip(bodies, forces.tolist()):
            af(b, -1, f, gp(b, cid)[0], wf, cid)

    def step(self) -> None:
        """Advance the physics by one time step."""
        self._step(self._cid)
        self._version += 1

    @property
    def state_version(self) -> int:
        """A counter that changes whenever a body may have moved (a physics step, a teleport): states read at
        one value are still the states while it holds it."""
        return self._version

    def read_body_poses(self, bodies: Sequence[int], out: NDArray[np.float64]) -> None:
        """Read the poses of ``bodies`` into ``out`` (k, 7): position m and quaternion (x, y, z, w)."""
        cid, gp = self._cid, self._get_pose
        flat: list[float] = []
        for b in bodies:
            pos, orn = gp(b, cid)
            flat += pos
            flat += orn
        out.reshape(-1)[:] = flat

    def read_body_velocities(self, bodies: Sequence[int], out: NDArray[np.float64]) -> None:
        """Read the velocities of ``bodies`` into ``out`` (k, 6): linear m/s and angular rad/s, world frame."""
        cid, gv = self._cid, self._get_vel
        flat: list[float] = []
        for b in bodies:
            vel, ang = gv(b, cid)
            flat += vel
            flat += ang
        out.reshape(-1)[:] = flat

    def contact_pairs(self) -> frozenset[tuple[int, int]] | set[tuple[int, int]]:
        """Body pairs (a < b) in contact now: Bullet's contacts (one query) and the ghost pairs whose
        shapes overlap (``set_ghost_pair``), as if their contacts were enabled."""
        pts = self._contacts(-1, -1, -2, -2, self._cid)
        pairs: frozenset[tuple[int, int]] | set[tuple[int, int]] = _NO_PAIRS
        if pts:
            pairs = {(p[1], p[2]) if p[1] < p[2] else (p[2], p[1]) for p in pts}
        if self._ghost_pairs:
            extra = self.ghost_overlaps()
            if extra:
                pairs = set(pairs)
                pairs.update(extra)
        return pairs

    def ghost_overlaps(self) -> list[tuple[int, int]]:
        """Ghost pairs (a < b) whose collision shapes overlap now.

        One broad phase for all bodies of ghost pairs (bounding spheres about their base positions;
        agents' positions from the last ``read_agent_states``, other bodies' read now), then Bullet's
        exact closest-points query only for registered pairs whose spheres overlap. With a ``ghost_horizon``
        of h > 1 steps and more ghost bodies than one vectorised test of every pair is quick for
        (``_GhostIndex.DENSE_MAX_BODIES``), the broad phase runs once per h steps, its spheres grown by how far
        each body can move in that time (``_plan_ghosts``), and the exact query runs every step on the pairs
        it found (fewer bodies: the grown spheres' extra exact queries cost more than the broad phase saves).
        """
        g = self._ghosts if self._ghosts is not None else self._index_ghosts()
        if self.ghost_horizon > 1 and not g.dense:
            plan = self._ghost_plan
            if plan is None or self._version - plan[0] >= self.ghost_horizon:
                plan = self._plan_ghosts(g)
            if plan is not None:
                return self._overlapping(plan)
        return self._touching(g.near_pairs(self._ghost_centres(g)))

    def _touching(self, pairs: Iterable[tuple[int, int]]) -> list[tuple[int, int]]:
        """The pairs of ``pairs`` that Bullet's exact closest-points query finds touching or overlapping now."""
        cid, closest = self._cid, self._closest
        return [(a, b) for a, b in pairs if closest(a, b, 0.0, physicsClientId=cid)]

    def _ghost_centres(self, g: _GhostIndex) -> NDArray[np.float64]:
        """(k, 3) m, base positions of the ghost bodies now, agents first (``g.centres``, filled)."""
        c, m = g.centres, g.n_agents
        if m:
            states = self._states if self._states is not None else np.array(self._poses, dtype=float)
            c[:m] = states[g.agent_rows, :3]
        if g.others:
            gp, cid = self._get_pose, self._cid
            c[m:] = [gp(b, cid)[0] for b in g.others]
        return c

    def _plan_ghosts(self, g: _GhostIndex) -> _GhostPlan | None:
        """Broad phase for the next ``ghost_horizon`` steps: the registered pairs whose bounding spheres, each
        grown by the farthest its body can move in that time (speed now times the horizon, plus half
        ``GHOST_MAX_ACCELERATION`` times its square), overlap now. No other pair can overlap before the
        horizon ends, so the exact query on these alone finds what a broad phase every step would.
        None (a broad phase every step) while the agents' velocities are unknown (after a teleport).

        Each run also checks the last one's bound: a body farther from where it was than it could have moved
        is counted in ``ghost_bound_exceeded``, and from then on the broad phase runs every step.
        """
        if self._states is None:
            return None
        c = self._ghost_centres(g).copy()
        v = np.empty_like(c)
        m = g.n_agents
        v[:m] = self._states[g.agent_rows, 7:10]
        if g.others:
            gv, cid = self._get_vel, self._cid
            v[m:] = [gv(b, cid)[0] for b in g.others]
        tau = self.ghost_horizon / self.physics_hz
        grow = np.sqrt(np.einsum("ij,ij->i", v, v)) * tau + 0.5 * self.GHOST_MAX_ACCELERATION * tau * tau
        last = self._ghost_plan
        if last is not None and self._version - last[0] == self.ghost_horizon:
            d = c - last[2]
            if np.any(np.einsum("ij,ij->i", d, d) > last[3] * last[3]):
                self.ghost_bound_exceeded += 1
                self.ghost_horizon = 1
                self._ghost_plan = None
                return None
        pairs = g.near_pairs(c, grow)
        self._ghost_plan = (self._version, pairs, c, grow, self._agent_pair_test(g, pairs))
        return self._ghost_plan

    #: from this many candidate pairs of a broad phase over a horizon on, those of two agents are tested with
    #: their bounding spheres every step (one vectorised test) before Bullet's exact query
    SPHERE_TEST_MIN_PAIRS = 8

    def _agent_pair_test(self, g: _GhostIndex, pairs: list[tuple[int, int]]) -> _AgentPairTest | None:
        """The per-step sphere test of the candidate pairs of two agents (None when there are few candidates)."""
        if len(pairs) < self.SPHERE_TEST_MIN_PAIRS:
            return None
        at = {b: k for k, b in enumerate(g.bodies.tolist())}
        rows = np.arange(len(self._agents))[g.agent_rows]
        m = g.n_agents
        which = [k for k, (a, b) in enumerate(pairs) if at[a] < m and at[b] < m]
        if not which:
            return None
        i = np.array([at[pairs[k][0]] for k in which], dtype=np.int64)
        j = np.array([at[pairs[k][1]] for k in which], dtype=np.int64)
        limit2 = (g.reach[i] + g.reach[j] + g.SLACK) ** 2
        return _AgentPairTest(np.asarray(which, dtype=np.int64), rows[i], rows[j], limit2, len(pairs))

    def _overlapping(self, plan: _GhostPlan) -> list[tuple[int, int]]:
        """The candidate pairs of a broad phase over a horizon that overlap now (Bullet's exact query; the pairs
        of two agents first tested with their bounding spheres about the agents' positions now, when many)."""
        pairs, test = plan[1], plan[4]
        if test is None or self._states is None:
            return self._touching(pairs)
        s = self._states
        d = s[test.rows_a, :3] - s[test.rows_b, :3]
        keep = np.ones(test.n_pairs, dtype=bool)
        keep[test.which] = np.einsum("ij,ij->i", d, d) <= test.limit2
        return self._touching(p for p, k in zip(pairs, keep.tolist()) if k)

    def set_ghost_pair(self, a: int, b: int, ghost: bool) -> None:
        """Make two bodies ghosts of each other (``ghost``): no contact response between them, but their
        overlaps are reported by ``contact_pairs`` as contacts; or give them contacts again."""
        pb.setCollisionFilterPair(a, b, -1, -1, int(not ghost), physicsClientId=self._cid)
        self._set_ghost(a, b, ghost)

    @property
    def ghost_pairs(self) -> frozenset[tuple[int, int]]:
        """The registered ghost pairs (a < b)."""
        return frozenset(self._ghost_pairs)

    def _set_ghost(self, a: int, b: int, ghost: bool) -> None:
        key = (a, b) if a < b else (b, a)
        if ghost:
            self._ghost_pairs.add(key)
        else:
            self._ghost_pairs.discard(key)
        self._ghosts = None
        self._ghost_plan = None

    def _index_ghosts(self) -> _GhostIndex:
        bodies = {b for pair in self._ghost_pairs for b in pair}
        agents = [b for b in self._agents if b in bodies]
        others = sorted(bodies.difference(agents))
        row = {b: i for i, b in enumerate(self._agents)}
        reach = np.array([self._body_reach(b) for b in agents + others])
        self._ghosts = _GhostIndex([row[b] for b in agents], agents, others, reach, self._ghost_pairs)
        return self._ghosts

    def _body_reach(self, body: int) -> float:
        """m, an upper bound of the distance from a body's base position to any point of its collision shape
        (the farthest corner of its bounding box; the shape is rigid, so it holds in any pose)."""
        if body not in self._reach:
            lo, hi = pb.getAABB(body, -1, physicsClientId=self._cid)
            pos = np.asarray(pb.getBasePositionAndOrientation(body, physicsClientId=self._cid)[0])
            corners = np.array(list(itertools.product(*zip(lo, hi))))
            self._reach[body] = float(np.max(np.linalg.norm(corners - pos, axis=1)))
        return self._reach[body]

    def reset_agent(
        self,
        index: int,
        position: Sequence[float],
        quaternion: Sequence[float] = (0, 0, 0, 1),
        velocity: Sequence[float] = (0, 0, 0),
        angular_velocity: Sequence[float] = (0, 0, 0),
    ) -> None:
        """Teleport an agent to a state (for tests and environment resets)."""
        b = self._agents[index]
        pb.resetBasePositionAndOrientation(b, list(position), list(quaternion), physicsClientId=self._cid)
        pb.resetBaseVelocity(b, list(velocity), list(angular_velocity), physicsClientId=self._cid)
        self._poses[index] = tuple(float(v) for v in position)
        self._states = None  # no longer what the agents' states are
        self._version += 1
        self._ghost_plan = None  # a teleport is no motion the broad phase bounded

    def reset_body(self, body: int, position: Sequence[float], quaternion: Sequence[float] = (0, 0, 0, 1)) -> None:
        """Teleport any body to a pose, at rest."""
        pb.resetBasePositionAndOrientation(
            body, list(map(float, position)), list(map(float, quaternion)), physicsClientId=self._cid
        )
        pb.resetBaseVelocity(body, [0, 0, 0], [0, 0, 0], physicsClientId=self._cid)
        self._version += 1
        self._ghost_plan = None  # a teleport is no motion the broad phase bounded
        if self._kind.get(body) is BodyKind.AGENT:
            self._poses[self._agents.index(body)] = tuple(float(v) for v in position)
            self._states = None

    def body_pose(self, body: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Position (3,) m and quaternion (4,) of any body."""
        pos, orn = pb.getBasePositionAndOrientation(body, physicsClientId=self._cid)
        return np.asarray(pos), np.asarray(orn)

    def body_velocity(self, body: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Linear (3,) m/s and angular (3,) rad/s velocity of any body, world frame."""
        v, w = pb.getBaseVelocity(body, physicsClientId=self._cid)
        return np.asarray(v), np.asarray(w)

    def body_mass(self, body: int) -> float:
        """Mass of a body as Bullet holds it, kg."""
        return float(pb.getDynamicsInfo(body, -1, physicsClientId=self._cid)[0])

    def set_body_mass(self, body: int, mass: float) -> None:
        """Change a body's mass, kg (for payload experiments)."""
        pb.changeDynamics(body, -1, mass=float(mass), physicsClientId=self._cid)

    # ------------------------------------------------------------ constraints
    def attach(self, parent: int, child: int, max_force: float = 2.0, square: bool = False) -> int:
        """Hold ``child`` rigidly to ``parent`` at their current relative pose; returns a handle.

        ``max_force`` (N) is the grip: a harder pull (a collision) makes the held body slip. With
        ``square`` the child (a cube) is held as a self-centring square jaw grips it: at the
        quarter-turn orientation nearest to its own relative to the parent, its faces parallel to the
        parent's axes, and centred on the parent's vertical (body z) axis at the depth it was gripped;
        the grip turns and slides it there.
        """
        cid = self._cid
        self.wake(child)
        pp, po = pb.getBasePositionAndOrientation(parent, physicsClientId=cid)
        cp, co = pb.getBasePositionAndOrientation(child, physicsClientId=cid)
        ip, io = pb.invertTransform(pp, po)
        rel_p, rel_o = pb.multiplyTransforms(ip, io, cp, co)
        if square:
            rel_o = _nearest_quarter_turn(rel_o)
            rel_p = (0.0, 0.0, rel_p[2])
        c = pb.createConstraint(
            parent,
            -1,
            child,
            -1,
            pb.JOINT_FIXED,
            [0, 0, 0],
            rel_p,
            [0, 0, 0],
            parentFrameOrientation=rel_o,
            physicsClientId=cid,
        )
        pb.changeConstraint(c, maxForce=float(max_force), physicsClientId=cid)
        self._held[c] = (child, parent)
        return c

    def holder(self, body: int) -> int | None:
        """The body that holds ``body`` through ``attach`` (a carried box's carrier), or None."""
        for child, parent in self._held.values():
            if child == body:
                return parent
        return None

    def pin(
        self, body: int, position: Sequence[float], quaternion: Sequence[float] | None = None, max_force: float = 1.0
    ) -> int:
        """Hold ``body`` at a world pose with a constraint of at most ``max_force`` N; returns a handle.

        A weak pin pulls the body there (a guide), a strong one keeps it there (a bond); either
        gives way to a harder push and pulls back once it stops. ``quaternion`` None: the quarter
        turn nearest to the body's own orientation (for a cube, the same shape, unturned).
        """
        cid = self._cid
        self.wake(body)
        if quaternion is None:
            quaternion = _nearest_quarter_turn(pb.getBasePositionAndOrientation(body, physicsClientId=cid)[1])
        c = pb.createConstraint(
            body,
            -1,
            -1,
            -1,
            pb.JOINT_FIXED,
            [0, 0, 0],
            [0, 0, 0],
            [float(v) for v in position],
            childFrameOrientation=[float(v) for v in quaternion],
            physicsClientId=cid,
        )
        pb.changeConstraint(c, maxForce=float(max_force), physicsClientId=cid)
        return int(c)

    def set_constraint_force(self, constraint: int, max_force: float) -> None:
        """Change the largest force N a constraint made by ``attach`` or ``pin`` applies."""
        pb.changeConstraint(constraint, maxForce=float(max_force), physicsClientId=self._cid)

    def set_pair_collision(self, a: int, b: int, enabled: bool) -> None:
        """Enable or disable contacts between two bodies; disabled, their overlaps are not reported either
        (a held load and its carrier; see ``set_ghost_pair`` for pairs whose overlaps count)."""
        pb.setCollisionFilterPair(a, b, -1, -1, int(enabled), physicsClientId=self._cid)
        self._set_ghost(a, b, False)

    def overlapping(self, a: int, b: int) -> bool:
        """True when two bodies' collision shapes overlap (works with their contacts disabled)."""
        return bool(pb.getClosestPoints(a, b, 0.0, physicsClientId=self._cid))

    def detach(self, constraint: int) -> None:
        """Remove a constraint made by ``attach``."""
        pb.removeConstraint(constraint, physicsClientId=self._cid)
        self._held.pop(constraint, None)

    # --------------------------------------------------------------- sensing
    def ray_cast(
        self, starts: NDArray[np.float64], ends: NDArray[np.float64]
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Cast rays in one batched call; returns hit body handles (m,) (-1 for none) and hit fractions (m,)."""
        out = pb.rayTestBatch(starts.tolist(), ends.tolist(), physicsClientId=self._cid)
        hits = np.fromiter((r[0] for r in out), dtype=np.int64, count=len(out))
        frac = np.fromiter((r[2] for r in out), dtype=float, count=len(out))
        return hits, frac

    # ------------------------------------------------------------- rendering
    def render(
        self, width: int, height: int, *, target: Sequence[float], distance: float, yaw: float, pitch: float
    ) -> NDArray[np.uint8]:
        """Render an RGB frame (height, width, 3) with the tiny software renderer (works in DIRECT)."""
        cid = self._cid
        view = pb.computeViewMatrixFromYawPitchRoll(list(target), distance, yaw, pitch, 0.0, 2, physicsClientId=cid)
        proj = pb.computeProjectionMatrixFOV(50.0, width / height, 0.05, 50.0, physicsClientId=cid)
        img = pb.getCameraImage(
            width,
            height,
            view,
            proj,
            renderer=pb.ER_TINY_RENDERER,
            shadow=0,
            flags=pb.ER_NO_SEGMENTATION_MASK,
            physicsClientId=cid,
        )
        rgba = np.reshape(np.asarray(img[2], dtype=np.uint8), (height, width, 4))
        return rgba[:, :, :3]

    # ------------------------------------------------------------ GUI overlays
    def set_camera(self, target: Sequence[float], distance: float, yaw: float, pitch: float) -> None:
        """Point the GUI's camera at ``target`` (3,) m from ``distance`` m, ``yaw`` and ``pitch`` deg
        (Bullet's convention: yaw 0 looks along +y); nothing happens in DIRECT mode."""
        if self.gui:
            pb.resetDebugVisualizerCamera(
                float(distance), float(yaw), float(pitch), [float(v) for v in target], physicsClientId=self._cid
            )

    def set_color(self, body: int, rgba: Sequence[float]) -> None:
        """Colour every visual shape of a body (RGBA in [0, 1])."""
        pb.changeVisualShape(body, -1, rgbaColor=[float(v) for v in rgba], physicsClientId=self._cid)

    def debug_text(
        self,
        text: str,
        position: Sequence[float],
        *,
        color: Sequence[float] = (0.0, 0.0, 0.0),
        size: float = 1.4,
        replace: int = -1,
    ) -> int:
        """Show ``text`` at ``position`` (3,) m in the GUI (replacing the item ``replace``); returns the
        item's id, -1 in DIRECT mode (where nothing is drawn)."""
        if not self.gui:
            return -1
        kw = {"replaceItemUniqueId": replace} if replace >= 0 else {}
        return int(
            pb.addUserDebugText(
                text,
                [float(v) for v in position],
                textColorRGB=[float(c) for c in color[:3]],
                textSize=float(size),
                physicsClientId=self._cid,
                **kw,
            )
        )

    def debug_line(
        self,
        start: Sequence[float],
        end: Sequence[float],
        *,
        color: Sequence[float] = (1.0, 0.0, 0.0),
        width: float = 2.0,
        lifetime: float = 0.0,
    ) -> int:
        """Draw a line from ``start`` to ``end`` (3,) m in the GUI for ``lifetime`` s of wall-clock time (0:
        until removed); returns its id, -1 in DIRECT mode (where nothing is drawn)."""
        if not self.gui:
            return -1
        return int(
            pb.addUserDebugLine(
                [float(v) for v in start],
                [float(v) for v in end],
                lineColorRGB=[float(c) for c in color[:3]],
                lineWidth=float(width),
                lifeTime=float(lifetime),
                physicsClientId=self._cid,
            )
        )

    def debug_points(
        self,
        points: NDArray[np.float64],
        colors: Sequence[Sequence[float]],
        *,
        size: float = 4.0,
        lifetime: float = 0.0,
    ) -> int:
        """Draw points (k, 3) m in RGB ``colors`` (k, 3) in the GUI for ``lifetime`` s of wall-clock time (0:
        until removed), in one call; returns the item's id, -1 in DIRECT mode (where nothing is drawn)."""
        if not self.gui or len(points) == 0:
            return -1
        return int(
            pb.addUserDebugPoints(
                np.asarray(points, dtype=float).tolist(),
                [[float(c) for c in rgb[:3]] for rgb in colors],
                pointSize=float(size),
                lifeTime=float(lifetime),
                physicsClientId=self._cid,
            )
        )

    def close(self) -> None:
        """Disconnect the client (idempotent)."""
        if self._cid >= 0:
            try:
                pb.disconnect(physicsClientId=self._cid)
            except pb.error:
                pass
            self._cid = -1

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass


class _GhostIndex:
    """The bodies of the registered ghost pairs and the per-step broad phase over them.

    Args:
        agent_rows: (m,) row of each ghost agent in the world's agent order.
        agents: (m,) their body handles.
        others: handles of the ghost bodies that are not agents (their positions are read each step).
        reach: (m + len(others),) m, bounding-sphere radius of each body about its base position, agents first.
        pairs: the registered ghost pairs (a < b) of body handles.
    """

    #: up to this many bodies, one vectorised test of every registered pair's spheres; beyond, a k-d tree
    #: (``sphere_pairs``) finds the overlapping spheres, and the registered pairs among them are kept
    DENSE_MAX_BODIES = 48  # where the two cost about the same (about 27 us a step on this machine)
    SLACK = 0.01  # m, added to the sum of two bounding radii

    def __init__(
        self,
        agent_rows: list[int],
        agents: list[int],
        others: list[int],
        reach: NDArray[np.float64],
        pairs: set[tuple[int, int]],
    ) -> None:
        bodies = agents + others
        self.bodies = np.asarray(bodies, dtype=np.int64)
        m = len(agent_rows)
        self.n_agents = m
        # agents' rows in the state array; a slice when they are the first m agents (a view, no gather)
        self.agent_rows: slice | NDArray[np.int64] = (
            slice(0, m) if agent_rows == list(range(m)) else np.asarray(agent_rows, dtype=np.int64)
        )
        self.others = others
        self.reach = reach
        self.pairs = frozenset(pairs)
        self.centres = np.zeros((len(bodies), 3))  # m, filled each step
        self.dense = len(bodies) <= self.DENSE_MAX_BODIES
        if self.dense:  # every registered pair (handles a < b): its squared reach, and +1 / -1 at its bodies
            at = {b: i for i, b in enumerate(bodies)}
            self.ab = sorted(pairs)
            i = np.array([at[a] for a, _ in self.ab], dtype=np.int64)
            j = np.array([at[b] for _, b in self.ab], dtype=np.int64)
            self.pair_index = (i, j)
            self.limit2 = (reach[i] + reach[j] + self.SLACK) ** 2
            # (p, k): one matrix product gives every pair's separation (faster than gathers on small arrays)
            self.difference = np.zeros((len(i), len(bodies)))
            self.difference[np.arange(len(i)), i] = 1.0
            self.difference[np.arange(len(i)), j] = -1.0

    def near_pairs(
        self, centres: NDArray[np.float64], grow: NDArray[np.float64] | None = None
    ) -> list[tuple[int, int]]:
        """Registered pairs (a < b) whose bounding spheres overlap, given the base positions (k, 3) m (and
        ``grow`` (k,) m added to each body's radius)."""
        if self.dense:
            limit2 = self.limit2
            if grow is not None:
                i, j = self.pair_index
                limit2 = (self.reach[i] + self.reach[j] + self.SLACK + grow[i] + grow[j]) ** 2
            d = self.difference @ centres
            d *= d
            near = d @ _ONES3 <= limit2
            if not near.any():
                return []
            ab = self.ab
            return [ab[k] for k in np.flatnonzero(near).tolist()]
        i, j = sphere_pairs(centres, self.reach if grow is None else self.reach + grow, self.SLACK)
        a, b = self.bodies[i], self.bodies[j]
        lo, hi = np.minimum(a, b).tolist(), np.maximum(a, b).tolist()
        pairs = self.pairs
        return [p for p in zip(lo, hi) if p in pairs]


_ONES3 = np.ones(3)


def sphere_pairs(
    centres: NDArray[np.float64], radii: NDArray[np.float64], slack: float = 0.0
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Index pairs (i, j), i < j, of spheres (centres (k, 3) m, radii (k,) m) that overlap within ``slack`` m.

    One k-d tree query for the pairs within the largest reach (compiled, no loop over spheres), then each
    candidate tested with its own radii.
    """
    from scipy.spatial import cKDTree

    empty = np.zeros(0, dtype=np.int64)
    if len(centres) < 2:
        return empty, empty
    ij = cKDTree(centres).query_pairs(2.0 * float(np.max(radii)) + slack, output_type="ndarray")
    i, j = ij[:, 0].astype(np.int64), ij[:, 1].astype(np.int64)
    d = centres[i] - centres[j]
    keep = np.einsum("ij,ij->i", d, d) <= (radii[i] + radii[j] + slack) ** 2
    return i[keep], j[keep]


def _nearest_quarter_turn(q: Any) -> tuple[float, float, float, float]:
    """The rotation of the cube's symmetry group (axes onto axes) nearest to the rotation ``q``
    (x, y, z, w)."""
    from scipy.spatial.transform import Rotation

    R = np.array(pb.getMatrixFromQuaternion(q)).reshape(3, 3)
    S = np.zeros((3, 3))
    rows, cols = [0, 1, 2], [0, 1, 2]
    for _ in range(3):  # greedily give each box axis the parent axis it is most parallel to
        a, b = np.unravel_index(int(np.argmax(np.abs(R[np.ix_(rows, cols)]))), (len(rows), len(cols)))
        r, c = rows.pop(a), cols.pop(b)
        S[r, c] = 1.0 if R[r, c] >= 0.0 else -1.0
    if np.linalg.det(S) < 0.0:  # a tie near 45 deg: flip the least certain of the three choices
        r, c = min(zip(*np.nonzero(S)), key=lambda rc: abs(R[rc]))
        S[r, c] = -S[r, c]
    x, y, z, w = Rotation.from_matrix(S).as_quat()
    return (float(x), float(y), float(z), float(w))
