"""The types of tasks with points to pass or visit (``route``, ``tour``): the points and which are done."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.base import TaskView


@dataclasses.dataclass(frozen=True)
class Points:
    """The points to pass or visit and which count as done now (``TaskView.state`` of a route or a tour).

    Attributes:
        points: (W, 3) m, in the task's order.
        points_done: (W,) True once a point counts as passed or visited.
    """

    points: NDArray[np.float64]
    points_done: NDArray[np.bool_]


#: what a route or a tour shows at a planner tick
PointsView = TaskView[Points]

#: the state of a task without points
NO_POINTS = Points(np.zeros((0, 3)), np.zeros(0, dtype=bool))


def points_of(view: TaskView[Any]) -> Points:
    """The points a view shows (``NO_POINTS`` when its task has none): for consumers that serve several
    task kinds (the learning environments)."""
    return view.state if isinstance(view.state, Points) else NO_POINTS
