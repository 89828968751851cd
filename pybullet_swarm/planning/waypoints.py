"""The default planner of waypoint tasks: every agent follows the task's timed set-points."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from pybullet_swarm.planning.base import Command, TaskInfo, WorldView
from pybullet_swarm.planning.views.waypoints import SetPoints
from pybullet_swarm.planning.params import NoParams


class WaypointFollower:
    """Centralised: every agent flies to the set-point the task shows as active (``SetPoints.targets`` of its view).

    Args:
        params: none (``NoParams``).
    """

    name: ClassVar[str] = "waypoints"
    centralized: ClassVar[bool] = True
    Params: ClassVar[type[NoParams]] = NoParams

    def __init__(self, params: NoParams | None = None) -> None:
        self.params = params if params is not None else NoParams()

    def reset(self, n: int, rng: np.random.Generator, info: TaskInfo) -> None:
        """Nothing to prepare: the set-points come with every tick's view."""
        self.n = n

    def plan_all(self, view: WorldView) -> list[Command]:
        """Each agent's active set-point (holding position when the task shows none)."""
        shown = view.task.state
        if not isinstance(shown, SetPoints) or len(shown.targets) != self.n:
            return [Command.hold() for _ in range(self.n)]
        return [Command.goto(shown.targets[i], yaw=float(shown.target_yaws[i])) for i in range(self.n)]


from pybullet_swarm.planning.registry import register_planner  # noqa: E402

register_planner(
    "waypoints",
    WaypointFollower,
    "centralised: every agent follows the task's timed set-points",
    ("waypoints",),
    default_for=("waypoints",),
)
