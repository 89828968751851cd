"""Planners and avoidance layers by name."""
from __future__ import annotations

from typing import Any, Callable

from pybullet_swarm.planning.shortest_path import ShortestPath
from pybullet_swarm.planning.waypoints import WaypointFollower

#: name -> (factory(**params), description, task kinds it solves)
PLANNERS: dict[str, tuple[Callable[..., Any], str, tuple[str, ...]]] = {
    "waypoints": (WaypointFollower, "centralised: every agent follows the task's timed set-points", ("waypoints",)),
    "shortest_path": (ShortestPath, "centralised baseline: boxes in structure order, straight lines at the "
                                    "search height, other agents ignored", ("construction",)),
}

#: task kind -> default planner
DEFAULT_PLANNER = {"waypoints": "waypoints", "construction": "shortest_path"}

AVOIDANCE: dict[str, str] = {"none": "no local avoidance (default)"}
