"""The construction task of the reference thesis: carry boxes from a depot into a structure.

Boxes are real rigid bodies. An agent that asks to GRASP within ``attach_threshold`` of a free
box's grasp point (straight above the box, at ``grasp_height``) holds it with a fixed
constraint; RELEASE removes the constraint and the box settles under gravity. A slot is open
when it is empty and every slot before it in the build order is filled: the slots under it, and
the lower slots whose column a box placed here would block for an agent of the run's airframe
(``tasks.build_order``); a box counts as placed when it rests within ``place_tolerance_m`` and
``place_tolerance_deg`` of a slot. The task is completed when every slot is filled and the
structure has stood still for ``settle_s``.

``structure`` and ``boxes`` are lists of box centres, or voxel layers and named shapes expanded
into such lists when the scenario is loaded (``tasks.layouts``).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

import numpy as np
import pydantic
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.metrics.collisions import CollisionClass
from pybullet_swarm.metrics.construction import task_lower_bound
from pybullet_swarm.planning.base import Action, Obstacles, TaskView, view_distance
from pybullet_swarm.planning.views.construction import (
    CARRIED,
    FREE,
    PLACED,
    ConstructionLayout,
    ConstructionLocalView,
    ConstructionState,
    ConstructionView,
)
from pybullet_swarm.tasks import register_task
from pybullet_swarm.tasks.base import NOT_MINE, Framing, ScenarioLike, TaskBase, TaskContext
from pybullet_swarm.tasks.build_order import REACH_MARGIN, Reach, build_order, prerequisites
from pybullet_swarm.tasks.layouts import expand_boxes
from pybullet_swarm.types import Event, TimeSeries
from pybullet_swarm.world import BodyKind, World

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]


def cube_half_extents(quaternions: NDArray[np.float64], size: float) -> NDArray[np.float64]:
    """Half extents (k, 3) m of the world-axis boxes around cubes of edge ``size`` m turned by ``quaternions`` (k, 4)
    (x, y, z, w)."""
    x, y, z, w = (np.asarray(quaternions, dtype=float).reshape(-1, 4)[:, k] for k in range(4))
    rows = np.stack(
        [
            np.abs(1 - 2 * (y * y + z * z)) + np.abs(2 * (x * y - z * w)) + np.abs(2 * (x * z + y * w)),
            np.abs(2 * (x * y + z * w)) + np.abs(1 - 2 * (x * x + z * z)) + np.abs(2 * (y * z - x * w)),
            np.abs(2 * (x * z - y * w)) + np.abs(2 * (y * z + x * w)) + np.abs(1 - 2 * (x * x + y * y)),
        ],
        axis=1,
    )
    return 0.5 * size * rows


class ConstructionTask(pydantic.BaseModel):
    """Scenario section ``task`` of kind ``construction``."""

    model_config = pydantic.ConfigDict(extra="forbid", strict=True, frozen=True)

    kind: Literal["construction"]
    time_limit_s: float = Field(500.0, gt=0.0, le=1e5)
    boxes: Annotated[list[Vec3], Field(min_length=1, max_length=500)]  # m, box centres at the start
    structure: Annotated[list[Vec3], Field(min_length=1, max_length=500)]  # m, goal slot centres
    box_size: float = Field(0.1, gt=0.0, le=2.0)  # m, cube edge
    box_mass: float = Field(0.01, gt=0.0, le=10.0)  # kg
    box_friction: float = Field(0.8, ge=0.0, le=5.0)
    attach_threshold: float = Field(0.02, gt=0.0, le=1.0)  # m, agent to grasp point
    grasp_gap: float = Field(0.005, ge=0.0, le=0.5)  # m, airframe bottom to box top when held
    place_tolerance_m: float = Field(0.01, gt=0.0, le=1.0)
    place_tolerance_deg: float = Field(10.0, gt=0.0, le=45.0)
    # a placed box counts as displaced only beyond (1 + place_hysteresis) x the place tolerances
    place_hysteresis: float = Field(0.5, ge=0.0, le=2.0)
    settle_s: float = Field(1.0, ge=0.0, le=100.0)
    # s, a run in which no box is grasped for the first time and the structure grows no higher than it
    # has been for this long ends as stalled (null: never)
    stall_time_s: float | None = Field(150.0, gt=0.0, le=1e5)
    settle_speed: float = Field(0.01, gt=0.0, le=10.0)  # m/s, "still" below this
    search_height: float = Field(0.45, gt=0.0, le=100.0)  # m, cruise altitude of the planners
    grip_force: float = Field(2.0, gt=0.0, le=1000.0)  # N, a harder pull on a held box makes it slip
    # the grip squares a held box to the airframe (nearest quarter turn) and centres it under it, as a
    # self-centring square jaw would: a box knocked askew is placed straight again, and one grasped off
    # its grasp point hangs on the airframe's axis, where its pull (weight and wake drag) twists nothing
    # (false: held as it was grasped)
    square_grip: bool = True
    view_radius: float | None = Field(None, gt=0.0, le=100.0)  # m (default: 2 x agent radius)
    # distance in which the view radius is measured: "chebyshev" (the largest per-axis difference, a
    # cube of half-width view_radius: the thesis's appendix A, dist = max(abs(object - agent))) or
    # "euclidean" (a ball)
    view_norm: Literal["chebyshev", "euclidean"] = "chebyshev"
    # how a released box comes to rest in a slot (see ``ConstructionRuntime``): "guided" (self-aligning
    # bricks: a chamfered guide pulls a box released over an open slot into it and an interlock bonds
    # it to the structure) or "free" (a box drops, and rests where friction leaves it: the thesis)
    placement: Literal["guided", "free"] = "guided"
    guide_capture: float = Field(0.3, gt=0.0, le=0.5)  # x box_size, horizontal reach of a slot's guide
    # x box_size, height above its slot a box is captured from: above the tops of the boxes beside it (a box
    # set down between placed boxes of its own width is otherwise held against them before the guide takes it)
    guide_height: float = Field(1.2, ge=0.0, le=5.0)
    guide_force: float = Field(0.5, gt=0.0, le=1000.0)  # N, the guide's pull on a captured box
    # the chamfers also take a box still held on its way down: a carried box within the guide's reach of an
    # open slot slides past the boxes bonded beside (and above) it, as a released one does (false: it meets
    # their edges until released, and a box lowered a few mm off a solid wall's slot is pressed onto them)
    guide_carried: bool = True
    bond_force: float = Field(50.0, gt=0.0, le=1e5)  # N, the interlock's hold on a placed box

    @pydantic.model_validator(mode="before")
    @classmethod
    def _expand_layouts(cls, data: Any) -> Any:
        """Expand a structure or depot written as voxels or named shapes into box centres."""
        if not isinstance(data, dict) or not any(isinstance(data.get(k), (dict, list)) for k in ("structure", "boxes")):
            return data
        size = data.get("box_size", cls.model_fields["box_size"].default)
        if isinstance(size, bool) or not isinstance(size, (int, float)) or not 0.0 < size <= 2.0:
            size = cls.model_fields["box_size"].default  # refused by its own field; expand with the default
        out = dict(data)
        for key in ("boxes", "structure"):
            if key in out:
                out[key] = expand_boxes(out[key], float(size), key)
        return out

    def plan_info(self, vehicle: Any) -> dict[str, Any]:
        """The layout the planners are told (``layout_info``) for agents of ``vehicle`` (VehicleParams)."""
        return layout_info(
            self, agent_half_height=0.5 * float(vehicle.collision_size[2]), agent_radius=float(vehicle.radius)
        )

    def check(self, scenario: ScenarioLike, source: str) -> None:
        """Refuse boxes outside the arena, overlapping boxes or slots, and unsupported slots."""
        h = 0.5 * self.box_size
        lx, ly = scenario.arena.size
        boxes = np.asarray(self.boxes, dtype=float)
        slots = np.asarray(self.structure, dtype=float)
        if len(slots) > len(boxes):
            raise ConfigError(
                f"needs at most as many slots as boxes ({len(boxes)}), got {len(slots)}",
                source=source,
                field="task.structure",
            )
        for name, pts in (("boxes", boxes), ("structure", slots)):
            for i, p in enumerate(pts):
                if not (h - 1e-9 <= p[0] <= lx - h + 1e-9 and h - 1e-9 <= p[1] <= ly - h + 1e-9):
                    raise ConfigError(
                        f"box at ({p[0]:g}, {p[1]:g}) is outside the arena [0, {lx:g}] x [0, {ly:g}] m "
                        f"(box size {self.box_size:g} m)",
                        source=source,
                        field=f"task.{name}[{i}]",
                    )
                if p[2] < h - 1e-6:
                    raise ConfigError(
                        f"box centre must be at least box_size / 2 = {h:g} m above the ground, got z = {p[2]:g}",
                        source=source,
                        field=f"task.{name}[{i}]",
                    )
            j, k = _first_overlap(pts, self.box_size)
            if j >= 0:
                raise ConfigError(f"boxes {j} and {k} overlap", source=source, field=f"task.{name}[{k}]")
        for i, p in enumerate(boxes):
            if p[2] > h + 1e-6 and not _supported(p, boxes, self.box_size):
                raise ConfigError("box floats: nothing under it", source=source, field=f"task.boxes[{i}]")
        for i, p in enumerate(slots):
            if p[2] > h + 1e-6 and not _supported(p, slots, self.box_size):
                raise ConfigError(
                    f"slot {i} at ({p[0]:g}, {p[1]:g}, {p[2]:g}) has nothing under it (no slot or ground supports its centre)",
                    source=source,
                    field=f"task.structure[{i}]",
                )
        for i, p in enumerate(boxes):
            d = np.max(np.abs(slots - p), axis=1)
            if np.any(d < self.box_size - 1e-9):
                raise ConfigError("box starts inside a goal slot", source=source, field=f"task.boxes[{i}]")
        from pybullet_swarm.vehicle import load_vehicle

        vehicle = load_vehicle(scenario.agents.vehicle)
        self._check_reach(scenario, Reach.of(self.box_size, vehicle.collision_size, self.grasp_gap), source)

    def _check_reach(self, scenario: ScenarioLike, reach: Reach, source: str) -> None:
        """Refuse boxes and slots an agent of this airframe cannot reach from above (the arena's edge, an
        obstacle over them, the ceiling over the finished structure), and a structure no order builds."""
        lx, ly = scenario.arena.size
        ax, ay = reach.airframe_half - REACH_MARGIN  # the airframe's centre stays this far inside the arena
        for name, pts in (("boxes", np.asarray(self.boxes, dtype=float)), ("structure", np.asarray(self.structure))):
            what = "box" if name == "boxes" else "slot"
            for i, p in enumerate(pts):
                if not (ax - 1e-9 <= p[0] <= lx - ax + 1e-9 and ay - 1e-9 <= p[1] <= ly - ay + 1e-9):
                    raise ConfigError(
                        f"{what} {i} at ({p[0]:g}, {p[1]:g}) is too near the arena's edge for an airframe "
                        f"{2 * ax:g} x {2 * ay:g} m to hover over it (its centre must lie in "
                        f"[{ax:g}, {lx - ax:g}] x [{ay:g}, {ly - ay:g}] m)",
                        source=source,
                        field=f"task.{name}[{i}]",
                    )
                self._check_obstacles(scenario, p, reach, f"task.{name}[{i}]", what, i, source)
        slots = np.asarray(self.structure, dtype=float)
        top = scenario.arena.height
        need = (
            float(np.max(slots[:, 2])) + 0.5 * self.box_size + self.box_size + reach.grasp_gap + reach.airframe_height
        )
        if top is not None and need > top + 1e-9:
            raise ConfigError(
                f"an agent carrying a box over the finished structure (top {float(np.max(slots[:, 2])) + 0.5 * self.box_size:g} m) "
                f"needs {need:.3g} m of height, above the ceiling {top:g} m",
                source=source,
                field="arena.height",
            )
        if build_order(prerequisites(slots, reach)) is None:  # cannot happen while every constraint points up
            raise ConfigError("no order of placements builds this structure", source=source, field="task.structure")

    @staticmethod
    def _check_obstacles(
        scenario: ScenarioLike, p: NDArray[np.float64], reach: Reach, field: str, what: str, i: int, source: str
    ) -> None:
        """Refuse an arena obstacle in the column an agent sweeps over the box or slot at ``p`` (3,) m."""
        for k, ob in enumerate(getattr(scenario.arena, "obstacles", ())):
            c = ob.center()
            hx, hy = ob.half_extents_xy()
            h = ob.size[1] if ob.shape == "cylinder" else ob.size[2]
            ob_top = c[2] + 0.5 * h
            d = np.abs(c[:2] - p[:2])
            in_box = bool(np.all(d < np.array([hx, hy]) + reach.box_half - 1e-9)) and ob_top > p[2] - reach.box_half
            in_air = bool(np.all(d < np.array([hx, hy]) + reach.half - 1e-9)) and ob_top > p[2] + reach.box_half
            if in_box or in_air:
                raise ConfigError(
                    f"{what} {i} at ({p[0]:g}, {p[1]:g}, {p[2]:g}) cannot be reached from above: arena.obstacles[{k}] "
                    "stands in the column an agent carrying a box sweeps over it",
                    source=source,
                    field=field,
                )


def grasp_height(spec: ConstructionTask, agent_half_height: float) -> float:
    """m, height of an agent's centre above the centre of the box it holds."""
    return agent_half_height + spec.grasp_gap + 0.5 * spec.box_size


def layout_info(spec: ConstructionTask, *, agent_half_height: float, agent_radius: float) -> dict[str, Any]:
    """The static layout every agent is told (keyword arguments of ``TaskInfo``: its ``layout``); the
    same when the scenario is loaded (for the planners' layout checks) and when the run starts."""
    layout = ConstructionLayout(
        depot=np.asarray(spec.boxes, dtype=float).reshape(-1, 3),
        slots=np.asarray(spec.structure, dtype=float).reshape(-1, 3),
        box_size=spec.box_size,
        grasp_height=grasp_height(spec, agent_half_height),
        search_height=spec.search_height,
        attach_threshold=spec.attach_threshold,
        view_radius=spec.view_radius if spec.view_radius is not None else 2.0 * agent_radius,
        view_norm=spec.view_norm,
        # m, how far above its slot a released box is still captured by the guide (0: free placement)
        guide_height=spec.guide_height * spec.box_size if spec.placement == "guided" else 0.0,
        box_mass=spec.box_mass,
    )
    return {"layout": layout}


def _first_overlap(pts: NDArray[np.float64], size: float) -> tuple[int, int]:
    for k in range(1, len(pts)):
        d = np.max(np.abs(pts[:k] - pts[k]), axis=1)
        hit = np.nonzero(d < size - 1e-9)[0]
        if hit.size:
            return int(hit[0]), k
    return -1, -1


def supporters(slots: NDArray[np.float64], size: float) -> list[NDArray[np.int64]]:
    """For each slot, the slots directly under it whose top face touches its bottom face and
    whose footprint overlaps its own."""
    out = []
    for p in slots:
        dz = p[2] - slots[:, 2]
        under = (
            (np.abs(dz - size) < 1e-6)
            & (np.abs(slots[:, 0] - p[0]) < size - 1e-9)
            & (np.abs(slots[:, 1] - p[1]) < size - 1e-9)
        )
        out.append(np.nonzero(under)[0])
    return out


def _supported(p: NDArray[np.float64], pts: NDArray[np.float64], size: float) -> bool:
    """True when the centre of the box at ``p`` lies over the union of the footprints of the
    boxes right under it (so it cannot tip over)."""
    dz = p[2] - pts[:, 2]
    under = pts[(np.abs(dz - size) < 1e-6)]
    if under.size == 0:
        return False
    h = 0.5 * size
    inside = (np.abs(under[:, 0] - p[0]) <= h + 1e-9) & (np.abs(under[:, 1] - p[1]) <= h + 1e-9)
    if inside.any():
        return True
    # centre over a gap between supports: supported when supports lie on both sides of it
    near = under[(np.abs(under[:, 0] - p[0]) < size) & (np.abs(under[:, 1] - p[1]) < size)]
    if len(near) < 2:
        return False
    lo_x, hi_x = near[:, 0].min() - h, near[:, 0].max() + h
    lo_y, hi_y = near[:, 1].min() - h, near[:, 1].max() + h
    return bool(lo_x <= p[0] <= hi_x and lo_y <= p[1] <= hi_y)


def _box_tilt_and_yaw_error(q: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Tilt (angle of the box axis closest to vertical from vertical) and yaw error modulo 90 deg,
    both rad, of cube orientations q (B, 4) (x, y, z, w)."""
    from pybullet_swarm.control.rotations import quat_to_matrix

    R = quat_to_matrix(q)
    zc = np.abs(R[:, 2, :])  # |vertical component| of each box axis
    k = np.argmax(zc, axis=1)
    tilt = np.arccos(np.clip(zc[np.arange(len(q)), k], -1.0, 1.0))
    # heading of one horizontal box axis, folded into [-45, 45) deg
    j = (k + 1) % 3
    ax = R[np.arange(len(q)), :, j]
    yaw = np.arctan2(ax[:, 1], ax[:, 0])
    yaw = (yaw + np.pi / 4) % (np.pi / 2) - np.pi / 4
    return tilt, np.abs(yaw)


#: the class of a carried box's contact with a body of the arena, by the body's kind
_LOAD_ON = {
    BodyKind.GROUND: CollisionClass.LOAD_GROUND.value,
    BodyKind.WALL: CollisionClass.LOAD_WALL.value,
    BodyKind.OBSTACLE: CollisionClass.LOAD_OBSTACLE.value,
}


class ConstructionRuntime(TaskBase):
    """Bodies, grasps and placements of a construction run.

    Args:
        spec: the validated task section.
        world: the World to build the boxes in.
        agent_half_height: m, half the airframe's height (for the grasp point).
        agent_radius: m.
        ghost: carried boxes pass through other agents and their loads, as the agents do; their overlaps
            are ghost pairs of the World (reported as contacts).
        starts: (n, 3) m, the agents' start positions (for the task's lower bound).
        v_max: (3,) m/s per-axis velocity limit (None: unlimited), for the lower bound.
        position_std: m, per-axis standard deviation of an agent's own position estimate (0 on true state).
        collision_size: (3,) m, the airframe's collision box (default: a square of the agent's enclosing
            circle, ``2 * agent_half_height`` tall), for the build order.
    """

    def __init__(
        self,
        spec: ConstructionTask,
        world: World,
        *,
        agent_half_height: float,
        agent_radius: float,
        ghost: bool = False,
        starts: NDArray[np.float64] | None = None,
        v_max: NDArray[np.float64] | None = None,
        position_std: float = 0.0,
        collision_size: NDArray[np.float64] | None = None,
    ) -> None:
        self.spec = spec
        self.agent_starts = np.zeros((0, 3)) if starts is None else np.asarray(starts, dtype=float)
        self.n = len(self.agent_starts)
        self.v_max = v_max
        self.position_std = float(position_std)
        self.world = world
        self.ghost = ghost  # carried boxes pass through other agents and loads; overlaps still reported
        self.size = spec.box_size
        self.start = np.asarray(spec.boxes, dtype=float)  # (B, 3)
        self.slots = np.asarray(spec.structure, dtype=float)  # (S, 3)
        self.B, self.S = len(self.start), len(self.slots)
        self.agent_half_height = float(agent_half_height)  # m
        self.agent_radius = float(agent_radius)  # m
        self.grasp_height = grasp_height(spec, agent_half_height)
        self.view_radius = spec.view_radius if spec.view_radius is not None else 2.0 * agent_radius
        self.bodies = [
            world.add_box(
                p,
                [spec.box_size] * 3,
                mass=spec.box_mass,
                kind=BodyKind.BOX,
                name=f"box{i}",
                color=(0.55, 0.45, 0.3, 1.0),
                friction=spec.box_friction,
            )
            for i, p in enumerate(self.start)
        ]
        self.body_to_box = {b: i for i, b in enumerate(self.bodies)}
        self.support = supporters(self.slots, spec.box_size)
        if collision_size is None:
            collision_size = np.array([2.0 * agent_radius, 2.0 * agent_radius, 2.0 * agent_half_height])
        self.reach = Reach.of(spec.box_size, collision_size, spec.grasp_gap)
        self.prereq = prerequisites(self.slots, self.reach)  # slots to fill before each slot (the build order)
        self.positions = self.start.copy()  # (B, 3) m
        self.quaternions = np.tile([0.0, 0.0, 0.0, 1.0], (self.B, 1))
        self._states = np.zeros((self.B, 7))  # the boxes' poses as the World reads them
        self._read_at: int | None = None  # the World's state version of the last read
        self._slots_still: tuple[NDArray[np.float64], bytes] | None = None  # see _update_slots
        self._open: tuple[bytes, NDArray[np.bool_]] | None = None  # slot_open of a slot_box
        self.state = np.zeros(self.B, dtype=np.int64)  # FREE / CARRIED / PLACED
        self.carried_by = np.full(self.B, -1, dtype=np.int64)
        self.slot_box = np.full(self.S, -1, dtype=np.int64)  # box in each slot, -1 when empty
        self._constraints: dict[int, int] = {}
        self._guides: dict[int, int] = {}  # box -> pin constraint (guided placement)
        self.guided_slot = np.full(self.B, -1, dtype=np.int64)  # slot a box is guided into or bonded in
        # guide_carried: carried box -> boxes it slides past (contacts off); and pairs to give contacts again
        # once they no longer overlap
        self._passing: dict[int, set[int]] = {}
        self._restore: set[tuple[int, int]] = set()
        self.still_since: float | None = None
        self.completed_at: float | None = None
        self.events: list[Event] = []
        self.grasps = 0
        self.stall_time_s = spec.stall_time_s
        self.ever_grasped = np.zeros(self.B, dtype=bool)  # boxes taken from where they lay at least once
        self.most_placed = 0  # the most slots filled at once so far
        self.releases = 0

    @classmethod
    def build(cls, spec: ConstructionTask, ctx: TaskContext) -> ConstructionRuntime:
        """The runtime factory registered in ``TASK_RUNTIMES``."""
        return cls(
            spec,
            ctx.world,
            agent_half_height=0.5 * float(ctx.collision_size[2]),
            agent_radius=ctx.agent_radius,
            ghost=ctx.ghost,
            starts=ctx.starts,
            v_max=ctx.v_max,
            position_std=ctx.position_std,
            collision_size=ctx.collision_size,
        )

    # ------------------------------------------------------------ bookkeeping
    def read(self) -> None:
        """Read box poses from the World (once per state of the World: nothing moved since the last read,
        nothing is read)."""
        version = self.world.state_version
        if version == self._read_at:
            return
        st = self._states
        self.world.read_body_poses(self.bodies, st)
        self.positions[:] = st[:, :3]
        self.quaternions[:] = st[:, 3:7]
        self._read_at = version

    def speeds(self, boxes: NDArray[np.int64]) -> NDArray[np.float64]:
        """(k,) m/s, the speeds of ``boxes`` now (read when asked: only the completion check needs them)."""
        v = np.zeros((len(boxes), 6))
        self.world.read_body_velocities([self.bodies[i] for i in boxes.tolist()], v)
        return np.linalg.norm(v[:, :3], axis=1)

    def _update_slots(self, t: float) -> None:
        """Fill and empty slots from the boxes' poses; nothing to do when the last update changed nothing and
        since then no loose box has moved and no box's state or slot has changed (it would judge the same)."""
        if self._slots_still is not None and self._still():
            return
        before = self.slot_box.tobytes()
        self._judge_slots(t)
        self._slots_still = None
        if self.slot_box.tobytes() == before:
            self._slots_still = (self._states[:, :7].copy(), self.state.tobytes() + before)

    def _still(self) -> bool:
        """True when no loose box has moved, and no box's state or slot changed, since the last update."""
        assert self._slots_still is not None
        poses, key = self._slots_still
        if self.state.tobytes() + self.slot_box.tobytes() != key:
            return False
        moved = (poses != self._states[:, :7]).any(axis=1)
        moved &= self.state != CARRIED  # where a carried box is does not fill or empty a slot
        return not moved.any()

    def _judge_slots(self, t: float) -> None:
        """Every slot's box from the boxes' poses now (all slots at once), with place and unplace events."""
        tilt, yaw = _box_tilt_and_yaw_error(self.quaternions)
        tol_a = math.radians(self.spec.place_tolerance_deg)
        aligned = (tilt <= tol_a) & (yaw <= tol_a)
        loose = self.state != CARRIED
        d = np.linalg.norm(self.positions[None, :, :] - self.slots[:, None, :], axis=2)  # (S, B)
        # hysteresis: a box in its slot stays there until it has moved clearly out of the tolerances
        # (a box resting on the boundary would otherwise flicker between placed and free)
        wide = 1.0 + self.spec.place_hysteresis
        kept = loose & (tilt <= wide * tol_a) & (yaw <= wide * tol_a)
        old = self.slot_box
        held = np.maximum(old, 0)
        stays = (old >= 0) & kept[held] & (d[np.arange(self.S), held] <= wide * self.spec.place_tolerance_m)
        # otherwise the nearest aligned loose box within the tolerance (the first of equals)
        cand = (d <= self.spec.place_tolerance_m) & (aligned & loose)[None, :]
        nearest = np.argmin(np.where(cand, d, np.inf), axis=1)
        new_slot_box = np.where(stays, old, np.where(cand.any(axis=1), nearest, -1)).astype(np.int64)
        for s in np.flatnonzero(new_slot_box != old).tolist():
            b = int(new_slot_box[s])
            if b >= 0 and self.guided_slot[b] == s and b in self._guides:  # in its slot: the guide bonds it
                self.world.set_constraint_force(self._guides[b], self.spec.bond_force)
            if b >= 0:
                self.events.append(Event(t, "placed", f"box{b}", f"slot{s}"))
            else:
                self.events.append(Event(t, "unplaced", f"box{old[s]}", f"slot{s}"))
        self.slot_box = new_slot_box
        self.most_placed = max(self.most_placed, self.boxes_placed)
        placed = np.zeros(self.B, dtype=bool)
        placed[new_slot_box[new_slot_box >= 0]] = True
        self.state = np.where(self.state == CARRIED, CARRIED, np.where(placed, PLACED, FREE))

    @property
    def slot_open(self) -> NDArray[np.bool_]:
        """(S,) True for empty slots whose prerequisites in the build order are all filled (the slots under
        them, and every lower slot whose column a box placed here would block: ``build_order``), and that no
        box is being guided into."""
        into = self._guided_into()
        key = self.slot_box.tobytes() + into.tobytes()
        if self._open is None or self._open[0] != key:
            filled = self.slot_box >= 0
            taken = filled | (into >= 0)  # a slot a box is being guided into is no longer open
            is_open = np.array([not taken[s] and bool(np.all(filled[self.prereq[s]])) for s in range(self.S)])
            self._open = (key, is_open)
        return self._open[1].copy()

    @property
    def boxes_placed(self) -> int:
        """Number of filled slots."""
        return int(np.count_nonzero(self.slot_box >= 0))

    def grasp_points(self) -> NDArray[np.float64]:
        """(B, 3) m, where an agent's centre must be to grasp each box."""
        return self.positions + np.array([0.0, 0.0, self.grasp_height])

    # ----------------------------------------------------------------- actions
    def grasp(self, agent: int, agent_body: int, agent_pos: NDArray[np.float64], t: float) -> int:
        """Attach the nearest free box within the attach threshold; returns its id or -1."""
        if agent in self.carried_by:
            return -1
        d = np.linalg.norm(self.grasp_points() - agent_pos, axis=1)
        d[~self._free()] = np.inf
        i = int(np.argmin(d))
        if not np.isfinite(d[i]) or d[i] > self.spec.attach_threshold:
            return -1
        body = self.bodies[i]
        self._constraints[i] = self.world.attach(
            agent_body, body, max_force=self.spec.grip_force, square=self.spec.square_grip
        )
        self.world.set_pair_collision(agent_body, body, False)  # the grip: never a contact
        for other in self._ghost_partners(i, agent_body):
            self.world.set_ghost_pair(other, body, True)
        self.state[i] = CARRIED
        self.carried_by[i] = agent
        self.grasps += 1
        self.ever_grasped[i] = True
        self.events.append(Event(t, "grasp", f"agent{agent}", f"box{i}", f"{d[i] * 100:.1f} cm from grasp point"))
        return i

    def release(self, agent: int, agent_body: int, t: float) -> int:
        """Let go of the box ``agent`` holds; returns its id or -1."""
        held = np.nonzero(self.carried_by == agent)[0]
        if held.size == 0:
            return -1
        i = int(held[0])
        self.world.detach(self._constraints.pop(i))
        self.world.set_pair_collision(agent_body, self.bodies[i], True)
        for other in self._ghost_partners(i, agent_body):
            self.world.set_ghost_pair(other, self.bodies[i], False)
        self.state[i] = FREE
        self.carried_by[i] = -1
        self.releases += 1
        self.events.append(Event(t, "release", f"agent{agent}", f"box{i}"))
        if self.spec.placement == "guided":
            self._capture(i, t)
        passed = self._passing.pop(i, set())
        if self.guided_slot[i] >= 0:  # captured: the guide keeps it off its slot's neighbours
            passed -= set(self._bonded_neighbours(int(self.guided_slot[i])))
        self._restore.update((i, b) for b in passed)  # it meets the others again
        return i

    # ------------------------------------------------------- guided placement
    def _capture(self, box: int, t: float) -> None:
        """Guided placement: a box released over an open slot, within the guide's reach, is pulled into it.

        The model is a self-aligning brick: a chamfered socket (or guide pins) takes a box whose
        centre is within ``guide_capture`` x box_size of the slot horizontally and at most
        ``guide_height`` x box_size above it, and slides it down into place, squared to the
        structure. The guide is a pin of ``guide_force`` N on the slot pose; the box does not
        touch the placed boxes beside and under it on the way (the chamfers let it slide past
        them), so a release beside a placed box never pushes it. Once placed, the pin becomes the
        interlock (``bond_force``). With ``guide_carried`` the chamfers take a box still held on its
        way down too (``_pass_carried``). Left out: the guide's own geometry (a box released outside
        the reach falls freely and may land on the guide's rim), the chamfers' sideways push on a held
        box (it passes the neighbours' edges instead of being pushed off them), friction in the guide, wear.
        """
        p, _ = self.world.body_pose(self.bodies[box])
        s = self._guide_slot(np.asarray(p, dtype=float))
        if s < 0:
            return
        body = self.bodies[box]
        for other in self._bonded_neighbours(s):
            self.world.set_pair_collision(body, self.bodies[other], False)
        self._guides[box] = self.world.pin(body, self.slots[s], None, self.spec.guide_force)
        self.guided_slot[box] = s
        self.events.append(Event(t, "guided", f"box{box}", f"slot{s}"))

    def _guide_slot(self, p: NDArray[np.float64]) -> int:
        """The nearest open slot (no box on its way into it) whose guide reaches a box centred at ``p`` (3,) m,
        -1 when none: within ``guide_capture`` x box_size horizontally, at most ``guide_height`` x box_size
        above the slot and not below it by more than the reach."""
        open_ = np.flatnonzero(self.slot_open & (self._guided_into() < 0))
        if open_.size == 0:
            return -1
        rel = self.slots[open_] - p
        reach = self.spec.guide_capture * self.size
        ok = (np.hypot(rel[:, 0], rel[:, 1]) <= reach) & (-rel[:, 2] <= self.spec.guide_height * self.size + 1e-9)
        ok &= rel[:, 2] <= reach  # not captured from below
        if not np.any(ok):
            return -1
        return int(open_[ok][np.argmin(np.linalg.norm(rel[ok], axis=1))])

    def _pass_carried(self) -> None:
        """``guide_carried``: a carried box within a guide's reach slides past the boxes bonded beside and
        above its slot (their contacts off, as for a released box the guide has taken; the boxes under the
        slot still bear it). Leaving the reach, it meets them again once they no longer overlap."""
        world = self.world
        for pair in sorted(self._restore):
            a, b = pair
            slot = int(self.guided_slot[a])
            if slot >= 0 and b in self._bonded_neighbours(slot):  # the guide has taken it: they stay apart
                self._restore.discard(pair)
            elif not world.overlapping(self.bodies[a], self.bodies[b]):
                world.set_pair_collision(self.bodies[a], self.bodies[b], True)
                self._restore.discard(pair)
        held = np.flatnonzero(self.state == CARRIED).tolist()
        for i in set(self._passing) - set(held):  # dropped outside ``release`` (a slipped grip)
            self._restore.update((i, b) for b in self._passing.pop(i))
        for i in held:
            s = self._guide_slot(self.positions[i])
            want: set[int] = set()
            if s >= 0:
                want = {
                    b
                    for b in self._bonded_neighbours(s)
                    if self.slots[self.guided_slot[b], 2] >= self.slots[s, 2] - 1e-6
                }
            had = self._passing.get(i, set())
            for b in want - had:
                world.set_pair_collision(self.bodies[i], self.bodies[b], False)
                self._restore.discard((i, b))
            self._restore.update((i, b) for b in had - want)
            if want:
                self._passing[i] = want
            else:
                self._passing.pop(i, None)

    def _free(self) -> NDArray[np.bool_]:
        """(B,) boxes an agent may take: free, and not on their way into a slot."""
        return (self.state == FREE) & (self.guided_slot < 0)

    def _guided_into(self) -> NDArray[np.int64]:
        """(S,) box being guided into or bonded in each slot, -1 when none."""
        out = np.full(self.S, -1, dtype=np.int64)
        has = np.flatnonzero(self.guided_slot >= 0)
        out[self.guided_slot[has]] = has
        return out

    def _bonded_neighbours(self, slot: int) -> list[int]:
        """Boxes guided or bonded in the slots touching ``slot`` (faces, edges or corners)."""
        near = np.max(np.abs(self.slots - self.slots[slot]), axis=1) <= self.size * (1.0 + 1e-6)
        near[slot] = False
        into = self._guided_into()
        return [int(b) for b in into[near] if b >= 0]

    def _ghost_partners(self, box: int, agent_body: int) -> list[int]:
        """Bodies a carried box passes through in ghost mode, their overlaps still reported as contacts: every
        other agent and every other carried box (agents and their loads pass through each other). None in
        physical mode."""
        if not self.ghost:
            return []
        others = [self.bodies[j] for j in np.nonzero(self.state == CARRIED)[0] if j != box]
        return [*(a for a in self.world.agent_bodies if a != agent_body), *others]

    def carrying(self, n: int) -> NDArray[np.int64]:
        """(n,) box held by each agent, or -1."""
        out = np.full(n, -1, dtype=np.int64)
        held = np.nonzero(self.carried_by >= 0)[0]
        out[self.carried_by[held]] = held
        return out

    # ---------------------------------------------------------------- progress
    def update(self, t: float, positions: NDArray[np.float64] | None = None) -> bool:
        """Read the boxes, update the slots and check completion at time ``t``; True once completed
        (the agents' ``positions`` are not needed)."""
        self.read()
        self._update_slots(t)
        if self.spec.placement == "guided" and self.spec.guide_carried:  # off: nothing is ever passed
            self._pass_carried()
        if self.completed_at is not None:
            return True
        if self.boxes_placed == self.S and np.all(self.speeds(self.slot_box) < self.spec.settle_speed):
            if self.still_since is None:
                self.still_since = t
            if t - self.still_since >= self.spec.settle_s - 1e-9:
                self.completed_at = t
                return True
        else:
            self.still_since = None
        return False

    def progress(self) -> int:
        """Boxes grasped for the first time plus the most slots filled at once so far: a swarm that keeps
        taking the same boxes, or placing boxes only to knock others out, makes no progress."""
        return int(np.count_nonzero(self.ever_grasped)) + self.most_placed

    def visible(self, p: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Free boxes and open slots within the view radius of position ``p`` (3,) m."""
        free = np.nonzero(self._free() & self.in_view(self.grasp_points() - p))[0]
        open_ = np.nonzero(self.slot_open & self.in_view(self.slots + [0.0, 0.0, self.grasp_height] - p))[0]
        return free, open_

    def in_view(self, rel: NDArray[np.float64]) -> NDArray[np.bool_]:
        """(...,) True where an object whose grasp point lies at ``rel`` (..., 3) m from an agent is in
        its view: within view_radius + grasp_height in the task's ``view_norm`` (measured from the
        grasp point, so that an agent holding station over a box sees it)."""
        return view_distance(rel, self.spec.view_norm) <= self.view_radius + self.grasp_height

    # ---------------------------------------------------------------- protocol
    def task_info(self) -> dict[str, Any]:
        """The layout: depot, slots, box size, grasp height, view and search settings."""
        return layout_info(self.spec, agent_half_height=self.agent_half_height, agent_radius=self.agent_radius)

    def framing(self) -> Framing:
        """The camera frames the cruise altitude; the boxes are coloured; the status counts placed boxes."""
        return Framing(
            height=max(0.6, float(self.spec.search_height) + 0.2),
            bodies=tuple(int(b) for b in self.bodies),
            status=f"boxes placed {self.boxes_placed}/{self.S}",
        )

    def view(self, t: float) -> ConstructionView:
        """Boxes, their states, slots and who carries what."""
        state, filled = self.state.copy(), self.slot_box.copy()
        into = self._guided_into()
        guided = (filled < 0) & (into >= 0)  # a box on its way into its slot counts as placed there
        filled[guided] = into[guided]
        state[into[guided]] = PLACED
        still = np.nonzero(state != CARRIED)[0]  # free and placed boxes stand still for avoidance
        return TaskView(
            t,
            self.carrying(self.n),
            ConstructionState(self.positions.copy(), state, self.slots, filled, self.slot_open),
            obstacles=Obstacles(
                self.positions[still], cube_half_extents(self.quaternions[still], self.size), still.astype(np.int64)
            ),
        )

    def local_views(
        self, true_positions: NDArray[np.float64], sensed_positions: NDArray[np.float64]
    ) -> list[ConstructionLocalView]:
        """Free boxes and open slots in each agent's view (measured from where the airframe truly is).

        Boxes are seen relative to the airframe, so they appear in the agent's own (possibly
        estimated) frame; slots are planned coordinates and are given as they are.
        """
        n = len(true_positions)
        gh = np.array([0.0, 0.0, self.grasp_height])
        seen_b = self._free()[None, :] & self.in_view(self.grasp_points()[None, :, :] - true_positions[:, None, :])
        seen_s = self.slot_open[None, :] & self.in_view((self.slots + gh)[None, :, :] - true_positions[:, None, :])
        shift = sensed_positions - true_positions
        # every (agent, object) in view at once, in agent order; each agent's rows are one slice of them
        ab, boxes = np.nonzero(seen_b)
        at, slots = np.nonzero(seen_s)
        box_pos = self.positions[boxes] + shift[ab]
        slot_pos = self.slots[slots]
        rows = np.arange(n + 1)
        b_lo = np.searchsorted(ab, rows).tolist()
        s_lo = np.searchsorted(at, rows).tolist()
        return [
            ConstructionLocalView(box_pos[b0:b1], boxes[b0:b1], slot_pos[s0:s1], slots[s0:s1])
            for b0, b1, s0, s1 in zip(b_lo, b_lo[1:], s_lo, s_lo[1:])
        ]

    def apply(self, agent: int, action: Action, t: float, position: NDArray[np.float64]) -> float | None:
        """GRASP the free box at the agent's grasp point, or RELEASE the one it holds; returns the new
        payload mass kg when it changed."""
        body = self.world.agent_bodies[agent]
        if action == Action.GRASP:
            return self.spec.box_mass if self.grasp(agent, body, position, t) >= 0 else None
        if action == Action.RELEASE:
            return 0.0 if self.release(agent, body, t) >= 0 else None
        return None

    def contact_class(self, agent: int, body: int) -> str | None:
        """A box touched by an agent: ``agent_structure`` when placed, ``agent_box`` when free or carried
        by another agent, nothing for the agent's own load."""
        box = self.body_to_box.get(body)
        if box is None:
            return NOT_MINE
        if self.carried_by[box] == agent:
            return None
        return (CollisionClass.AGENT_STRUCTURE if self.state[box] == PLACED else CollisionClass.AGENT_BOX).value

    def body_contact_class(self, a: int, b: int) -> str | None:
        """A carried box touching another carried box (``load_load``), a free box (``load_box``), a placed
        one (``load_structure``; a box being guided into its slot counts as placed), the ground (``load_ground``),
        a wall (``load_wall``) or a static obstacle (``load_obstacle``); nothing else counts, nor a carried box set
        down on the ground within the guide's reach of an open slot (a placement)."""
        i, j = self.body_to_box.get(a), self.body_to_box.get(b)
        if i is None and j is None:
            return None
        if i is None or j is None:  # a box and a body of the arena: counts when the box is carried
            box, other = (i, b) if i is not None else (int(j or 0), a)
            if self.state[box] != CARRIED:
                return None
            kind = self.world.body_kind(other)
            if kind is BodyKind.GROUND and self._guide_slot(self.world.body_pose(self.bodies[box])[0]) >= 0:
                return None  # set down into its open slot on the ground: a placement, not a contact
            return _LOAD_ON.get(kind)
        if self.state[i] != CARRIED:
            i, j = j, i
        if self.state[i] != CARRIED:
            return None
        if self.state[j] == CARRIED:
            return CollisionClass.LOAD_LOAD.value
        if self.state[j] == PLACED or self.guided_slot[j] >= 0:
            return CollisionClass.LOAD_STRUCTURE.value
        return CollisionClass.LOAD_BOX.value

    def refresh(self) -> None:
        """Read the boxes' poses now."""
        self.read()

    def sample(self) -> dict[str, NDArray[np.float64]]:
        """Box positions (B, 3) m, orientations (B, 4) (x, y, z, w) and carriers (B,) (agent, -1: none) now."""
        self.read()
        return {"box_positions": self.positions, "box_quaternions": self.quaternions, "box_carried_by": self.carried_by}

    def metrics(
        self, series: TimeSeries | None = None, planner_artefacts: dict[str, Any] | None = None
    ) -> dict[str, Any]:
        """Boxes placed, grasps, releases, the task's lower bound and the efficiency of the run."""
        out: dict[str, Any] = {
            "boxes_placed": self.boxes_placed,
            "boxes_total": self.S,
            "grasps": self.grasps,
            "releases": self.releases,
        }
        if self.n:
            v = np.full(3, 1e9) if self.v_max is None else self.v_max
            lb = task_lower_bound(self.agent_starts, self.start, self.slots, v, grasp_height=self.grasp_height)
            out["task_lower_bound_s"] = lb["task_lower_bound_s"]
            out["efficiency"] = (lb["task_lower_bound_s"] / self.completed_at) if self.completed_at else None
        return out


register_task("construction", ConstructionTask, ConstructionRuntime)
