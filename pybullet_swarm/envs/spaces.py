"""The documented observation layout: each agent's local ``Observation`` flattened into one vector.

One row per agent, float32, blocks in this order (a block is absent when its size is 0):

| block | size | content (world frame, SI units) | bounds |
|---|---|---|---|
| ``own`` | 14 | position (3) m; velocity (3) m/s; roll, pitch, yaw (3) rad; body rates (3) rad/s; carrying a box (1) 0/1; elapsed time / time limit (1) | arena box with margins; +-10 m/s; +-pi; +-50 rad/s; [0, 1]; [0, 1] |
| ``goal`` | 3 | active set-point - position, m (waypoint tasks only) | +-``far`` |
| ``neighbours`` | 7 k | per neighbour within the sensing radius, nearest first: relative position (3) m, relative velocity (3) m/s, present (1) | +-radius; +-20 m/s; [0, 1] |
| ``boxes`` | 4 kb | per visible free box, nearest first: box centre - position (3) m, present (1) (construction) | +-(view radius + 2 grasp height) |
| ``slots`` | 4 ks | per visible open slot, nearest first: slot centre - position (3) m, present (1) (construction) | as boxes |
| ``points`` | 4 kp | per point not yet passed or visited, nearest first: point - position (3) m, present (1) (route, tour) | +-``far`` |
| ``ranges`` | r | range readings of the last planner tick, m (when the agents have range sensors) | [0, max range] |

Own state is what the agent knows of itself (the estimate when the scenario flies on estimated
state, else the truth); neighbours come from the same perception stage as the planners'
(``pybullet_swarm.sensing.perception``), chosen and measured from their true positions with no
noise drawn, so that observing does not change the run's random stream. Boxes and slots are the
task's local views (what each agent sees, relative to where its airframe is); points are the
task's points not yet passed or visited (route and tour tasks). Absent entries (fewer neighbours than k, ...) are zeros with ``present`` 0. Values outside the
bounds (an agent that left the arena) are clipped, so every observation lies in its space.
``ObservationLayout.slice(name)`` gives a block's columns.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pybullet_swarm.envs.kernels import clip_rows, fill_own
from pybullet_swarm.sensing.perception import PerceptionStage
from pybullet_swarm.planning.views.construction import ConstructionLayout, boxes_of
from pybullet_swarm.planning.views.points import points_of
from pybullet_swarm.planning.views.waypoints import set_points_of

OWN_SIZE = 14
VELOCITY_BOUND = 10.0  # m/s, own velocity
RELATIVE_VELOCITY_BOUND = 20.0  # m/s, neighbour velocity relative to the agent
RATE_BOUND = 50.0  # rad/s, body rates
RANGE_BOUND = 100.0  # m, range readings


@dataclasses.dataclass(frozen=True)
class ObservationLayout:
    """Named blocks of an observation row and their bounds.

    Attributes:
        blocks: (name, start, stop) column ranges in order.
        low: (dim,) lower bounds.
        high: (dim,) upper bounds.
        neighbours: k, neighbour slots.
        boxes: kb, box slots.
        slots: ks, slot slots.
        points: kp, tour point slots.
        ranges: r, range readings.
    """

    blocks: tuple[tuple[str, int, int], ...]
    low: NDArray[np.float32]
    high: NDArray[np.float32]
    neighbours: int
    boxes: int
    slots: int
    points: int
    ranges: int

    @property
    def dim(self) -> int:
        """Length of one observation row."""
        return int(self.low.shape[0])

    def slice(self, name: str) -> slice:
        """Columns of block ``name`` (``own``, ``goal``, ``neighbours``, ``boxes``, ``slots``, ``points``, ``ranges``)."""
        for block, start, stop in self.blocks:
            if block == name:
                return slice(start, stop)
        raise KeyError(f"no block {name!r} in this layout; blocks: {', '.join(b for b, _, _ in self.blocks)}")

    def describe(self) -> list[dict[str, Any]]:
        """The blocks as plain data (name, start, stop)."""
        return [{"name": b, "start": s, "stop": e} for b, s, e in self.blocks]


def _nearest(
    rel: NDArray[np.float64], valid: NDArray[np.bool_], k: int
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The k nearest valid vectors per row: rel (n, m, 3), valid (n, m) -> (n, k, 3), (n, k); absent ones zero."""
    n, m = valid.shape
    out = np.zeros((n, k, 3))
    present = np.zeros((n, k), dtype=bool)
    if m == 0 or k == 0:
        return out, present
    key = np.where(valid, np.einsum("nmi,nmi->nm", rel, rel), np.inf)
    order = np.argsort(key, axis=1, kind="stable")[:, :k]
    kk = order.shape[1]
    present[:, :kk] = np.take_along_axis(valid, order, axis=1)
    out[:, :kk] = np.take_along_axis(rel, order[:, :, None], axis=1)
    out[~present] = 0.0
    return out, present


class ObservationBuilder:
    """Builds the (n, dim) observation matrix of all agents at once from a ``Simulation``.

    Args:
        sim: the simulation (its scenario and task decide which blocks exist).
        neighbours: k nearest neighbours (capped at n - 1).
        boxes: nearest visible free boxes (construction only).
        slots: nearest visible open slots (construction only).
        points: nearest unvisited tour points (tour only).
        ranges: number of range readings per agent (0: none).
        range_bound: m, upper bound of a range reading.
    """

    def __init__(
        self,
        sim: Any,
        *,
        neighbours: int,
        boxes: int,
        slots: int,
        points: int,
        ranges: int = 0,
        range_bound: float = RANGE_BOUND,
    ) -> None:
        sc = sim.scenario
        self.n = sim.n
        lx, ly = (float(v) for v in sc.arena.size)
        ceiling = float(sc.arena.height) if sc.arena.height is not None else 5.0
        self.far = max(3.0 * lx, 3.0 * ly, 2.0 * ceiling + 1.0)  # m, bound of long relative vectors
        self.radius = float(sc.agents.sensing_radius)
        self.k = min(int(neighbours), self.n - 1)
        self.stage = PerceptionStage(self.n, self.radius)  # no neighbour noise: observing draws nothing
        task = sim.task.view(sim.time)
        info = sim.info
        shown = set_points_of(task)
        self.waypoints = shown is not None and len(shown.targets) == self.n
        shows = boxes_of(task)
        has_objects = len(shows.objects) > 0 and len(shows.slots) > 0
        self.kb = int(boxes) if has_objects else 0
        self.ks = int(slots) if has_objects else 0
        self.kp = int(points) if len(points_of(task).points) > 0 else 0
        self.r = int(ranges)
        view = 0.0
        if has_objects and isinstance(info.layout, ConstructionLayout):
            view = float(info.layout.view_radius) + 2.0 * float(info.layout.grasp_height)
        pi = math.pi
        pos_low, pos_high = [-lx, -ly, -1.0], [2.0 * lx, 2.0 * ly, 2.0 * ceiling]
        parts: list[tuple[str, list[float], list[float]]] = [
            (
                "own",
                pos_low + [-VELOCITY_BOUND] * 3 + [-pi, -pi / 2, -pi] + [-RATE_BOUND] * 3 + [0.0, 0.0],
                pos_high + [VELOCITY_BOUND] * 3 + [pi, pi / 2, pi] + [RATE_BOUND] * 3 + [1.0, 1.0],
            ),
        ]
        if self.waypoints:
            parts.append(("goal", [-self.far] * 3, [self.far] * 3))
        r, rv = self.radius, RELATIVE_VELOCITY_BOUND
        if self.k:
            parts.append(("neighbours", ([-r] * 3 + [-rv] * 3 + [0.0]) * self.k, ([r] * 3 + [rv] * 3 + [1.0]) * self.k))
        if self.kb:
            parts.append(("boxes", ([-view] * 3 + [0.0]) * self.kb, ([view] * 3 + [1.0]) * self.kb))
        if self.ks:
            parts.append(("slots", ([-view] * 3 + [0.0]) * self.ks, ([view] * 3 + [1.0]) * self.ks))
        if self.kp:
            f = self.far
            parts.append(("points", ([-f] * 3 + [0.0]) * self.kp, ([f] * 3 + [1.0]) * self.kp))
        if self.r:
            parts.append(("ranges", [0.0] * self.r, [float(range_bound)] * self.r))
        blocks, start = [], 0
        for name, lo, _hi in parts:
            blocks.append((name, start, start + len(lo)))
            start += len(lo)
        low = np.concatenate([np.asarray(lo, dtype=np.float32) for _, lo, _ in parts])
        high = np.concatenate([np.asarray(hi, dtype=np.float32) for _, _, hi in parts])
        self.layout = ObservationLayout(tuple(blocks), low, high, self.k, self.kb, self.ks, self.kp, self.r)
        self._low = low.astype(np.float64)  # float32 bounds, exactly, for clipping in float64
        self._high = high.astype(np.float64)
        self._sl = {name: slice(s, e) for name, s, e in blocks}
        self._goal = self._sl.get("goal", slice(0, 0))
        self._not_carrying = np.zeros(self.n)

    def build(self, sim: Any, goal: NDArray[np.float64] | None = None) -> NDArray[np.float32]:
        """Observation rows (n, dim) float32 of every agent now.

        Args:
            sim: the simulation (its state arrays, task runtime and last range readings are read).
            goal: (n, 3) m, the active set-points (timed set-point tasks; taken from the task's view when None).
        """
        n = self.n
        task = sim.task.view(sim.time)
        pc = self.stage.snapshot(sim.time, sim.state_array, sim.sensed_state_array, sim.ranges, task.carrying)
        pos, vel = pc.positions, pc.velocities
        out = np.empty((n, self.layout.dim))
        carrying = (task.carrying >= 0).astype(np.float64)
        fill_own(out, sim.sensed_state_array, sim.controller.body_rates, carrying, sim.time / sim.time_limit)
        if self.waypoints:
            shown = set_points_of(task)
            assert shown is not None  # a waypoints task shows set-points at every tick
            out[:, self._goal] = (shown.targets if goal is None else goal) - pos
        if self.k:
            table = pc.nearest_table(self.k)[:, : self.k]  # (n, k), nearest first
            present = table >= 0
            j = np.where(present, table, 0)
            true = sim.state_array
            rel = np.where(present[:, :, None], true[j, :3] - pos[:, None, :], 0.0)
            rel_v = np.where(present[:, :, None], true[j, 7:10] - vel[:, None, :], 0.0)
            block = np.concatenate([rel, rel_v, present[:, :, None].astype(float)], axis=2)
            out[:, self._sl["neighbours"]] = block.reshape(n, -1)
        if self.kb or self.ks:
            local = sim.task.local_views(sim.state_array[:, :3], pos)
            if self.kb:
                out[:, self._sl["boxes"]] = _nearest_block([lv.boxes for lv in local], pos, self.kb)
            if self.ks:
                out[:, self._sl["slots"]] = _nearest_block([lv.slots for lv in local], pos, self.ks)
        if self.kp:
            pts = points_of(task)
            rel = pts.points[None, :, :] - pos[:, None, :]
            vec, present_p = _nearest(rel, np.broadcast_to(~pts.points_done, (n, len(pts.points))), self.kp)
            out[:, self._sl["points"]] = np.concatenate([vec, present_p[:, :, None]], axis=2).reshape(n, -1)
        if self.r:
            out[:, self._sl["ranges"]] = sim.ranges
        clip_rows(out, self._low, self._high)  # non-finite values (a diverged run) become 0
        return out.astype(np.float32)


def _nearest_block(seen: list[NDArray[np.float64]], pos: NDArray[np.float64], k: int) -> NDArray[np.float64]:
    """(n, 4 k) block of the k nearest of each agent's seen objects (per agent (m_i, 3) m): object -
    position (3) m and a present flag, nearest first; absent entries zero."""
    n = len(seen)
    m = max((len(x) for x in seen), default=0)
    rel = np.zeros((n, m, 3))
    valid = np.zeros((n, m), dtype=bool)
    for i, x in enumerate(seen):
        rel[i, : len(x)] = x - pos[i]
        valid[i, : len(x)] = True
    vec, present = _nearest(rel, valid, k)
    return np.concatenate([vec, present[:, :, None]], axis=2).reshape(n, -1)
