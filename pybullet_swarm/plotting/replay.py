"""Replay frames of finished runs, drawn with matplotlib from the saved results (nothing is re-simulated).

A run directory holds everything a replay needs: ``timeseries.npz`` (agent poses; box poses and
who carries each box for construction runs), ``events.csv`` (contacts, grasps, placements),
``scenario.yaml`` (arena, obstacles, structure slots, waypoints), ``metrics.json`` (names for the
heads-up line) and, for pheromone planners, ``pheromones.npz`` (snapshots of the field).
``experiment.replay`` reads them into ``replay_data`` and writes the video or a still; this
module only draws.

Frames are drawn on one matplotlib figure whose artists are created once and updated in place.
Everything is projected by this module's own camera (``ViewCamera``) onto pixel coordinates, so
the axes span the frame pixel for pixel: for a fixed camera (``top``, ``3d``) the static scene is
drawn once and each frame blits only the moving artists; a moving camera (``chase``, ``orbit``)
redraws the static scene too, still without creating artists.

Views:

- ``top``: orthographic, from above, the arena filling the frame (x to the right, y up).
- ``3d``: a fixed perspective camera framing the arena and the flight volume (as ``--gui``).
- ``orbit``: the ``3d`` camera circling the arena once every ``ORBIT_PERIOD_S`` of video.
- ``chase``: a camera behind and above the swarm's centroid, looking along its smoothed heading.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import re
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure
from matplotlib import colormaps
from numpy.typing import NDArray

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.types import Event, TimeSeries
from pybullet_swarm.world.camera import camera_for_arena

DEFAULT_SIZE = (1280, 720)  # px, width x height of a replay
DEFAULT_FPS = 25  # frames per second of a replay
DEFAULT_SPEED = 4.0  # simulated seconds per second of video
TRAIL_S = 3.0  # s of simulated time behind each agent drawn as its trail
ORBIT_PERIOD_S = 24.0  # s of video per turn of the orbit camera
CHASE_PITCH_DEG = -30.0  # deg, the chase camera looks down this much
CHASE_SMOOTH_S = 1.5  # s, half-width of the moving average of the chased centroid and heading
FLASH_S = 0.6  # s of simulated time a contact flashes (at least FLASH_FRAMES frames)
FLASH_FRAMES = 10
MIN_ICON_FRACTION = 0.04  # a vehicle is drawn at least this fraction of the frame height across
MAX_LABELLED_AGENTS = 20  # agents are numbered on the frame up to this many
NEAR_M = 0.05  # m, near plane of the perspective cameras
FOV_DEG = 50.0  # deg, vertical field of view of the perspective cameras (Bullet's render)
DPI = 100

BACKGROUND = (0.975, 0.975, 0.97, 1.0)
FLOOR = (0.90, 0.90, 0.87, 1.0)
BOX_FREE = (0.76, 0.60, 0.42, 1.0)
BOX_PLACED = (0.42, 0.62, 0.33, 1.0)
OBSTACLE = (0.52, 0.55, 0.60, 0.6)
FLASH = (0.86, 0.08, 0.08, 1.0)
TARGET = (0.35, 0.35, 0.35, 1.0)
TARGET_DONE = (0.20, 0.60, 0.25, 1.0)
LIGHT = np.array([0.35, -0.45, 0.82]) / np.linalg.norm([0.35, -0.45, 0.82])  # direction towards the light
CONTACT_KINDS = frozenset({"agent_agent", "agent_box", "agent_structure", "agent_ground", "agent_obstacle"})


def _colours(rgba: Any) -> Any:
    """(n, 4) RGBA rows for a collection's colours: matplotlib takes arrays, its type stubs name only sequences."""
    return rgba


class View(str, enum.Enum):
    """Camera of a replay."""

    TOP = "top"
    CHASE = "chase"
    ORBIT = "orbit"
    THREE_D = "3d"

    def __str__(self) -> str:
        return self.value


# --------------------------------------------------------------------------------- data
@dataclasses.dataclass(frozen=True)
class Obstacle3D:
    """A static obstacle as drawn: ``shape`` 'box' (size x, y, z m, turned by yaw rad) or 'cylinder'
    (size radius, height m); ``center`` (3,) m."""

    shape: str
    size: tuple[float, ...]
    center: tuple[float, float, float]
    yaw: float = 0.0


@dataclasses.dataclass(frozen=True)
class PheromoneHistory:
    """Snapshots of one pheromone layer seen from above.

    Attributes:
        layer: layer name.
        t: (k,) s, snapshot times.
        values: (k, nx, ny) the column value of largest magnitude in each cell.
        cell: m, cell edge.
    """

    layer: str
    t: NDArray[np.float64]
    values: NDArray[np.float32]
    cell: float


@dataclasses.dataclass(frozen=True)
class ReplayData:
    """Everything a replay draws, read from a run directory by ``load_replay``.

    Attributes:
        t: (m,) s, sample times.
        positions: (m, n, 3) m.
        quaternions: (m, n, 4) (x, y, z, w).
        box_positions: (m, B, 3) m (B = 0 without boxes).
        box_quaternions: (m, B, 4) (x, y, z, w).
        box_carried_by: (m, B) agent holding each box, -1 for none.
        box_size: m, cube edge.
        slots: (S, 3) m, structure slot centres.
        targets: (W, 3) m, waypoints or inspection points of the task.
        arena: (2,) m, Lx, Ly.
        obstacles: static obstacles.
        rotor_xy: (4, 2) m, rotor positions in the body frame.
        rotor_radius: m.
        events: the run's events in time order.
        pheromone: the pheromone field, when the planner kept one.
        title: first line of the heads-up display.
    """

    t: NDArray[np.float64]
    positions: NDArray[np.float64]
    quaternions: NDArray[np.float64]
    box_positions: NDArray[np.float64]
    box_quaternions: NDArray[np.float64]
    box_carried_by: NDArray[np.int64]
    box_size: float
    slots: NDArray[np.float64]
    targets: NDArray[np.float64]
    arena: tuple[float, float]
    obstacles: tuple[Obstacle3D, ...]
    rotor_xy: NDArray[np.float64]
    rotor_radius: float
    events: tuple[Event, ...]
    pheromone: PheromoneHistory | None = None
    title: str = ""

    @property
    def n_agents(self) -> int:
        """Number of agents."""
        return int(self.positions.shape[1])

    @property
    def n_boxes(self) -> int:
        """Number of boxes."""
        return int(self.box_positions.shape[1])

    @property
    def height(self) -> float:
        """m, top of the flight volume to keep in view: the highest sample (and slot) plus a margin."""
        top = float(np.max(self.positions[..., 2])) if self.positions.size else 0.0
        if self.slots.size:
            top = max(top, float(np.max(self.slots[:, 2])))
        return max(0.6, top + 0.25)


def _carried_from_events(t: NDArray[np.float64], n_boxes: int, events: Sequence[Event]) -> NDArray[np.int64]:
    """(m, B) carrier of each box at each sample, from ``grasp`` and ``release`` events (runs recorded
    before ``box_carried_by`` was): samples after an event show it."""
    out = np.full((t.size, n_boxes), -1, dtype=np.int64)
    for e in events:
        if e.kind not in ("grasp", "release"):
            continue
        agent, box = _index(e.a, "agent"), _index(e.b, "box")
        if agent is None or box is None or box >= n_boxes:
            continue
        k = int(np.searchsorted(t, e.time_s + 1e-4))  # a sample at the event's instant was taken before it
        out[k:, box] = agent if e.kind == "grasp" else -1
    return out


def _index(name: str, prefix: str) -> int | None:
    """``agent3`` -> 3 for prefix ``agent``; None for other names."""
    m = re.fullmatch(rf"{prefix}(\d+)", name or "")
    return int(m.group(1)) if m else None


def _obstacles(arena: Mapping[str, Any]) -> tuple[Obstacle3D, ...]:
    out = []
    for ob in arena.get("obstacles", []) or []:
        size = tuple(float(v) for v in ob["size"])
        pos = [float(v) for v in ob["position"]]
        height = size[1] if ob["shape"] == "cylinder" else size[2]
        z = pos[2] if len(pos) == 3 else 0.5 * height
        out.append(Obstacle3D(str(ob["shape"]), size, (pos[0], pos[1], z), math.radians(float(ob.get("yaw_deg", 0.0)))))
    return tuple(out)


def _targets(task: Mapping[str, Any]) -> NDArray[np.float64]:
    """(W, 3) m: the waypoints of a route, the points of a tour, the absolute set-points of a waypoints task."""
    kind = task.get("kind")
    if kind == "route":
        items = task.get("waypoints") or []
    elif kind == "tour":
        items = task.get("points") or []
    elif kind == "waypoints" and task.get("relative", True) is False:
        items = [w["position"] for w in task.get("waypoints") or [] if isinstance(w, Mapping) and "position" in w]
    else:
        items = []
    return np.asarray(items, dtype=float).reshape(-1, 3)


def pheromone_history(arrays: Mapping[str, NDArray[Any]] | None) -> PheromoneHistory | None:
    """The floor overlay from the arrays of ``pheromones.npz``: the ``task`` layer (or the first one)."""
    if arrays is None or "layers" not in arrays:
        return None
    layers = [str(n) for n in np.asarray(arrays["layers"]).ravel()]
    if not layers:
        return None
    layer = "task" if "task" in layers else layers[0]
    hist = np.asarray(arrays.get(f"{layer}_history", np.zeros((0, 0, 0))))
    if hist.ndim != 3 or hist.shape[0] == 0:
        return None
    return PheromoneHistory(
        layer, np.asarray(arrays["snapshot_t"], dtype=float), hist.astype(np.float32), float(arrays["cell"])
    )


def replay_data(
    ts: TimeSeries,
    events: Sequence[Event],
    scenario: Mapping[str, Any],
    metrics: Mapping[str, Any] | None = None,
    pheromones: Mapping[str, NDArray[Any]] | None = None,
) -> ReplayData:
    """What a replay draws, from a run's saved results.

    Args:
        ts: the recorded time series (``timeseries.npz``), at least one sample.
        events: the run's events (``events.csv``).
        scenario: the resolved scenario (``scenario.yaml``): arena, obstacles, task, vehicle.
        metrics: the run's metrics (``metrics.json``), for the title line.
        pheromones: the arrays of ``pheromones.npz``, when the planner kept a field.

    Raises:
        ValueError: a series without samples.
    """
    from pybullet_swarm.vehicle import load_vehicle

    if ts.t.size == 0:
        raise ValueError("the run recorded no samples (nothing to replay)")
    metrics = metrics or {}
    t = ts.t.astype(float)
    m = ts.positions.shape[0]
    task = scenario.get("task", {}) or {}
    extra = ts.extra
    boxes = extra["box_positions"].astype(float) if "box_positions" in extra else np.zeros((m, 0, 3))
    b = boxes.shape[1]
    box_q = (
        extra["box_quaternions"].astype(float)
        if "box_quaternions" in extra
        else np.tile(np.array([0.0, 0.0, 0.0, 1.0]), (m, b, 1))
    )
    carried = (
        np.rint(extra["box_carried_by"]).astype(np.int64)
        if "box_carried_by" in extra
        else _carried_from_events(t, b, events)
    )
    try:
        vehicle = load_vehicle((scenario.get("agents", {}) or {}).get("vehicle", "quad150"))
        rotor_xy = vehicle.rotor_xy
        half_width = 0.5 * max(vehicle.collision_size[:2])  # the rotors reach the airframe's box
        rotor_radius = max(0.3 * vehicle.arm_length, half_width - vehicle.arm_length / math.sqrt(2))
    except (OSError, ValueError, ConfigError):
        rotor_xy = 0.053 * np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]]) / math.sqrt(2)
        rotor_radius = 0.0375
    size = (scenario.get("arena", {}) or {}).get("size", [3.0, 1.0])
    name = metrics.get("scenario") or scenario.get("name", "run")
    planner = metrics.get("planner") or (scenario.get("planner", {}) or {}).get("name") or ""
    avoidance = metrics.get("avoidance") or scenario.get("avoidance") or "none"
    seed = metrics.get("seed", scenario.get("seed"))
    title = f"{name}  |  {planner or 'task set-points'} + {avoidance} avoidance  |  seed {seed}"
    return ReplayData(
        t=t,
        positions=ts.positions.astype(float),
        quaternions=ts.quaternions.astype(float),
        box_positions=boxes,
        box_quaternions=box_q,
        box_carried_by=carried,
        box_size=float(task.get("box_size", 0.1)),
        slots=np.asarray(task.get("structure", []), dtype=float).reshape(-1, 3),
        targets=_targets(task),
        arena=(float(size[0]), float(size[1])),
        obstacles=_obstacles(scenario.get("arena", {}) or {}),
        rotor_xy=np.asarray(rotor_xy, dtype=float),
        rotor_radius=float(rotor_radius),
        events=tuple(events),
        pheromone=pheromone_history(pheromones),
        title=title,
    )


# ----------------------------------------------------------------------------- geometry
def quat_matrices(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4) (x, y, z, w), body to world."""
    x, y, z, w = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
        ],
        axis=-2,
    )


def frame_times(t0: float, t1: float, speed: float, fps: int) -> NDArray[np.float64]:
    """Simulated times (k,) s of the frames of a replay of [t0, t1] at ``speed`` x real time and ``fps``.

    Frame j shows t0 + j * speed / fps; there are floor((t1 - t0) * fps / speed) + 1 frames.
    """
    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed: expected a positive number, got {speed!r}")
    count = int(math.floor((t1 - t0) * fps / speed + 1e-9)) + 1
    return t0 + np.arange(max(count, 1), dtype=float) * (speed / fps)


@dataclasses.dataclass(frozen=True)
class ViewCamera:
    """Maps world points to frame pixels (u right, v down, origin at the top-left corner).

    Attributes:
        eye: (3,) m, camera position (orthographic: any point on the axis, above the scene).
        forward, right, up: (3,) unit vectors of the camera in the world frame.
        focal: px; orthographic: px per m; perspective: px per unit of lateral offset / depth.
        centre: (2,) px, where the optical axis meets the frame.
        orthographic: parallel projection along ``forward``.
    """

    eye: NDArray[np.float64]
    forward: NDArray[np.float64]
    right: NDArray[np.float64]
    up: NDArray[np.float64]
    focal: float
    centre: tuple[float, float]
    orthographic: bool = False

    def project(self, points: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Pixels (..., 2) and depths (..., ) m of points (..., 3) m; NaN pixels behind the near plane."""
        q = np.asarray(points, dtype=float) - self.eye
        depth = q @ self.forward
        x, y = q @ self.right, q @ self.up
        if self.orthographic:
            scale = np.full_like(depth, self.focal)
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                scale = np.where(depth > NEAR_M, self.focal / depth, np.nan)
        return np.stack([self.centre[0] + scale * x, self.centre[1] - scale * y], axis=-1), depth

    def px_per_m(self, depth: NDArray[np.float64]) -> NDArray[np.float64]:
        """Pixels per metre of a lateral length at ``depth`` (...,) m."""
        if self.orthographic:
            return np.full_like(np.asarray(depth, dtype=float), self.focal)
        return self.focal / np.maximum(np.asarray(depth, dtype=float), NEAR_M)

    def facing(self, points: NDArray[np.float64], normals: NDArray[np.float64]) -> NDArray[np.bool_]:
        """(k,) True where a face at ``points`` (k, 3) with outward ``normals`` (k, 3) faces the camera."""
        if self.orthographic:
            return normals @ (-self.forward) > 1e-9
        return np.einsum("ij,ij->i", normals, self.eye - points) > 1e-9

    def clip(self, polygon: NDArray[np.float64]) -> NDArray[np.float64]:
        """The part (k', 3) of a planar polygon (k, 3) m in front of the near plane (Sutherland-Hodgman)."""
        if self.orthographic:
            return polygon
        d = (polygon - self.eye) @ self.forward - NEAR_M
        out = []
        for i in range(len(polygon)):
            p, q, dp, dq = polygon[i - 1], polygon[i], d[i - 1], d[i]
            if dq >= 0:
                if dp < 0:
                    out.append(p + (q - p) * (dp / (dp - dq)))
                out.append(q)
            elif dp >= 0:
                out.append(p + (q - p) * (dp / (dp - dq)))
        return np.array(out).reshape(-1, 3)


def _basis(yaw_deg: float, pitch_deg: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Forward, right, up of Bullet's yaw/pitch camera (yaw 0 looks along +y, x to the right)."""
    psi, theta = math.radians(yaw_deg), math.radians(pitch_deg)
    forward = np.array([-math.sin(psi) * math.cos(theta), math.cos(psi) * math.cos(theta), math.sin(theta)])
    right = np.array([math.cos(psi), math.sin(psi), 0.0])
    return forward, right, np.cross(right, forward)


def perspective(
    target: Sequence[float] | NDArray[np.float64],
    distance: float,
    yaw_deg: float,
    pitch_deg: float,
    size: tuple[int, int],
) -> ViewCamera:
    """The perspective camera of Bullet's (target, distance, yaw, pitch) with a ``FOV_DEG`` vertical
    field of view, for frames of ``size`` (width, height) px."""
    forward, right, up = _basis(yaw_deg, pitch_deg)
    w, h = size
    focal = 0.5 * h / math.tan(math.radians(FOV_DEG) / 2)
    return ViewCamera(
        np.asarray(target, dtype=float) - distance * forward, forward, right, up, focal, (0.5 * w, 0.5 * h)
    )


def top_camera(arena: tuple[float, float], size: tuple[int, int], *, hud_px: float) -> ViewCamera:
    """Orthographic camera from above fitting the arena below a heads-up band of ``hud_px`` px."""
    w, h = size
    lx, ly = arena
    margin = 0.03 * min(w, h)
    scale = min((w - 2 * margin) / lx, (h - hud_px - 2 * margin) / ly)
    centre = (0.5 * w, hud_px + margin + 0.5 * (h - hud_px - 2 * margin))
    return ViewCamera(
        np.array([0.5 * lx, 0.5 * ly, 1e3]),
        np.array([0.0, 0.0, -1.0]),
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 1.0, 0.0]),
        scale,
        centre,
        orthographic=True,
    )


def _fixed_3d(data: ReplayData, size: tuple[int, int]) -> tuple[tuple[float, float, float], float, float, float]:
    cam = camera_for_arena(data.arena, data.height, aspect=size[0] / size[1])
    return cam.target, cam.distance, cam.yaw, cam.pitch


def _orbit_base(data: ReplayData, size: tuple[int, int]) -> tuple[NDArray[np.float64], float, float]:
    """Target (3,) m on the vertical through the arena's centre, distance m and pitch deg of an orbit:
    the 3d framing of a square that holds the arena at any yaw."""
    lx, ly = data.arena
    d = math.hypot(lx, ly)
    cam = camera_for_arena((d, d), data.height, pitch=-35.0, aspect=size[0] / size[1])
    forward = _basis(cam.yaw, cam.pitch)[0]
    eye = cam.eye() + np.array([0.5 * (lx - d), 0.5 * (ly - d), 0.0])
    # the same view, its target slid along the line of sight onto the vertical through the centre
    distance = (0.5 * ly - eye[1]) / forward[1]
    return eye + distance * forward, float(distance), cam.pitch


def _moving_average(x: NDArray[np.float64], half: int) -> NDArray[np.float64]:
    """Centred moving average (m, ...) over 2 * half + 1 samples (shorter windows at the ends)."""
    if half <= 0 or x.shape[0] < 2:
        return x.copy()
    c = np.concatenate([np.zeros((1, *x.shape[1:])), np.cumsum(x, axis=0)])
    m = x.shape[0]
    lo = np.clip(np.arange(m) - half, 0, m)
    hi = np.clip(np.arange(m) + half + 1, 0, m)
    counts = (hi - lo).reshape(-1, *([1] * (x.ndim - 1)))
    return (c[hi] - c[lo]) / counts


def chase_track(data: ReplayData) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Smoothed centroid (m, 3) m, heading (m,) rad and horizontal spread (m,) m of the swarm per sample."""
    t, pos = data.t, data.positions
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    half = int(round(CHASE_SMOOTH_S / dt))
    centroid = _moving_average(pos.mean(axis=1), half)
    spread = _moving_average(
        np.sqrt(np.mean(np.sum((pos[..., :2] - pos.mean(axis=1, keepdims=True)[..., :2]) ** 2, axis=2), axis=1)), half
    )
    vel = np.gradient(centroid[:, :2], t, axis=0) if t.size > 1 else np.zeros((1, 2))
    speed = np.linalg.norm(vel, axis=1)
    heading = np.full(t.size, math.pi / 2)  # no motion yet: look along +y, as the 3d view
    last = math.pi / 2
    for k in range(t.size):  # hold the last heading while the swarm hovers
        if speed[k] > 0.02:
            last = math.atan2(vel[k, 1], vel[k, 0])
        heading[k] = last
    heading = _moving_average(np.unwrap(heading), half)
    return centroid, heading, spread


# ----------------------------------------------------------------------------- meshes
_CUBE = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
_CUBE_FACES = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
_CUBE_NORMALS = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]], dtype=float)


def cube_faces(
    centres: NDArray[np.float64], rotations: NDArray[np.float64], extents: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Faces (k, 6, 4, 3) m and outward normals (k, 6, 3) of boxes: centres (k, 3) m, rotations
    (k, 3, 3), extents (k, 3) m."""
    corners = np.einsum("kij,kvj->kvi", rotations, _CUBE[None] * extents[:, None, :]) + centres[:, None, :]
    return corners[:, _CUBE_FACES], np.einsum("kij,fj->kfi", rotations, _CUBE_NORMALS)


def _obstacle_faces(ob: Obstacle3D, sides: int = 20) -> list[tuple[NDArray[np.float64], NDArray[np.float64], bool]]:
    """(polygon (k, 3) m, outward normal (3,), outlined) faces of an obstacle (a cylinder as a prism whose
    side faces are not outlined)."""
    c = np.asarray(ob.center)
    if ob.shape == "cylinder":
        r, h = ob.size[0], ob.size[1]
        a = np.linspace(0.0, 2 * math.pi, sides, endpoint=False)
        ring = np.stack([r * np.cos(a), r * np.sin(a), np.zeros(sides)], axis=1)
        top, bottom = ring + c + [0, 0, h / 2], ring + c - [0, 0, h / 2]
        faces = [(top, np.array([0.0, 0.0, 1.0]), True), (bottom[::-1], np.array([0.0, 0.0, -1.0]), True)]
        for i in range(sides):
            j = (i + 1) % sides
            mid = 0.5 * (a[i] + a[i] + 2 * math.pi / sides)
            normal = np.array([math.cos(mid), math.sin(mid), 0.0])
            faces.append((np.array([bottom[i], bottom[j], top[j], top[i]]), normal, False))
        return faces
    cz, sz = math.cos(ob.yaw), math.sin(ob.yaw)
    rot = np.array([[[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]]])
    polys, normals = cube_faces(c[None], rot, np.asarray(ob.size, dtype=float)[None])
    return [(p, nrm, True) for p, nrm in zip(polys[0], normals[0])]


def _shade(colors: NDArray[np.float64], normals: NDArray[np.float64]) -> NDArray[np.float64]:
    """Colours (k, 4) lit by ``LIGHT`` on faces with ``normals`` (k, 3) (alpha kept)."""
    out = np.array(colors, dtype=float, copy=True)
    out[:, :3] *= (0.62 + 0.38 * np.clip(normals @ LIGHT, 0.0, 1.0))[:, None]
    return out


def agent_colors(n: int) -> NDArray[np.float64]:
    """One RGBA colour (n, 4) per agent: tab10 up to 10 agents, else evenly spaced hues (as ``--gui``)."""
    if n <= 10:
        return np.asarray(colormaps["tab10"](np.arange(n)))
    return np.asarray(colormaps["hsv"](np.arange(n) / n))


# ----------------------------------------------------------------------------- text
class _TextLayer:
    """The heads-up box and the agents' numbers, drawn onto finished frames with Pillow: matplotlib lays
    out and renders a text artist every frame, which cost more than every other artist together.

    Args:
        font_px: px, size of the heads-up text (the numbers are 0.85 of it).
        title: first line of the heads-up box.
        widest: the longest second line expected (the box is sized for it once).
        size: (width, height) px of the frames.
    """

    LINE_SPACING = 1.35
    PAD = 0.45  # of the font size, around the text in the box

    def __init__(self, font_px: float, title: str, widest: str, size: tuple[int, int]) -> None:
        from matplotlib import font_manager
        from PIL import ImageFont

        mono = font_manager.findfont(font_manager.FontProperties(family="DejaVu Sans Mono"))
        bold = font_manager.findfont(font_manager.FontProperties(family="DejaVu Sans", weight="bold"))
        self.mono = ImageFont.truetype(mono, max(6, round(font_px)))
        self.bold = ImageFont.truetype(bold, max(6, round(0.85 * font_px)))
        self.title = title
        pad = self.PAD * font_px
        self.origin = (0.012 * size[0], 0.012 * size[1])
        self.line = self.LINE_SPACING * font_px
        width = max(self.mono.getlength(title), self.mono.getlength(widest + "  "))
        x0, y0 = self.origin
        self.box = (x0, y0, x0 + width + 2 * pad, y0 + 2 * self.line + 2 * pad - (self.LINE_SPACING - 1) * font_px)
        self.text_xy = (x0 + pad, y0 + pad)

    def draw(
        self,
        rgba: Any,
        size: tuple[int, int],
        hud: str,
        labels: Sequence[tuple[str, tuple[float, float], tuple[int, int, int]]],
    ) -> NDArray[np.uint8]:
        """The RGB frame (height, width, 3) of the RGBA pixels ``rgba`` (a buffer of ``size`` (width,
        height) px) with the heads-up box (title and ``hud``) and the ``labels`` (text, bottom-left
        corner px, RGB) drawn on it."""
        from PIL import Image, ImageDraw

        image = Image.frombuffer("RGBA", size, rgba, "raw", "RGBA", 0, 1).convert("RGB")
        draw = ImageDraw.Draw(image, "RGBA")
        draw.rounded_rectangle(
            self.box, radius=0.3 * self.line, fill=(255, 255, 255, 217), outline=(153, 153, 153, 255), width=1
        )
        x, y = self.text_xy
        draw.text((x, y), self.title, font=self.mono, fill=(0, 0, 0, 255))
        draw.text((x, y + self.line), hud, font=self.mono, fill=(0, 0, 0, 255))
        for text, (u, v), color in labels:
            draw.text((u, v), text, font=self.bold, fill=(*color, 255), anchor="ls")
        return np.asarray(image)


# ----------------------------------------------------------------------------- renderer
@dataclasses.dataclass(frozen=True)
class ReplayOptions:
    """How a replay is drawn.

    Attributes:
        view: the camera.
        speed: simulated seconds per second of video.
        size: (width, height) px, both even.
        fps: frames per second.
        trail_s: s of simulated time drawn behind each agent.
        show_speed: end the heads-up line with the playback speed (a still has none).
    """

    view: View = View.THREE_D
    speed: float = DEFAULT_SPEED
    size: tuple[int, int] = DEFAULT_SIZE
    fps: int = DEFAULT_FPS
    trail_s: float = TRAIL_S
    show_speed: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "view", View(self.view))
        w, h = (int(v) for v in self.size)
        if w < 64 or h < 64 or w % 2 or h % 2:
            raise ValueError(f"size: expected an even width and height of at least 64 px, got {self.size!r}")
        object.__setattr__(self, "size", (w, h))
        if not (isinstance(self.speed, (int, float)) and math.isfinite(self.speed) and self.speed > 0):
            raise ValueError(f"speed: expected a positive number, got {self.speed!r}")
        if not (isinstance(self.fps, int) and self.fps > 0):
            raise ValueError(f"fps: expected a positive integer, got {self.fps!r}")


class ReplayRenderer:
    """Draws frames of a replay; artists are made once and updated for every frame.

    Args:
        data: the run, from ``load_replay``.
        options: view, speed, size, frame rate.
    """

    def __init__(self, data: ReplayData, options: ReplayOptions = ReplayOptions()) -> None:
        self.data = data
        self.options = options
        w, h = options.size
        self.size = (w, h)
        self.font = 13.0 * h / 720.0
        self.hud_px = 3.3 * self.font * DPI / 72.0
        self.colors = agent_colors(data.n_agents)
        self._flash_life = max(FLASH_S, FLASH_FRAMES * options.speed / options.fps)
        self._prepare_events()
        self._prepare_camera()
        self.fig = Figure(figsize=(w / DPI, h / DPI), dpi=DPI, facecolor=BACKGROUND)
        self.canvas = FigureCanvasAgg(self.fig)
        ax = self.fig.add_axes((0.0, 0.0, 1.0, 1.0))
        ax.set_xlim(0.0, w)
        ax.set_ylim(h, 0.0)
        ax.set_axis_off()
        ax.set_facecolor(BACKGROUND)
        self.ax = ax
        self._make_artists()
        self._camera: ViewCamera | None = None
        self._pheromone_k = -1
        self._background: Any = None

    # ---------------------------------------------------------------- set-up
    def _prepare_events(self) -> None:
        d = self.data
        contacts = [e for e in d.events if e.kind in CONTACT_KINDS]
        self._contact_t = np.array([e.time_s for e in contacts], dtype=float)
        self._contact_ends = [(self._entity(e.a), self._entity(e.b)) for e in contacts]
        placed = [
            (e.time_s, 1 if e.kind == "placed" else -1, _index(e.a, "box"))
            for e in d.events
            if e.kind in ("placed", "unplaced")
        ]
        self._placed_t = np.array([p[0] for p in placed], dtype=float)
        self._placed_count = np.cumsum([p[1] for p in placed]) if placed else np.zeros(0)
        self._placed_change = [(p[1] > 0, p[2]) for p in placed]  # (placed, box) in time order
        reached = [
            (e.time_s, _index(e.b, "waypoint") if e.kind == "waypoint" else _index(e.b, "point"))
            for e in d.events
            if e.kind in ("waypoint", "visit")
        ]
        self._target_t = np.full(len(d.targets), np.inf)
        for t, j in reached:
            if j is not None and j < len(d.targets):
                self._target_t[j] = min(self._target_t[j], t)
        crashes = [e for e in d.events if e.kind in ("crashed", "diverged")]
        self._crash = crashes[0] if crashes else None

    def _entity(self, name: str) -> tuple[str, int]:
        for prefix in ("agent", "box"):
            i = _index(name, prefix)
            if i is not None:
                return prefix, i
        return "fixed", -1

    def _prepare_camera(self) -> None:
        d, o = self.data, self.options
        if o.view is View.TOP:
            self._fixed: ViewCamera | None = top_camera(d.arena, self.size, hud_px=self.hud_px)
        elif o.view is View.THREE_D:
            self._fixed = perspective(*_fixed_3d(d, self.size), self.size)
        else:
            self._fixed = None
        if o.view is View.ORBIT:
            self._orbit = _orbit_base(d, self.size)
        if o.view is View.CHASE:
            self._track = chase_track(d)
        self._frame_t0 = float(d.t[0])

    def camera(self, t: float) -> ViewCamera:
        """The camera of the frame showing simulated time ``t`` s."""
        if self._fixed is not None:
            return self._fixed
        o = self.options
        video_t = (t - self._frame_t0) / o.speed
        if o.view is View.ORBIT:
            target, distance, pitch = self._orbit
            return perspective(target, distance, 360.0 * video_t / ORBIT_PERIOD_S, pitch, self.size)
        centroid, heading, spread = self._track
        c = np.array([np.interp(t, self.data.t, centroid[:, i]) for i in range(3)])
        a = float(np.interp(t, self.data.t, heading))
        s = float(np.interp(t, self.data.t, spread))
        distance = float(np.clip(2.5 * s + 1.2, 1.2, 1.5 * max(self.data.arena)))
        return perspective(c, distance, math.degrees(a) - 90.0, CHASE_PITCH_DEG, self.size)

    def _make_artists(self) -> None:
        ax, d, f = self.ax, self.data, self.font
        lw = max(1.0, 1.6 * self.size[1] / 720.0)
        # static scene (drawn into the cached background of a fixed camera), in drawing order
        self.floor = PolyCollection([], facecolors=[FLOOR], edgecolors=[(0.35, 0.35, 0.35, 1.0)], linewidths=lw)
        self.grid = LineCollection([], colors=[(0.0, 0.0, 0.0, 0.10)], linewidths=0.8 * lw)
        self.field = PolyCollection([], linewidths=0.0)
        self.slots = LineCollection([], colors=[(0.25, 0.25, 0.25, 0.7)], linewidths=lw, linestyles="--")
        self.obstacles = PolyCollection([], edgecolors=[(0.2, 0.2, 0.25, 0.5)], linewidths=0.6)
        self.static = [self.floor, self.grid, self.field, self.slots, self.obstacles]
        # moving artists (drawn in the order of self.moving)
        self.shadows = ax.scatter([], [], facecolors=[(0.0, 0.0, 0.0, 0.22)], linewidths=0.0)
        self.targets = ax.scatter([], [], marker="D", s=(0.9 * f) ** 2, linewidths=lw)
        self.boxes = PolyCollection([], linewidths=0.8 * lw)
        self.trails = LineCollection([], linewidths=2.0 * lw, capstyle="round")
        self.arms = LineCollection([], colors=[(0.15, 0.15, 0.15, 1.0)], linewidths=2.2 * lw)
        self.rotors = ax.scatter([], [], linewidths=lw)
        self.carried = PolyCollection([], linewidths=2.2 * lw)
        self.bodies = ax.scatter([], [], edgecolors=[(0.1, 0.1, 0.1, 1.0)], linewidths=lw)
        self.heading = LineCollection([], colors=[(0.1, 0.1, 0.1, 1.0)], linewidths=2.0 * lw)
        self.rings = ax.scatter([], [], facecolors="none", linewidths=2.5 * lw)
        self.stars = ax.scatter([], [], marker="*", linewidths=0.5)
        for c in (*self.static, self.boxes, self.trails, self.arms, self.carried, self.heading):
            ax.add_collection(c, autolim=False)
        self.moving = [
            self.shadows,
            self.targets,
            self.boxes,
            self.trails,
            self.arms,
            self.rotors,
            self.carried,
            self.bodies,
            self.heading,
            self.rings,
            self.stars,
        ]
        self.text = _TextLayer(
            self.font * DPI / 72.0,
            d.title,
            max((self.hud_text(float(t)) for t in (d.t[0], d.t[-1])), key=len),
            self.size,
        )
        self._labels: list[tuple[str, tuple[float, float], tuple[int, int, int]]] = []
        for a in self.moving:
            a.set_animated(True)
        self._field_cells = self._cells() if d.pheromone is not None else None
        if d.pheromone is not None:
            span = float(np.max(np.abs(d.pheromone.values))) or 1.0
            self._field_norm = TwoSlopeNorm(vcenter=0.0, vmin=-span, vmax=span)
            self._field_cmap = colormaps["RdBu_r"]

    def _cells(self) -> NDArray[np.float64]:
        """Floor quads (nx * ny, 4, 3) m of the pheromone cells, x-major as the snapshots."""
        ph = self.data.pheromone
        assert ph is not None
        nx, ny = ph.values.shape[1:]
        c = ph.cell
        x, y = np.meshgrid(np.arange(nx) * c, np.arange(ny) * c, indexing="ij")
        x, y = x.ravel(), y.ravel()
        z = np.full_like(x, 2e-3)
        return np.stack(
            [
                np.stack([x, y, z], 1),
                np.stack([x + c, y, z], 1),
                np.stack([x + c, y + c, z], 1),
                np.stack([x, y + c, z], 1),
            ],
            axis=1,
        )

    # ---------------------------------------------------------------- state at a time
    def state(self, t: float) -> dict[str, NDArray[Any]]:
        """Interpolated state at ``t`` s: agent positions (n, 3), rotations (n, 3, 3), box positions
        (B, 3), box rotations (B, 3, 3), box carriers (B,)."""
        d = self.data
        ts = d.t
        if ts.size == 1:
            i, w = 0, 0.0
        else:
            i = int(np.clip(np.searchsorted(ts, t, side="right") - 1, 0, ts.size - 2))
            w = float(np.clip((t - ts[i]) / (ts[i + 1] - ts[i]), 0.0, 1.0)) if ts[i + 1] > ts[i] else 0.0
        j = min(i + 1, ts.size - 1)

        def lerp(a: NDArray[np.float64]) -> NDArray[np.float64]:
            return (1.0 - w) * a[i] + w * a[j]

        def nlerp(q: NDArray[np.float64]) -> NDArray[np.float64]:
            a, b = q[i], q[j]
            b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0, -b, b)
            m = (1.0 - w) * a + w * b
            return m / np.maximum(np.linalg.norm(m, axis=-1, keepdims=True), 1e-12)

        return {
            "positions": lerp(d.positions),
            "rotations": quat_matrices(nlerp(d.quaternions)),
            "box_positions": lerp(d.box_positions),
            "box_rotations": quat_matrices(nlerp(d.box_quaternions)),
            "carried_by": d.box_carried_by[j if w >= 1.0 else i],
            "index": np.array(i),
        }

    # ---------------------------------------------------------------- static scene
    def _update_static(self, cam: ViewCamera) -> None:
        d = self.data
        lx, ly = d.arena
        floor = cam.clip(np.array([[0, 0, 0], [lx, 0, 0], [lx, ly, 0], [0, ly, 0]], dtype=float))
        self.floor.set_verts([cam.project(floor)[0]] if len(floor) >= 3 else [])
        step = 0.5 if max(lx, ly) <= 8 else 1.0 if max(lx, ly) <= 20 else 5.0
        lines = [np.array([[x, 0, 0], [x, ly, 0]]) for x in np.arange(step, lx - 1e-9, step)]
        lines += [np.array([[0, y, 0], [lx, y, 0]]) for y in np.arange(step, ly - 1e-9, step)]
        self.grid.set_segments([self._polyline(cam, seg) for seg in lines])
        self.slots.set_segments(self._slot_edges(cam))
        faces = [f for ob in d.obstacles for f in _obstacle_faces(ob)]
        if faces:
            polys = np.concatenate([p for p, _, _ in faces])
            normals = np.array([nrm for _, nrm, _ in faces])
            outlined = np.array([o for _, _, o in faces])
            centres = np.array([p.mean(axis=0) for p, _, _ in faces])
            px, depth = cam.project(polys)
            sizes = np.cumsum([0] + [len(p) for p, _, _ in faces])
            keep = cam.facing(centres, normals)
            shown, far = [], []
            for k in np.nonzero(keep)[0]:
                p2 = px[sizes[k] : sizes[k + 1]]
                if np.all(np.isfinite(p2)):
                    shown.append(k)
                    far.append(-float(np.mean(depth[sizes[k] : sizes[k + 1]])))
            order = [shown[i] for i in np.argsort(far, kind="stable")]
            self.obstacles.set_verts([px[sizes[k] : sizes[k + 1]] for k in order])
            fill = _shade(np.tile(OBSTACLE, (len(order), 1)), normals[order])
            self.obstacles.set_facecolor(_colours(fill))
            self.obstacles.set_edgecolor(_colours(np.where(outlined[order][:, None], (0.2, 0.2, 0.25, 0.6), fill)))
        if self._field_cells is not None:
            px, _ = cam.project(self._field_cells)
            self._field_ok = np.all(np.isfinite(px), axis=(1, 2))
            px[~self._field_ok] = 0.0
            self.field.set_verts(list(px))

    def _polyline(self, cam: ViewCamera, seg: NDArray[np.float64], step: float = 0.1) -> NDArray[np.float64]:
        """A straight segment (2, 3) m projected as a polyline broken (NaN) behind the near plane."""
        k = max(2, int(np.linalg.norm(seg[1] - seg[0]) / step) + 1) if not cam.orthographic else 2
        pts = seg[0] + np.linspace(0.0, 1.0, k)[:, None] * (seg[1] - seg[0])
        return cam.project(pts)[0]

    def _slot_edges(self, cam: ViewCamera) -> list[NDArray[np.float64]]:
        d = self.data
        if not len(d.slots):
            return []
        polys, _ = cube_faces(d.slots, np.tile(np.eye(3), (len(d.slots), 1, 1)), np.full((len(d.slots), 3), d.box_size))
        edges = []
        for face in polys.reshape(-1, 4, 3):
            p = cam.project(np.vstack([face, face[:1]]))[0]
            if np.all(np.isfinite(p)):
                edges.append(p)
        return edges

    def _update_field(self, t: float) -> bool:
        """Colour the pheromone cells with the last snapshot at ``t``; True when it changed."""
        ph = self.data.pheromone
        if ph is None:
            return False
        k = int(np.clip(np.searchsorted(ph.t, t + 1e-9, side="right") - 1, 0, ph.t.size - 1))
        if k == self._pheromone_k:
            return False
        self._pheromone_k = k
        v = ph.values[k].ravel().astype(float)
        rgba = np.asarray(self._field_cmap(self._field_norm(v)))
        rgba[:, 3] = np.where(np.abs(v) > 1e-9, 0.8, 0.0)
        rgba[~self._field_ok, 3] = 0.0
        self.field.set_facecolor(_colours(rgba))
        return True

    # ---------------------------------------------------------------- moving artists
    def _update_moving(self, cam: ViewCamera, t: float) -> None:
        d, st = self.data, self.state(t)
        pos, rot = st["positions"], st["rotations"]
        n = d.n_agents
        centre, depth = cam.project(pos)
        scale = cam.px_per_m(depth)
        # vehicles: arms to the rotors, rotor discs, body disc; at least MIN_ICON_FRACTION of the height across
        span_m = 2.0 * (float(np.max(np.linalg.norm(d.rotor_xy, axis=1))) + d.rotor_radius)
        icon = np.maximum(span_m * scale, MIN_ICON_FRACTION * self.size[1])  # px
        grow = icon / np.maximum(span_m * scale, 1e-9)
        rotor_body = np.column_stack([d.rotor_xy, np.zeros(4)])
        rotor_w = np.einsum("nij,rj->nri", rot, rotor_body) + pos[:, None, :]
        rpx = cam.project(rotor_w)[0]
        rpx = centre[:, None, :] + (rpx - centre[:, None, :]) * grow[:, None, None]
        self.arms.set_segments(
            [np.array([rpx[i, 0], rpx[i, 2]]) for i in range(n)] + [np.array([rpx[i, 1], rpx[i, 3]]) for i in range(n)]
        )
        self.rotors.set_offsets(rpx.reshape(-1, 2))
        rotor_px = 2.0 * d.rotor_radius * scale * grow  # px, rotor diameter
        self.rotors.set_sizes(np.repeat(self._pt2(rotor_px), 4))
        rc = np.repeat(self.colors, 4, axis=0).copy()
        rc[:, 3] = 0.45
        self.rotors.set_facecolor(_colours(rc))
        self.rotors.set_edgecolor(_colours(np.repeat(self.colors, 4, axis=0)))
        self.bodies.set_offsets(centre)
        self.shadows.set_offsets(cam.project(pos * [1.0, 1.0, 0.0])[0])
        self.shadows.set_sizes(self._pt2(0.5 * icon))
        self.bodies.set_sizes(self._pt2(0.34 * icon))
        self.bodies.set_facecolor(_colours(self.colors))
        nose = cam.project(pos + rot[:, :, 0] * (0.5 * span_m))[0]
        direction = nose - centre
        norm = np.linalg.norm(direction, axis=1, keepdims=True)
        unit = np.where(norm > 1e-6, direction / np.maximum(norm, 1e-9), 0.0)
        self.heading.set_segments(
            list(np.stack([centre + unit * (0.26 * icon)[:, None], centre + unit * (0.62 * icon)[:, None]], axis=1))
        )
        rgb = np.round(self.colors[:, :3] * 255).astype(int)
        self._labels = [
            (str(i), (centre[i, 0] + 0.36 * icon[i], centre[i, 1] - 0.30 * icon[i]), tuple(rgb[i]))
            for i in range(min(n, MAX_LABELLED_AGENTS) if n <= MAX_LABELLED_AGENTS else 0)
            if np.all(np.isfinite(centre[i]))
        ]
        self._update_trails(cam, t, pos, int(st["index"]))
        self._update_boxes(cam, t, st)
        self._update_flashes(cam, t, pos, st["box_positions"], icon)
        self._update_targets(cam, t)

    def _pt2(self, diameter_px: NDArray[np.float64]) -> NDArray[np.float64]:
        """Scatter sizes (points^2) of discs ``diameter_px`` across."""
        return (np.nan_to_num(np.asarray(diameter_px, dtype=float)) * 72.0 / DPI) ** 2

    def _update_trails(self, cam: ViewCamera, t: float, pos: NDArray[np.float64], i: int) -> None:
        d = self.data
        lo = int(np.searchsorted(d.t, t - self.options.trail_s, side="left"))
        past = d.positions[lo : i + 1]
        pts = np.concatenate([past, pos[None]], axis=0)  # (k, n, 3)
        px = cam.project(pts)[0]
        self.trails.set_segments([px[:, a] for a in range(d.n_agents)])
        c = self.colors.copy()
        c[:, 3] = 0.55
        self.trails.set_color(c)

    def _update_boxes(self, cam: ViewCamera, t: float, st: dict[str, NDArray[Any]]) -> None:
        d = self.data
        if d.n_boxes == 0:
            return
        carried_by = st["carried_by"]
        polys, normals = cube_faces(st["box_positions"], st["box_rotations"], np.full((d.n_boxes, 3), d.box_size))
        placed = self._placed_boxes(t)
        color = np.tile(BOX_FREE, (d.n_boxes, 1))
        color[list(placed)] = BOX_PLACED
        for carried in (False, True):
            sel = np.nonzero((carried_by >= 0) == carried)[0]
            faces, nrm = polys[sel].reshape(-1, 4, 3), normals[sel].reshape(-1, 3)
            owner = np.repeat(sel, 6)
            px, depth = cam.project(faces)
            keep = cam.facing(faces.mean(axis=1), nrm) & np.all(np.isfinite(px), axis=(1, 2))
            order = np.nonzero(keep)[0]
            order = order[np.argsort(-depth[order].mean(axis=1), kind="stable")]
            face_color = _shade(color[owner[order]], nrm[order])
            target = self.carried if carried else self.boxes
            target.set_verts(list(px[order]))
            target.set_facecolor(_colours(face_color))
            if carried:
                target.set_edgecolor(_colours(self.colors[carried_by[owner[order]]]))
            else:
                target.set_edgecolor(_colours(np.tile((0.25, 0.2, 0.15, 1.0), (len(order), 1))))

    def _placed_boxes(self, t: float) -> set[int]:
        placed: set[int] = set()
        for now_placed, box in self._placed_change[: int(np.searchsorted(self._placed_t, t, side="right"))]:
            if box is not None:
                if now_placed:
                    placed.add(box)
                else:
                    placed.discard(box)
        return placed

    def _update_flashes(
        self, cam: ViewCamera, t: float, pos: NDArray[np.float64], boxes: NDArray[np.float64], icon: NDArray[np.float64]
    ) -> None:
        if self._contact_t.size == 0:
            return
        active = np.nonzero((self._contact_t <= t + 1e-9) & (t < self._contact_t + self._flash_life))[0]
        ring_xy, ring_alpha, ring_size, star_xy, star_alpha = [], [], [], [], []
        for k in active:
            alpha = 1.0 - (t - self._contact_t[k]) / self._flash_life
            ends = []
            for kind, i in self._contact_ends[k]:
                if kind == "agent" and i < len(pos):
                    ends.append((pos[i], float(icon[i])))
                elif kind == "box" and i < len(boxes):
                    ends.append((boxes[i], 0.8 * float(np.median(icon))))
            if not ends:
                continue
            for p, size in ends:
                ring_xy.append(p)
                ring_size.append(1.25 * size)
                ring_alpha.append(alpha)
            star_xy.append(np.mean([p for p, _ in ends], axis=0))
            star_alpha.append(alpha)
        rgba = np.tile(FLASH, (len(ring_xy), 1))
        rgba[:, 3] = ring_alpha
        self.rings.set_offsets(cam.project(np.array(ring_xy).reshape(-1, 3))[0])
        self.rings.set_sizes(self._pt2(np.array(ring_size)))
        self.rings.set_edgecolor(_colours(rgba))
        srgba = np.tile((1.0, 0.85, 0.1, 1.0), (len(star_xy), 1))
        srgba[:, 3] = star_alpha
        self.stars.set_offsets(cam.project(np.array(star_xy).reshape(-1, 3))[0])
        self.stars.set_sizes(np.full(len(star_xy), (1.6 * self.font) ** 2))
        self.stars.set_facecolor(_colours(srgba))
        edge = np.tile(FLASH, (len(star_xy), 1))
        edge[:, 3] = star_alpha
        self.stars.set_edgecolor(_colours(edge))

    def _update_targets(self, cam: ViewCamera, t: float) -> None:
        d = self.data
        if not len(d.targets):
            return
        self.targets.set_offsets(cam.project(d.targets)[0])
        done = self._target_t <= t + 1e-9
        self.targets.set_facecolor(_colours(np.where(done[:, None], TARGET_DONE, (1.0, 1.0, 1.0, 0.8))))
        self.targets.set_edgecolor(_colours(np.where(done[:, None], TARGET_DONE, TARGET)))

    def hud_text(self, t: float) -> str:
        """The heads-up line of the frame at ``t`` s: time, boxes placed, targets reached, contacts so far."""
        d = self.data
        parts = [f"t = {t:7.2f} s / {float(d.t[-1]):.1f} s"]
        if len(d.slots):
            k = int(np.searchsorted(self._placed_t, t, side="right"))
            parts.append(f"boxes placed {int(self._placed_count[k - 1]) if k else 0}/{len(d.slots)}")
        if len(d.targets):
            parts.append(f"targets {int(np.count_nonzero(self._target_t <= t + 1e-9))}/{len(d.targets)}")
        parts.append(f"contacts {int(np.searchsorted(self._contact_t, t, side='right'))}")
        if self._crash is not None and self._crash.time_s <= t:
            parts.append(f"{self._crash.kind}: {self._crash.a}")
        if self.options.show_speed:
            parts.append(f"x{self.options.speed:g}")
        return "   ".join(parts)

    # ---------------------------------------------------------------- frames
    def frame(self, t: float) -> NDArray[np.uint8]:
        """The RGB frame (height, width, 3) uint8 showing simulated time ``t`` s."""
        cam = self.camera(t)
        dirty = cam is not self._camera
        if dirty:
            self._camera = cam
            self._update_static(cam)
            self._pheromone_k = -1
        if self._update_field(t) or dirty or self._background is None:
            self.canvas.draw()  # the static scene; animated artists are left out
            self._background = self.canvas.copy_from_bbox(self.fig.bbox)
        else:
            self.canvas.restore_region(self._background)
        self._update_moving(cam, t)
        for a in self.moving:
            self.ax.draw_artist(a)
        return self.text.draw(self.canvas.buffer_rgba(), self.size, self.hud_text(t), self._labels)

    def frames(self) -> Iterator[NDArray[np.uint8]]:
        """Every frame of the replay, in order."""
        for t in self.times():
            yield self.frame(float(t))

    def times(self) -> NDArray[np.float64]:
        """Simulated times (k,) s of the frames."""
        d, o = self.data, self.options
        return frame_times(float(d.t[0]), float(d.t[-1]), o.speed, o.fps)
