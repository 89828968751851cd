"""The waypoints task: every agent follows a timed list of set-points."""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
import pydantic
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.planning.base import TaskView
from pybullet_swarm.planning.views.waypoints import SetPoints
from pybullet_swarm.tasks import register_task
from pybullet_swarm.tasks.base import TaskBase, TaskContext
from pybullet_swarm.types import Event, TimeSeries

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]


class _Strict(pydantic.BaseModel):
    model_config = pydantic.ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


class Waypoint(_Strict):
    """A timed set-point."""

    t_s: float = Field(ge=0.0, le=1e5)  # s, when it becomes active
    position: Vec3  # m, relative to the agent's start when `relative`
    yaw_deg: float = Field(0.0, ge=-360.0, le=360.0)


class WaypointsTask(_Strict):
    """Every agent follows a timed list of set-points; completed when all hold the last one."""

    kind: Literal["waypoints"]
    time_limit_s: float = Field(gt=0.0, le=1e5)
    waypoints: Annotated[list[Waypoint], Field(min_length=1)]
    relative: bool = True  # positions are offsets from each agent's start
    tolerance_m: float = Field(0.05, gt=0.0, le=100.0)
    hold_s: float = Field(1.0, ge=0.0, le=1e4)


class WaypointsRuntime(TaskBase):
    """Runtime of a ``waypoints`` task: active set-point per agent and completion.

    Completion: after the last set-point became active, every agent stayed within
    ``tolerance_m`` of it for ``hold_s``.
    """

    def __init__(self, spec: WaypointsTask, starts: NDArray[np.float64]) -> None:
        self.spec = spec
        self.n = starts.shape[0]
        self.times = np.array([w.t_s for w in spec.waypoints])
        pts = np.array([w.position for w in spec.waypoints], dtype=float)  # (k, 3)
        self.points = pts[None, :, :] + (starts[:, None, :] if spec.relative else 0.0)  # (n, k, 3)
        self.yaws = np.radians([w.yaw_deg for w in spec.waypoints])
        self._held_since: float | None = None
        self.completed_at: float | None = None
        self.events: list[Event] = []

    @classmethod
    def build(cls, spec: WaypointsTask, ctx: TaskContext) -> WaypointsRuntime:
        """The runtime factory registered in ``TASK_RUNTIMES``."""
        return cls(spec, ctx.starts)

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

    def view(self, t: float) -> TaskView:
        """The active set-points and yaws."""
        targets, yaws = self.targets(t)
        return TaskView(t, np.full(self.n, -1, dtype=np.int64), SetPoints(targets.copy(), yaws))

    def metrics(self, series: TimeSeries | None, planner_artefacts: dict[str, Any]) -> dict[str, Any]:
        """Nothing beyond the completion time and the flight metrics."""
        return {}


register_task("waypoints", WaypointsTask, WaypointsRuntime)
