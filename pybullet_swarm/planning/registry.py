"""Planners, avoidance layers and their registration by name, with their parameter models.

Planner modules register themselves with ``register_planner`` when imported; ``load`` imports
the known modules once (a module that is not there yet is skipped). Each entry records the
plug-in's parameter model (a ``planning.params.Params`` subclass): the scenario validates
``planner.params`` and ``avoidance_params`` against it at load, and the plug-in is built from
the validated instance: ``factory(params)`` for a planner, ``factory(sim, params)`` for a layer.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable, NamedTuple

from pybullet_swarm.planning.params import NoParams, Params


class PlannerEntry(NamedTuple):
    """A registered planner."""

    factory: Callable[..., Any]  # factory(params) -> planner
    description: str
    tasks: tuple[str, ...]  # task kinds it solves
    params: type[Params]  # its parameter model


class AvoidanceEntry(NamedTuple):
    """A registered avoidance layer (``factory`` None: no layer)."""

    factory: Callable[..., Any] | None  # factory(sim, params) -> layer
    description: str
    params: type[Params]


PLANNERS: dict[str, PlannerEntry] = {}
AVOIDANCE_LAYERS: dict[str, AvoidanceEntry] = {"none": AvoidanceEntry(None, "no local avoidance (default)", NoParams)}
#: task kind -> default planner
DEFAULT_PLANNER: dict[str, str] = {}

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


def _model(factory: Callable[..., Any] | None, params: type[Params] | None, name: str) -> type[Params]:
    model = params if params is not None else getattr(factory, "Params", NoParams)
    if not (isinstance(model, type) and issubclass(model, Params)):
        raise TypeError(f"{name}: the parameter model must be a subclass of planning.params.Params, got {model!r}")
    return model


def register_planner(
    name: str,
    factory: Callable[..., Any],
    description: str,
    tasks: tuple[str, ...],
    *,
    default_for: tuple[str, ...] = (),
    params: type[Params] | None = None,
) -> None:
    """Make a planner available by name (to ``--planner`` and ``pybullet-swarm list``).

    Args:
        name: the planner's name.
        factory: ``factory(params) -> planner``, given a validated instance of ``params``. An
            optional ``factory.check_task(task)`` is called when a scenario is loaded and raises
            ``ConfigError`` for a task the planner cannot fly (``laplacian`` without a formation).
        description: one line.
        tasks: task kinds it solves.
        default_for: task kinds whose default planner it is.
        params: its parameter model (default: ``factory.Params``, else no parameters).
    """
    PLANNERS[name] = PlannerEntry(factory, description, tuple(tasks), _model(factory, params, name))
    for kind in default_for:
        DEFAULT_PLANNER[kind] = name


def register_avoidance(
    name: str, factory: Callable[..., Any], description: str, *, params: type[Params] | None = None
) -> None:
    """Make a local avoidance layer available by name (to ``--avoidance``); ``factory(sim, params)``
    gets a validated instance of ``params`` (default: ``factory.Params``)."""
    AVOIDANCE_LAYERS[name] = AvoidanceEntry(factory, description, _model(factory, params, name))


def load() -> None:
    """Import every planner module once so that they register."""
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
