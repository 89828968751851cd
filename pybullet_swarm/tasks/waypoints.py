"""The waypoints task: every agent follows a timed list of set-points."""
from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.experiment.scenario import WaypointsTask


class WaypointsRuntime:
    """Runtime of a ``waypoints`` task: active set-point per agent and completion.

    Completion: after the last set-point became active, every agent stayed within
    ``tolerance_m`` of it for ``hold_s``.
    """

    def __init__(self, spec: WaypointsTask, starts: NDArray[np.float64]) -> None:
        self.spec = spec
        self.n = starts.shape[0]
        self.times = np.array([w.t_s for w in spec.waypoints])
        pts = np.array([w.position for w in spec.waypoints], dtype=float)           # (k, 3)
        self.points = pts[None, :, :] + (starts[:, None, :] if spec.relative else 0.0)  # (n, k, 3)
        self.yaws = np.radians([w.yaw_deg for w in spec.waypoints])
        self._held_since: float | None = None
        self.completed_at: float | None = None

    def active_index(self, t: float) -> int:
        """Index of the set-point active at time ``t`` s."""
        return max(int(np.searchsorted(self.times, t + 1e-9, side="right")) - 1, 0)

    def targets(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Target positions (n, 3) m and yaws (n,) rad at time ``t``."""
        k = self.active_index(t)
        return self.points[:, k, :], np.full(self.n, self.yaws[k])

    def update(self, t: float, positions: NDArray[np.float64]) -> bool:
        """Check completion at time ``t`` with agent positions (n, 3); True once completed."""
        if self.completed_at is not None:
            return True
        if t + 1e-9 < self.times[-1]:
            return False
        err = np.linalg.norm(positions - self.points[:, -1, :], axis=1)
        if np.all(err <= self.spec.tolerance_m):
            if self._held_since is None:
                self._held_since = t
            if t - self._held_since >= self.spec.hold_s - 1e-9:
                self.completed_at = t
                return True
        else:
            self._held_since = None
        return False
