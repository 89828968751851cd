"""Tasks: what the swarm must achieve, how completion is judged, task-specific metrics.

A task module registers the pydantic model of its scenario section in ``TASK_MODELS`` and, for
tasks beyond the built-in ``waypoints`` and ``construction``, a runtime factory in
``TASK_RUNTIMES``: ``factory(spec, sim) -> runtime`` with

- ``completed_at: float | None`` and ``events: list[Event]``,
- ``update(t, sim) -> bool`` (called every planner tick; True once completed),
- ``task_info() -> dict`` (keyword arguments for ``TaskInfo``: ``route``, ``slots``, ``extra`` ...),
- ``metrics(sim, timeseries) -> dict`` (task metrics merged into ``metrics.json``).
"""
from __future__ import annotations

import importlib
from typing import Any, Callable

# kind -> pydantic model of the task section; task modules register themselves here.
TASK_MODELS: dict[str, Any] = {}
# kind -> runtime factory(spec, sim) for the generic task protocol above.
TASK_RUNTIMES: dict[str, Callable[..., Any]] = {}

_MODULES = ("construction", "tour", "route")


def task_models() -> dict[str, Any]:
    """Every task model by kind (imports the task modules so that they register)."""
    for mod in _MODULES:
        try:
            importlib.import_module(f"pybullet_swarm.tasks.{mod}")
        except ModuleNotFoundError as exc:
            if exc.name != f"pybullet_swarm.tasks.{mod}":
                raise
    return TASK_MODELS
