"""Range sensors: a fan of horizontal rays per agent, cast for the whole swarm in one batched call.

Geometry. Agent i carries ``r`` rays at bearings ``angles`` (rad, counter-clockwise from the
body x axis). The fan is levelled: it turns with the agent's yaw only, as a stabilised ring of
proximity sensors would, so a tilted airframe does not look at the ground. Each ray starts on
the circle enclosing the airframe (``start_offset`` m from the centre, so that it cannot hit
its own agent) and is ``range_m`` long; a reading is the free distance m from that circle to
the first body the ray hits (obstacles, walls, other agents, boxes), ``range_m`` when it hits
nothing.

Noise. A hit reads its true distance plus zero-mean Gaussian noise of ``noise_std_m``, clipped
to [0, range_m]; a miss reads exactly ``range_m`` (no echo). The noise comes from the run's
generator (a child spawned from ``Simulation.rng``).

The sensing layer never imports pybullet: casting goes through any object with the
``RayCaster`` interface (the World has it).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Protocol

import numpy as np
from numpy.typing import NDArray


class RayCaster(Protocol):
    """Anything that casts a batch of rays (the World)."""

    def ray_cast(
        self, starts: NDArray[np.float64], ends: NDArray[np.float64]
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Hit body handles (m,) (-1: none) and hit fractions (m,) in [0, 1] for rays (m, 3) m."""


def fan_angles(rays: int, fov_deg: float) -> NDArray[np.float64]:
    """Bearings (rays,) rad of a fan centred on the body x axis.

    A full circle (``fov_deg`` 360) spreads the rays evenly starting straight ahead (8 rays:
    every 45 deg); a narrower fan puts its outer rays on its edges (-fov/2 ... +fov/2).
    """
    if rays < 1:
        raise ValueError(f"rays must be >= 1, got {rays}")
    if fov_deg >= 360.0 - 1e-9:
        return 2.0 * np.pi * np.arange(rays) / rays
    if rays == 1:
        return np.zeros(1)
    half = 0.5 * math.radians(fov_deg)
    return np.linspace(-half, half, rays)


@dataclasses.dataclass(frozen=True)
class RangeFan:
    """Geometry of one agent's fan of rays.

    Attributes:
        angles: (r,) rad, ray bearings in the levelled body frame (0: body x, counter-clockwise).
        range_m: m, length of a ray (the longest reading).
        start_offset: m, rays start this far from the agent's centre.
    """

    angles: NDArray[np.float64]
    range_m: float
    start_offset: float

    @property
    def rays(self) -> int:
        """Rays per agent."""
        return int(self.angles.size)

    def bearings(self, yaws: NDArray[np.float64]) -> NDArray[np.float64]:
        """World bearings (n, r) rad of every ray for agents with yaws (n,) rad."""
        return np.asarray(yaws, dtype=float).reshape(-1, 1) + self.angles[None, :]

    def directions(self, yaws: NDArray[np.float64]) -> NDArray[np.float64]:
        """Unit horizontal ray directions (n, r, 3) in the world frame."""
        b = self.bearings(yaws)
        return np.stack([np.cos(b), np.sin(b), np.zeros_like(b)], axis=2)

    def segments(
        self, positions: NDArray[np.float64], yaws: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Ray start and end points, each (n * r, 3) m, agent-major, for positions (n, 3) m."""
        d = self.directions(yaws)
        p = np.asarray(positions, dtype=float).reshape(-1, 1, 3)
        starts = p + self.start_offset * d
        ends = p + (self.start_offset + self.range_m) * d
        return starts.reshape(-1, 3), ends.reshape(-1, 3)


class RangeSensor:
    """Noisy range readings of every agent's fan, from one batched ray cast.

    Args:
        fan: the fan geometry (the same for every agent).
        noise_std_m: m, standard deviation of the Gaussian noise on a hit.
        rng: the generator of the noise.
    """

    def __init__(self, fan: RangeFan, noise_std_m: float, rng: np.random.Generator) -> None:
        if noise_std_m < 0.0:
            raise ValueError(f"noise_std_m must be >= 0, got {noise_std_m}")
        self.fan = fan
        self.noise_std_m = float(noise_std_m)
        self.rng = rng
        self.readings = np.zeros((0, fan.rays))  # (n, r) m, the last readings
        self.hit_bodies = np.zeros((0, fan.rays), dtype=np.int64)  # (n, r) body handles, -1: none

    def read(self, caster: RayCaster, positions: NDArray[np.float64], yaws: NDArray[np.float64]) -> NDArray[np.float64]:
        """Cast every agent's fan once; returns (and keeps) the readings (n, r) m.

        Args:
            caster: casts the batch (the World).
            positions: (n, 3) m, agent centres.
            yaws: (n,) rad.
        """
        n, r = len(positions), self.fan.rays
        starts, ends = self.fan.segments(positions, yaws)
        hits, frac = caster.ray_cast(starts, ends)
        hits = np.asarray(hits, dtype=np.int64).reshape(n, r)
        dist = np.asarray(frac, dtype=float).reshape(n, r) * self.fan.range_m
        hit = hits >= 0
        if self.noise_std_m > 0.0:
            dist = dist + np.where(hit, self.rng.normal(0.0, self.noise_std_m, size=(n, r)), 0.0)
        out = np.where(hit, np.clip(dist, 0.0, self.fan.range_m), self.fan.range_m)
        self.readings = out
        self.hit_bodies = hits
        return out
