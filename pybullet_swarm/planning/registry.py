"""Planners, avoidance layers and their registration by name.

Planner modules register themselves with ``register_planner`` when imported; ``_load`` imports
the known modules once (a module that is not there yet is skipped).
"""
from __future__ import annotations

import importlib
from typing import Any, Callable

#: name -> (factory(**params), description, task kinds it solves)
PLANNERS: dict[str, tuple[Callable[..., Any], str, tuple[str, ...]]] = {}
#: name -> (factory(sim, **params), description)
AVOIDANCE_LAYERS: dict[str, tuple[Callable[..., Any] | None, str]] = {"none": (None, "no local avoidance (default)")}
#: task kind -> default planner
DEFAULT_PLANNER: dict[str, str] = {}

_MODULES = ("waypoints", "shortest_path", "stigmergy", "orca", "aco_tour", "reynolds", "laplacian", "braitenberg")
_loaded = False


def register_planner(name: str, factory: Callable[..., Any], description: str, tasks: tuple[str, ...],
                     *, default_for: tuple[str, ...] = ()) -> None:
    """Make a planner available by name (to ``--planner`` and ``pybullet-swarm list``)."""
    PLANNERS[name] = (factory, description, tasks)
    for kind in default_for:
        DEFAULT_PLANNER[kind] = name


def register_avoidance(name: str, factory: Callable[..., Any], description: str) -> None:
    """Make a local avoidance layer available by name (to ``--avoidance``)."""
    AVOIDANCE_LAYERS[name] = (factory, description)


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


def planners() -> dict[str, tuple[Callable[..., Any], str, tuple[str, ...]]]:
    """Every registered planner."""
    load()
    return PLANNERS


def avoidance_layers() -> dict[str, tuple[Callable[..., Any] | None, str]]:
    """Every registered avoidance layer."""
    load()
    return AVOIDANCE_LAYERS


def default_planner(kind: str) -> str | None:
    """The default planner of a task kind."""
    load()
    return DEFAULT_PLANNER.get(kind)
