"""The waypoints task's own types: the set-points it shows."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.base import TaskView


@dataclasses.dataclass(frozen=True)
class SetPoints:
    """Each agent's active set-point now (``TaskView.state`` of a waypoints run).

    Attributes:
        targets: (n, 3) m, each agent's active set-point.
        target_yaws: (n,) rad, with ``targets``.
    """

    targets: NDArray[np.float64]
    target_yaws: NDArray[np.float64]


#: what a waypoints task shows at a planner tick
WaypointsView = TaskView[SetPoints]


def set_points_of(view: TaskView[Any]) -> SetPoints | None:
    """The set-points a view shows, None when its task has none."""
    return view.state if isinstance(view.state, SetPoints) else None
