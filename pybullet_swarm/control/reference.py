"""Reference shaping: waypoints or velocity set-points -> position/velocity/acceleration references."""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.control.kernels import shape_references


@dataclasses.dataclass(frozen=True)
class Reference:
    """References for the position loop.

    Attributes:
        positions: (n, 3) m.
        velocities: (n, 3) m/s.
        accelerations: (n, 3) m/s^2.
        yaw: (n,) rad.
        yaw_rate: (n,) rad/s.
    """

    positions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    accelerations: NDArray[np.float64]
    yaw: NDArray[np.float64]
    yaw_rate: NDArray[np.float64]


class ReferenceShaper:
    """Per-axis velocity- and acceleration-limited references, vectorised over agents.

    Targets are either positions (the reference follows a braking curve so it arrives without
    overshoot) or velocities (clipped to the limit); both change the reference velocity by at
    most ``a_max dt`` per tick. With ``v_max=None`` the shaper passes position targets through
    as raw steps (velocity and acceleration references zero).

    Args:
        n: number of agents.
        v_max: per-axis velocity limit (3,) m/s, or None for raw steps.
        a_max: per-axis acceleration limit (3,) m/s^2.
        dt: tick period, s.
    """

    def __init__(self, n: int, v_max: NDArray[np.float64] | None, a_max: NDArray[np.float64], dt: float) -> None:
        self.n = n
        self.v_max = None if v_max is None else np.asarray(v_max, dtype=float).reshape(3)
        self.a_max = np.asarray(a_max, dtype=float).reshape(3)
        self.dt = float(dt)
        self.p = np.zeros((n, 3))  # m
        self.v = np.zeros((n, 3))  # m/s
        self.a = np.zeros((n, 3))  # m/s^2
        self.yaw = np.zeros(n)  # rad
        self.yaw_rate = np.zeros(n)  # rad/s
        self.target = np.zeros((n, 3))  # m or m/s
        self.velocity_mode = np.zeros(n, dtype=np.bool_)
        self._ref = Reference(self.p, self.v, self.a, self.yaw, self.yaw_rate)
        self._args = (
            self.target,
            self.velocity_mode,
            self.p,
            self.v,
            self.a,
            self.v_max if self.v_max is not None else np.zeros(3),
            self.a_max,
            self.dt,
        )

    def reset(self, positions: NDArray[np.float64], yaw: NDArray[np.float64] | None = None) -> None:
        """Start at rest at ``positions`` (n, 3) m, holding them."""
        self.p[:] = positions
        self.v[:] = 0.0
        self.a[:] = 0.0
        self.target[:] = positions
        self.velocity_mode[:] = False
        self.yaw[:] = 0.0 if yaw is None else yaw

    def set_position_targets(self, targets: NDArray[np.float64], mask: NDArray[np.bool_] | None = None) -> None:
        """Aim agents (all, or those in ``mask``) at positions (n, 3) m."""
        if mask is None:
            self.target[:] = targets
            self.velocity_mode[:] = False
        else:
            self.target[mask] = targets[mask]
            self.velocity_mode[mask] = False

    def set_velocity_targets(self, velocities: NDArray[np.float64], mask: NDArray[np.bool_] | None = None) -> None:
        """Command agents (all, or those in ``mask``) with velocities (n, 3) m/s."""
        if mask is None:
            self.target[:] = velocities
            self.velocity_mode[:] = True
        else:
            self.target[mask] = velocities[mask]
            self.velocity_mode[mask] = True

    def leash(self, positions: NDArray[np.float64], lead: float) -> None:
        """Keep the position references of agents on velocity targets within ``lead`` m (per axis) of their
        ``positions`` (n, 3) m: the reference of an agent held back would run ahead of it, and the agent
        would later fly faster than commanded to catch up."""
        vm = self.velocity_mode
        if vm.any():
            self.p[vm] = np.clip(self.p[vm], positions[vm] - lead, positions[vm] + lead)

    def step(self) -> Reference:
        """Advance the references by one tick and return them (views, valid until the next step)."""
        if self.v_max is None:
            vm = ~self.velocity_mode
            self.p[vm] = self.target[vm]
            self.v[vm] = 0.0
            self.a[:] = 0.0
            if self.velocity_mode.any():
                self.v[~vm] = self.target[~vm]
                self.p[~vm] += self.v[~vm] * self.dt
        else:
            shape_references(*self._args)
        return self._ref

    @property
    def reference(self) -> Reference:
        """The current references (views of the shaper's arrays, updated in place)."""
        return self._ref
