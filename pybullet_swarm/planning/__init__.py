"""Planners (behind one protocol), the pheromone medium, local avoidance and ant colony optimisation."""

from __future__ import annotations


def available_planners() -> dict[str, str]:
    """Planner names with a one-line description."""
    from pybullet_swarm.planning.registry import planners

    return {name: f"{e.description} [tasks: {', '.join(e.tasks)}]" for name, e in planners().items()}


def available_avoidance() -> dict[str, str]:
    """Avoidance layer names with a one-line description."""
    from pybullet_swarm.planning.registry import avoidance_layers

    return {name: e.description for name, e in avoidance_layers().items()}
