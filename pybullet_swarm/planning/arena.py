"""What a flocking planner knows of its arena: the bounding walls and the pillars, as seen from one agent.

Both flocking models that avoid obstacles (``vasarhelyi``, ``olfati_saber``) replace each wall and
each convex obstacle by a virtual agent at the point of it nearest to the agent, moving
perpendicular to it (Vásárhelyi's shill agents, Olfati-Saber's beta agents). This module gives
those points in the horizontal plane.

The arena is [0, Lx] x [0, Ly] (``TaskInfo.arena_size``); its walls are known to every agent
(``TaskInfo.extra["arena_walls"]``; a flocking planner keeps to the arena even without physical
walls). Pillars come from ``TaskInfo.extra["pillars"]``: (K, 3) [x, y, radius] m, the scenario's
cylinders and, conservatively, the circle around each box obstacle's footprint.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.base import TaskInfo
from pybullet_swarm.planning.views.route import FlockInfo

#: (4, 2) inward unit normals of the walls x = 0, x = Lx, y = 0, y = Ly
WALL_NORMALS = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])


@dataclasses.dataclass(frozen=True)
class ArenaGeometry:
    """The walls and pillars of a flocking arena (horizontal plane).

    Attributes:
        size: (2,) m, the arena is [0, Lx] x [0, Ly].
        pillars: (K, 3) [x, y, radius] m.
    """

    size: NDArray[np.float64]
    pillars: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))

    @staticmethod
    def from_info(info: TaskInfo) -> ArenaGeometry:
        """The arena the agents are told of."""
        pillars = np.asarray(info.extra.get("pillars", np.zeros((0, 3))), dtype=float).reshape(-1, 3)
        return ArenaGeometry(np.asarray(info.arena_size, dtype=float).reshape(2), pillars)

    def walls(self, xy: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The nearest point of each wall to ``xy`` (2,) m.

        Returns:
            points (4, 2) m, inward normals (4, 2), distances (4,) m (0 when ``xy`` is beyond the wall).
        """
        x, y = float(xy[0]), float(xy[1])
        lx, ly = float(self.size[0]), float(self.size[1])
        points = np.array([[0.0, y], [lx, y], [x, 0.0], [x, ly]])
        dist = np.maximum(np.array([x, lx - x, y, ly - y]), 0.0)
        return points, WALL_NORMALS, dist

    def pillar_points(
        self, xy: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The nearest point of each pillar's surface to ``xy`` (2,) m.

        Returns:
            points (K, 2) m, outward normals (K, 2) towards ``xy``, distances (K,) m from the surface (0 inside).
        """
        if len(self.pillars) == 0:
            return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0)
        c, r = self.pillars[:, :2], self.pillars[:, 2]
        d = np.asarray(xy, dtype=float)[None, :2] - c
        norm = np.linalg.norm(d, axis=1)
        u = np.where(norm[:, None] > 1e-9, d / np.where(norm > 1e-9, norm, 1.0)[:, None], np.array([1.0, 0.0]))
        return c + r[:, None] * u, u, np.maximum(norm - r, 0.0)


def flight_limits(
    info: FlockInfo, v_flock: float | None, v_max: float | None
) -> tuple[float, float, float, NDArray[np.float64]]:
    """A flocking agent's speeds and altitude: (v_flock m/s, the parameter or the task's; the speed cap m/s, the
    parameter or 4/3 v_flock; the task's flight altitude m; the (3,) m/s per-axis limits, 1e9 where unlimited)."""
    flock = float(v_flock if v_flock is not None else info.layout.v_flock)
    cap = float(v_max if v_max is not None else 4.0 / 3.0 * flock)
    return flock, cap, float(info.layout.altitude), np.where(np.isfinite(info.v_max), info.v_max, 1e9)


def altitude_velocity(z: float, altitude: float, gain: float) -> float:
    """Vertical velocity m/s pulling altitude z m towards ``altitude`` m at ``gain`` 1/s."""
    return gain * (altitude - z)


def cap_speed(v: NDArray[np.float64], v_max: float) -> NDArray[np.float64]:
    """Velocity v m/s scaled down, direction kept, to a magnitude of at most ``v_max`` m/s."""
    s = float(np.linalg.norm(v))
    return v * (v_max / s) if s > v_max else v
