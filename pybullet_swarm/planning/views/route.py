"""The route and flock tasks' own types: the route every agent is told before the run."""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.base import TaskInfo


@dataclasses.dataclass(frozen=True)
class RouteLayout:
    """A route to fly, told to every agent before it starts (``TaskInfo.layout`` of a route run).

    Attributes:
        route: (W, 3) m, the waypoints in order; z is the altitude to fly them at.
        pass_radius: m, horizontal distance that counts as passing a waypoint.
        formation_slots: (n, 3) m, the formation's slots centred on their mean, None for a flock.
    """

    route: NDArray[np.float64]
    pass_radius: float
    formation_slots: NDArray[np.float64] | None = None


@dataclasses.dataclass(frozen=True, kw_only=True)
class FlockLayout(RouteLayout):
    """A flock's circuit and flight settings (``TaskInfo.layout`` of a flock run); the circuit is its route.

    Attributes:
        circuit: (centre x m, centre y m, radius m) of the circle the flock flies around.
        altitude: m, the flight altitude.
        v_flock: m/s, the flock's preferred speed.
        r_coll: m, centre distance below which two agents count as colliding.
        connection_range_m: m, neighbours within it count as connected.
    """

    circuit: tuple[float, float, float]
    altitude: float
    v_flock: float
    r_coll: float
    connection_range_m: float


#: what every agent of a route run knows before it starts
RouteInfo = TaskInfo[RouteLayout]
#: what every agent of a flock run knows before it starts
FlockInfo = TaskInfo[FlockLayout]
