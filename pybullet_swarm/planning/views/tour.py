"""The tour task's own types: the points to visit and how, told to every agent before the run."""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.base import TaskInfo


@dataclasses.dataclass(frozen=True)
class TourLayout:
    """What every agent of a tour run is told before it starts (``TaskInfo.layout``).

    Attributes:
        points: (W, 3) m, the inspection points.
        visit_radius: m, an agent this close to a point visits it.
        return_home: every agent flies home (``homes``) after its last point.
        homes: (n, 3) m, where each agent returns to.
        a_max: (3,) m/s^2 per-axis acceleration limit of the flight-time model, or None.
    """

    points: NDArray[np.float64]
    visit_radius: float
    return_home: bool
    homes: NDArray[np.float64]
    a_max: NDArray[np.float64] | None = None


#: what every agent of a tour run knows before it starts
TourInfo = TaskInfo[TourLayout]
