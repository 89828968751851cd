"""Tasks: what the swarm must achieve, how completion is judged, task-specific metrics."""
from __future__ import annotations

from typing import Any

# kind -> pydantic model of the task section; task modules register themselves here.
TASK_MODELS: dict[str, Any] = {}
