"""Tasks: what the swarm must achieve, how completion is judged, task-specific metrics.

Every task kind, the built-in ones included, registers with ``register_task(kind, Model, Runtime)``:

- ``Model``: the pydantic model of its scenario section ``task`` (validated at load; it may declare
  ``check(scenario, source)`` to refuse layouts that cannot work, ``ChecksScenario``, and
  ``plan_info(vehicle)``, the static layout the planners will be told, ``PublishesPlanInfo``);
- ``Runtime``: a ``TaskRuntime`` class (``pybullet_swarm.tasks.base``) built with
  ``Runtime.build(spec, context)``.

The class is checked against the protocol when it registers. Another package registers a task
the same way through the entry-point group ``pybullet_swarm.tasks`` (the kind is the entry
point's name, the class names its model as ``Model``); ``task_entries()`` imports the bundled task
modules and reads the entry points once.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable, NamedTuple

from pybullet_swarm import plugins
from pybullet_swarm.plugins import BUILTIN_ORIGIN, Origin, PluginRefused

# kind -> pydantic model of the task section (kept for readers of the two tables)
TASK_MODELS: dict[str, Any] = {}
# kind -> runtime factory(spec, TaskContext) -> TaskRuntime
TASK_RUNTIMES: dict[str, Callable[..., Any]] = {}


class TaskEntry(NamedTuple):
    """A registered task kind and what its model declares.

    Attributes:
        model: the pydantic model of the scenario's ``task`` section.
        factory: ``factory(spec, context) -> TaskRuntime``.
        origin: where it comes from (pybullet_swarm or an installed distribution).
        checks_scenario: the model refuses layouts that cannot work (``ChecksScenario``).
        publishes_plan_info: the model tells the static layout before a run (``PublishesPlanInfo``).
    """

    model: Any
    factory: Callable[..., Any]
    origin: Origin = BUILTIN_ORIGIN
    checks_scenario: bool = False
    publishes_plan_info: bool = False


TASKS: dict[str, TaskEntry] = {}
#: "task kind" -> the one-line refusal of a task plug-in that could not be registered
REFUSED: dict[str, PluginRefused] = {}

_MODULES = ("waypoints", "construction", "tour", "route", "flock")
_loaded = False


def task_entry(kind: str, model: Any, runtime: Any, *, origin: Origin = BUILTIN_ORIGIN) -> TaskEntry:
    """The entry of a task kind, its runtime class checked against ``TaskRuntime``.

    Raises:
        PluginRefused: a plug-in that is not a task (what is missing named).
        TypeError: the same for a built-in one.
    """
    import pydantic

    from pybullet_swarm.tasks.base import ChecksScenario, PublishesPlanInfo, TaskRuntime

    def refuse(why: str) -> PluginRefused:
        exc = plugins.refusal("task", kind, origin, why)
        if origin.builtin:
            raise TypeError(str(exc))
        return exc

    if not (isinstance(model, type) and issubclass(model, pydantic.BaseModel)):
        raise refuse(f"Model must be a pydantic model of the task section, got {model!r}")
    lacks = [f for f in ("kind", "time_limit_s") if f not in model.model_fields]
    if lacks:
        raise refuse(f"Model misses the field {', '.join(lacks)}")
    if not isinstance(runtime, type):
        raise refuse(f"must be a class, got {type(runtime).__name__}")
    lacks = plugins.missing(runtime, TaskRuntime, data=("build",))
    if lacks:
        raise refuse(f"not a TaskRuntime: missing {', '.join(lacks)}")
    cls: Any = runtime
    return TaskEntry(
        model,
        cls.build,
        origin=origin,
        checks_scenario=plugins.declares(model, ChecksScenario),
        publishes_plan_info=plugins.declares(model, PublishesPlanInfo),
    )


def register_task(kind: str, model: Any, runtime: Any) -> None:
    """Make a task kind available (to scenarios' ``task.kind``): its model and its runtime class.

    Raises:
        TypeError: the classes do not satisfy the protocol.
    """
    _register(kind, task_entry(kind, model, runtime))


def _register(kind: str, entry: TaskEntry) -> None:
    TASKS[kind] = entry
    TASK_MODELS[kind] = entry.model
    TASK_RUNTIMES[kind] = entry.factory


def _load() -> None:
    global _loaded
    if _loaded:
        return
    _loaded = True
    for mod in _MODULES:
        importlib.import_module(f"pybullet_swarm.tasks.{mod}")
    for kind, ep, origin in plugins.entry_points(plugins.TASKS_GROUP):
        try:
            if kind in TASK_MODELS:
                taken = TASKS[kind].origin if kind in TASKS else plugins.BUILTIN
                raise plugins.refusal("task", kind, origin, f"the kind is taken by {taken}")
            cls = plugins.load("task", kind, ep, origin)
            _register(kind, task_entry(kind, cls.__dict__.get("Model"), cls, origin=origin))
        except PluginRefused as exc:
            REFUSED[f"task {kind}"] = exc


def task_entries() -> dict[str, TaskEntry]:
    """Every task kind's entry (imports the bundled task modules and reads the entry points once)."""
    _load()
    for kind, model in TASK_MODELS.items():  # a kind written straight into the two tables
        if kind not in TASKS and kind in TASK_RUNTIMES:
            from pybullet_swarm.tasks.base import ChecksScenario, PublishesPlanInfo

            TASKS[kind] = TaskEntry(
                model,
                TASK_RUNTIMES[kind],
                checks_scenario=plugins.declares(model, ChecksScenario),
                publishes_plan_info=plugins.declares(model, PublishesPlanInfo),
            )
    return TASKS


def refused() -> dict[str, PluginRefused]:
    """The task plug-ins that could not be registered, by "task kind", with their one-line refusal."""
    _load()
    return REFUSED


def task_models() -> dict[str, Any]:
    """Every task model by kind."""
    task_entries()
    return TASK_MODELS


def task_runtimes() -> dict[str, Callable[..., Any]]:
    """Every task runtime factory by kind."""
    task_entries()
    return TASK_RUNTIMES
