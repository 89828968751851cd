"""Planners (behind one protocol), the pheromone medium, local avoidance and ant colony optimisation."""
from __future__ import annotations


def available_planners() -> dict[str, str]:
    """Planner names with a one-line description."""
    return {"waypoints": "centralised: every agent follows the task's timed set-points (default)"}


def available_avoidance() -> dict[str, str]:
    """Avoidance layer names with a one-line description."""
    return {"none": "no local avoidance (default)"}
