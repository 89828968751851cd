"""Tasks: what the swarm must achieve, how completion is judged, task-specific metrics."""
from __future__ import annotations

from typing import Any

# kind -> pydantic model of the task section; task modules register themselves here.
TASK_MODELS: dict[str, Any] = {}


def task_models() -> dict[str, Any]:
    """Every task model by kind (imports the task modules so that they register)."""
    from pybullet_swarm.tasks import construction  # noqa: F401

    return TASK_MODELS
