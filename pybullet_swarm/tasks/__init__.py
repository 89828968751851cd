"""Tasks: what the swarm must achieve, how completion is judged, task-specific metrics.

Every task kind, the built-in ones included, registers the same two things:

- ``TASK_MODELS[kind]``: the pydantic model of its scenario section ``task`` (validated at load;
  an optional ``check(scenario, source)`` method refuses layouts that cannot work);
- ``TASK_RUNTIMES[kind]``: ``factory(spec, context) -> TaskRuntime`` (``pybullet_swarm.tasks.base``).

A user task registers itself the same way from its own module (import it before loading the
scenario); ``task_models()`` imports the bundled task modules.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable

# kind -> pydantic model of the task section; task modules register themselves here.
TASK_MODELS: dict[str, Any] = {}
# kind -> runtime factory(spec, TaskContext) -> TaskRuntime
TASK_RUNTIMES: dict[str, Callable[..., Any]] = {}

_MODULES = ("waypoints", "construction", "tour", "route", "flock")


def task_models() -> dict[str, Any]:
    """Every task model by kind (imports the task modules so that they register)."""
    for mod in _MODULES:
        importlib.import_module(f"pybullet_swarm.tasks.{mod}")
    return TASK_MODELS


def task_runtimes() -> dict[str, Callable[..., Any]]:
    """Every task runtime factory by kind."""
    task_models()
    return TASK_RUNTIMES
