"""Cameras that frame an arena: Bullet's yaw/pitch orbit camera, fitted to the arena and its flight volume.

Pure geometry (numpy only): ``World.render``, the GUI's camera (``World.set_camera``), the replay's
perspective views and the learning environments' frames all frame the arena with ``camera_for_arena``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

RENDER_FOV_DEG = 50.0  # vertical field of view of World.render, deg


@dataclasses.dataclass(frozen=True)
class Camera:
    """Orbit camera of ``World.render``.

    Attributes:
        target: (3,) m, the point looked at.
        distance: from the camera to ``target``, m.
        yaw: deg about +z; 0 puts the camera on the -y side looking along +y (x to the right).
        pitch: deg; negative looks down.
    """

    target: tuple[float, float, float]
    distance: float
    yaw: float
    pitch: float

    def __post_init__(self) -> None:
        target = tuple(float(v) for v in self.target)
        if len(target) != 3 or not all(math.isfinite(v) for v in target):
            raise ValueError(f"camera.target: expected 3 finite coordinates in m, got {self.target!r}")
        if not (math.isfinite(self.distance) and self.distance > 0.0):
            raise ValueError(f"camera.distance: expected a positive distance in m, got {self.distance!r}")
        if not (-90.0 < self.pitch < 90.0):
            raise ValueError(f"camera.pitch: expected a pitch in (-90, 90) deg, got {self.pitch!r}")
        object.__setattr__(self, "target", target)
        object.__setattr__(self, "distance", float(self.distance))
        object.__setattr__(self, "yaw", float(self.yaw))
        object.__setattr__(self, "pitch", float(self.pitch))

    def basis(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Forward, right and up unit vectors (3,) of the camera in the world frame."""
        return _basis(self.yaw, self.pitch)

    def eye(self) -> NDArray[np.float64]:
        """Camera position (3,) m."""
        forward = self.basis()[0]
        return np.asarray(self.target) - self.distance * forward


def _basis(yaw: float, pitch: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Forward, right, up (3,) of Bullet's yaw/pitch camera with +z up."""
    psi, theta = math.radians(yaw), math.radians(pitch)
    forward = np.array([-math.sin(psi) * math.cos(theta), math.cos(psi) * math.cos(theta), math.sin(theta)])
    right = np.array([math.cos(psi), math.sin(psi), 0.0])
    return forward, right, np.cross(right, forward)


def _box_corners(lx: float, ly: float, height: float) -> NDArray[np.float64]:
    """Corners (8, 3) m of [0, lx] x [0, ly] x [0, height]."""
    return np.array([[x, y, z] for x in (0.0, lx) for y in (0.0, ly) for z in (0.0, height)])


def _fit_distance(
    points: NDArray[np.float64], target: NDArray[np.float64], yaw: float, pitch: float, half_tan: tuple[float, float]
) -> float:
    """Smallest distance, m, at which ``points`` (k, 3) m project within ``half_tan`` (x, y).

    A point q (relative to the target) is in view when |q.r| <= tx (q.f + d) and
    |q.u| <= ty (q.f + d), f, r, u being the camera's forward, right and up axes.
    """
    forward, right, up = _basis(yaw, pitch)
    q = points - target
    depth = q @ forward
    need = np.maximum(np.abs(q @ right) / half_tan[0], np.abs(q @ up) / half_tan[1]) - depth
    return float(need.max())


def _centre_vertically(
    points: NDArray[np.float64], target: NDArray[np.float64], distance: float, yaw: float, pitch: float
) -> NDArray[np.float64]:
    """Target (3,) m moved along the camera's up axis so ``points`` (k, 3) are centred vertically.

    The move leaves depths and horizontal positions in the image unchanged.
    """
    forward, _, up = _basis(yaw, pitch)
    q = points - (target - distance * forward)
    depth, height = q @ forward, q @ up
    lo, hi = -distance, distance  # shift s of the eye along up, m; the image y of a point is (height - s) / depth
    for _ in range(60):
        s = 0.5 * (lo + hi)
        y = (height - s) / depth
        if y.max() + y.min() > 0.0:
            lo = s
        else:
            hi = s
    return target + 0.5 * (lo + hi) * up


def camera_for_arena(
    size_xy: Sequence[float],
    height: float = 1.0,
    *,
    pitch: float = -45.0,
    aspect: float = 16.0 / 9.0,
    fill: float = 0.92,
    fov_deg: float = RENDER_FOV_DEG,
) -> Camera:
    """Camera that frames the arena [0, Lx] x [0, Ly] x [0, height] from the side and above.

    The longer side of the arena runs across the image. The camera is as close as possible
    while the floor spans at most ``fill`` of the image and the whole flight volume stays
    inside it; the volume is then centred vertically.

    Args:
        size_xy: (2,) arena size Lx, Ly, m.
        height: top of the flight volume to keep in view, m.
        pitch: deg, negative looks down.
        aspect: width / height of the frames that will be rendered.
        fill: fraction of the image (both directions) the floor may span, in (0, 1].
        fov_deg: vertical field of view of the camera, deg (``World.render``'s by default; Bullet's GUI
            camera has 90).
    """
    lx, ly = (float(v) for v in size_xy)
    if not (lx > 0.0 and ly > 0.0 and math.isfinite(lx) and math.isfinite(ly)):
        raise ValueError(f"size_xy: expected two positive sizes in m, got {tuple(size_xy)!r}")
    if not (height >= 0.0 and math.isfinite(height)):
        raise ValueError(f"height: expected a non-negative height in m, got {height!r}")
    if not (0.0 < fill <= 1.0):
        raise ValueError(f"fill: expected a fraction in (0, 1], got {fill!r}")
    if not (-90.0 < pitch < 0.0):
        raise ValueError(f"pitch: expected a downward pitch in (-90, 0) deg, got {pitch!r}")
    if not aspect > 0.0:
        raise ValueError(f"aspect: expected a positive width/height ratio, got {aspect!r}")
    yaw = 0.0 if lx >= ly else 90.0
    if not (0.0 < fov_deg < 180.0):
        raise ValueError(f"fov_deg: expected a field of view in (0, 180) deg, got {fov_deg!r}")
    tan_y = math.tan(math.radians(fov_deg / 2.0))
    floor, volume = _box_corners(lx, ly, 0.0), _box_corners(lx, ly, height)
    target = np.array([lx / 2.0, ly / 2.0, 0.0])

    def distance_for(t: NDArray[np.float64]) -> float:
        return max(
            _fit_distance(floor, t, yaw, pitch, (fill * tan_y * aspect, fill * tan_y)),
            _fit_distance(volume, t, yaw, pitch, (tan_y * aspect, tan_y)),
        )

    for _ in range(4):
        target = _centre_vertically(volume, target, distance_for(target), yaw, pitch)
    return Camera(tuple(target.tolist()), distance_for(target), yaw, pitch)  # type: ignore[arg-type]
