"""The default planner of waypoint tasks: every agent follows the task's timed set-points."""
from __future__ import annotations

from typing import Callable, ClassVar

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.base import Command, TaskInfo, WorldView
from pybullet_swarm.planning.params import NoParams


class WaypointFollower:
    """Centralised: reads the task's schedule (``info.extra['schedule']``: t -> (targets (n, 3), yaws (n,))).

    Args:
        params: none (``NoParams``).
    """

    name: ClassVar[str] = "waypoints"
    centralized: ClassVar[bool] = True
    Params: ClassVar[type[NoParams]] = NoParams

    def __init__(self, params: NoParams | None = None) -> None:
        self.params = params if params is not None else NoParams()

    def reset(self, n: int, rng: np.random.Generator, info: TaskInfo) -> None:
        """Keep the task's schedule."""
        self.schedule: Callable[[float], tuple[NDArray[np.float64], NDArray[np.float64]]] = info.extra["schedule"]

    def plan_all(self, view: WorldView) -> list[Command]:
        """Each agent's active set-point."""
        targets, yaws = self.schedule(view.time_s)
        return [Command.goto(targets[i], yaw=float(yaws[i])) for i in range(len(targets))]


from pybullet_swarm.planning.registry import register_planner  # noqa: E402

register_planner("waypoints", WaypointFollower, "centralised: every agent follows the task's timed set-points",
                 ("waypoints",), default_for=("waypoints",))
