"""Planners, avoidance layers and their registration by name, with their parameter models.

Planner modules register themselves with ``register_planner`` when imported; ``load`` imports
the bundled modules once (a module that is not there yet is skipped), then registers the classes
other packages name in the entry-point groups ``pybullet_swarm.planners`` and
``pybullet_swarm.avoidance`` (``pybullet_swarm.plugins``). Every class is checked against its
protocol when it registers (``Planner`` or ``CentralPlanner``, ``AvoidanceLayer``) and its optional
abilities (``planning.capabilities``) are recorded in its entry. A plug-in that does not satisfy its
protocol is refused in one line naming its distribution and what is missing (``refused()``).

Each entry records the plug-in's parameter model (a ``planning.params.Params`` subclass): the
scenario validates ``planner.params`` and ``avoidance_params`` against it at load, and the plug-in
is built from the validated instance: ``factory(params)`` for a planner, ``factory(setup, params)``
for a layer.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable, NamedTuple

from pybullet_swarm import plugins
from pybullet_swarm.plugins import BUILTIN_ORIGIN, Origin, PluginRefused
from pybullet_swarm.planning.base import AvoidanceLayer, CentralPlanner, Planner, TaskInfo
from pybullet_swarm.planning.capabilities import (
    ChecksTask,
    Medium,
    ProvidesMedium,
    PublishesArtefacts,
    ReportsActivities,
    ReportsActivity,
)
from pybullet_swarm.planning.params import NoParams, Params


class PlannerEntry(NamedTuple):
    """A registered planner and what it declares.

    Attributes:
        factory: ``factory(params) -> planner`` (the planner class).
        description: one line.
        tasks: task kinds it solves.
        params: its parameter model.
        origin: where it comes from (pybullet_swarm or an installed distribution).
        centralized: one instance for the swarm (``CentralPlanner``), else one per agent.
        make_medium: ``make_medium(params, info) -> Medium`` (``ProvidesMedium``), or None.
        check_task: ``check_task(task_model)`` raising ``ConfigError`` (``ChecksTask``), or None.
        reports_activity: its planners say what they do (``ReportsActivity``/``ReportsActivities``).
        publishes_artefacts: its planner publishes data (``PublishesArtefacts``).
    """

    factory: Callable[..., Any]
    description: str
    tasks: tuple[str, ...]
    params: type[Params]
    origin: Origin = BUILTIN_ORIGIN
    centralized: bool = False
    make_medium: Callable[[Any, TaskInfo], Medium] | None = None
    check_task: Callable[[Any], None] | None = None
    reports_activity: bool = False
    publishes_artefacts: bool = False


class AvoidanceEntry(NamedTuple):
    """A registered avoidance layer (``factory`` None: no layer).

    Attributes:
        factory: ``factory(setup, params) -> layer`` (the layer class), None for "none".
        description: one line.
        params: its parameter model.
        origin: where it comes from.
        needs_range_sensors: the clock gives every agent its fan of range rays.
        publishes_artefacts: the layer publishes files (``PublishesArtefacts``).
    """

    factory: Callable[..., Any] | None
    description: str
    params: type[Params]
    origin: Origin = BUILTIN_ORIGIN
    needs_range_sensors: bool = False
    publishes_artefacts: bool = False


PLANNERS: dict[str, PlannerEntry] = {}
AVOIDANCE_LAYERS: dict[str, AvoidanceEntry] = {"none": AvoidanceEntry(None, "no local avoidance (default)", NoParams)}
#: task kind -> default planner
DEFAULT_PLANNER: dict[str, str] = {}
#: name -> the one-line refusal of a plug-in that could not be registered
REFUSED: dict[str, PluginRefused] = {}

_MODULES = (
    "waypoints",
    "shortest_path",
    "stigmergy",
    "orca",
    "aco_tour",
    "reynolds",
    "laplacian",
    "braitenberg",
    "vasarhelyi",
    "olfati_saber",
)
_loaded = False


def _model(factory: Any, params: type[Params] | None, name: str) -> type[Params]:
    model = params if params is not None else getattr(factory, "Params", NoParams)
    if not (isinstance(model, type) and issubclass(model, Params)):
        raise TypeError(f"{name}: the parameter model must be a subclass of planning.params.Params, got {model!r}")
    return model


def _refuse(kind: str, name: str, origin: Origin, why: str) -> PluginRefused:
    exc = plugins.refusal(kind, name, origin, why)
    if origin.builtin:  # a bundled module that does not satisfy its protocol is a bug, not a user's plug-in
        raise TypeError(str(exc))
    return exc


def _as_class(kind: str, name: str, factory: Any, origin: Origin) -> Any:
    """``factory`` when it is a class (whose attributes the protocols name), else refused."""
    if not isinstance(factory, type):
        raise _refuse(kind, name, origin, f"must be a class, got {type(factory).__name__}")
    return factory


def _params_of(kind: str, name: str, cls: Any, params: type[Params] | None, origin: Origin) -> type[Params]:
    """The plug-in's parameter model (``params``, else ``cls.Params``, else none), else refused."""
    try:
        return _model(cls, params, name)
    except TypeError:
        raise _refuse(kind, name, origin, "Params must be a subclass of planning.params.Params") from None


def planner_entry(
    name: str,
    factory: Any,
    description: str,
    tasks: tuple[str, ...],
    *,
    params: type[Params] | None = None,
    origin: Origin = BUILTIN_ORIGIN,
) -> PlannerEntry:
    """The entry of a planner class, checked against ``Planner`` or ``CentralPlanner``.

    Raises:
        PluginRefused: a plug-in that is not a planner (what is missing named).
        TypeError: the same for a built-in one.
    """
    cls = _as_class("planner", name, factory, origin)
    if not isinstance(getattr(cls, "centralized", None), bool):
        raise _refuse("planner", name, origin, "missing the class attribute centralized (True or False)")
    central = cls.centralized
    protocol = CentralPlanner if central else Planner
    lacks = plugins.missing(factory, protocol, data=("name",))
    if lacks:
        raise _refuse("planner", name, origin, f"not a {protocol.__name__}: missing {', '.join(lacks)}")
    if not tasks or not all(isinstance(t, str) for t in tasks):
        raise _refuse("planner", name, origin, f"tasks must name at least one task kind, got {tasks!r}")
    return PlannerEntry(
        factory,
        description,
        tuple(tasks),
        _params_of("planner", name, cls, params, origin),
        origin=origin,
        centralized=central,
        make_medium=cls.make_medium if plugins.declares(factory, ProvidesMedium) else None,
        check_task=cls.check_task if plugins.declares(factory, ChecksTask) else None,
        reports_activity=plugins.declares(factory, ReportsActivities if central else ReportsActivity),
        publishes_artefacts=plugins.declares(factory, PublishesArtefacts),
    )


def register_planner(
    name: str,
    factory: Callable[..., Any],
    description: str,
    tasks: tuple[str, ...],
    *,
    default_for: tuple[str, ...] = (),
    params: type[Params] | None = None,
) -> None:
    """Make a planner class available by name (to ``--planner`` and ``pybullet-swarm list``).

    Args:
        name: the planner's name.
        factory: the planner class (``Planner``, or ``CentralPlanner`` with ``centralized = True``);
            ``factory(params)`` is given a validated instance of ``params``. Its optional abilities
            (``planning.capabilities``) are recorded: e.g. ``check_task(task)`` is called when a
            scenario is loaded and raises ``ConfigError`` for a task the planner cannot fly.
        description: one line.
        tasks: task kinds it solves.
        default_for: task kinds whose default planner it is.
        params: its parameter model (default: ``factory.Params``, else no parameters).

    Raises:
        TypeError: the class does not satisfy its protocol.
    """
    PLANNERS[name] = planner_entry(name, factory, description, tasks, params=params)
    for kind in default_for:
        DEFAULT_PLANNER[kind] = name


def avoidance_entry(
    name: str,
    factory: Any,
    description: str,
    *,
    params: type[Params] | None = None,
    origin: Origin = BUILTIN_ORIGIN,
) -> AvoidanceEntry:
    """The entry of an avoidance layer class, checked against ``AvoidanceLayer``.

    Raises:
        PluginRefused: a plug-in that is not a layer (what is missing named).
        TypeError: the same for a built-in one.
    """
    cls = _as_class("avoidance", name, factory, origin)
    lacks = plugins.missing(cls, AvoidanceLayer, data=("needs_range_sensors",))
    if lacks:
        raise _refuse("avoidance", name, origin, f"not an AvoidanceLayer: missing {', '.join(lacks)}")
    return AvoidanceEntry(
        factory,
        description,
        _params_of("avoidance", name, cls, params, origin),
        origin=origin,
        needs_range_sensors=bool(cls.needs_range_sensors),
        publishes_artefacts=plugins.declares(factory, PublishesArtefacts),
    )


def register_avoidance(
    name: str, factory: Callable[..., Any], description: str, *, params: type[Params] | None = None
) -> None:
    """Make a local avoidance layer class available by name (to ``--avoidance``); ``factory(setup, params)``
    gets a validated instance of ``params`` (default: ``factory.Params``).

    Raises:
        TypeError: the class does not satisfy ``AvoidanceLayer``.
    """
    AVOIDANCE_LAYERS[name] = avoidance_entry(name, factory, description, params=params)


def _description(cls: type) -> str:
    """A plug-in's one line: its ``description`` class attribute, else its docstring's first line."""
    text = getattr(cls, "description", None)
    if not isinstance(text, str):
        text = (cls.__doc__ or "").strip().partition("\n")[0]
    return " ".join(text.split())


def _load_plugins() -> None:
    """Register the classes installed distributions name in the planner and avoidance entry-point groups."""
    groups = ((plugins.PLANNERS_GROUP, "planner", PLANNERS), (plugins.AVOIDANCE_GROUP, "avoidance", AVOIDANCE_LAYERS))
    for group, kind, table in groups:
        for name, ep, origin in plugins.entry_points(group):
            try:
                if name in table:
                    raise plugins.refusal(kind, name, origin, f"the name is taken by {table[name].origin}")
                cls = plugins.load(kind, name, ep, origin)
                if kind == "planner":
                    tasks = getattr(cls, "tasks", ())
                    tasks = tuple(tasks) if isinstance(tasks, (tuple, list)) else ()
                    PLANNERS[name] = planner_entry(name, cls, _description(cls), tasks, origin=origin)
                else:
                    AVOIDANCE_LAYERS[name] = avoidance_entry(name, cls, _description(cls), origin=origin)
            except PluginRefused as exc:
                REFUSED[f"{kind} {name}"] = exc


def load() -> None:
    """Import every bundled planner module once so that they register, then the installed plug-ins."""
    global _loaded
    if _loaded:
        return
    _loaded = True
    for mod in _MODULES:
        try:
            importlib.import_module(f"pybullet_swarm.planning.{mod}")
        except ModuleNotFoundError as exc:
            if exc.name != f"pybullet_swarm.planning.{mod}":
                raise
    _load_plugins()


def refused() -> dict[str, PluginRefused]:
    """The plug-ins that could not be registered, by "kind name", with their one-line refusal."""
    load()
    return REFUSED


def make_medium(entry: PlannerEntry, params: Params, info: TaskInfo) -> Medium | None:
    """The shared medium of a run of ``entry``'s planner (None when it brings none).

    Raises:
        PluginRefused: what ``make_medium`` returned is not a ``Medium``.
    """
    if entry.make_medium is None:
        return None
    medium = entry.make_medium(params, info)
    if not isinstance(medium, Medium):
        lacks = ", ".join(plugins.methods(Medium))
        raise PluginRefused(f"planner from {entry.origin}: make_medium must return a Medium (with {lacks})")
    return medium


def planners() -> dict[str, PlannerEntry]:
    """Every registered planner."""
    load()
    return PLANNERS


def avoidance_layers() -> dict[str, AvoidanceEntry]:
    """Every registered avoidance layer."""
    load()
    return AVOIDANCE_LAYERS


def default_planner(kind: str) -> str | None:
    """The default planner of a task kind."""
    load()
    return DEFAULT_PLANNER.get(kind)
