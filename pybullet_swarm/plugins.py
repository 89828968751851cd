"""Plug-ins from other packages: entry points, where a plug-in comes from, and protocol checks.

A package outside pybullet_swarm makes a planner, an avoidance layer or a task available by
naming a class in one of the entry-point groups below (``pyproject.toml``)::

    [project.entry-points."pybullet_swarm.planners"]
    nearest_slot = "plugin_planner.planner:NearestSlot"

The registries (``planning.registry``, ``tasks``) read the groups once, the first time they are
asked, and check every class against its protocol before registering it: a plug-in that does not
satisfy it is refused with one line naming its distribution and what is missing, recorded in the
registry's refusals (``pybullet-swarm list`` prints them) and never registered.
"""

from __future__ import annotations

import dataclasses
import inspect
from importlib import metadata
from typing import Any

from typing_extensions import get_protocol_members

from pybullet_swarm.errors import ConfigError

#: entry-point group of planner classes
PLANNERS_GROUP = "pybullet_swarm.planners"
#: entry-point group of avoidance layer classes
AVOIDANCE_GROUP = "pybullet_swarm.avoidance"
#: entry-point group of task runtime classes
TASKS_GROUP = "pybullet_swarm.tasks"

#: the origin of what pybullet_swarm registers itself
BUILTIN = "pybullet_swarm"


class PluginRefused(ConfigError):
    """A plug-in that cannot be registered (it does not import, or does not satisfy its protocol)."""


@dataclasses.dataclass(frozen=True)
class Origin:
    """Where a registered plug-in comes from.

    Attributes:
        distribution: the installed distribution that declares the entry point ("pybullet_swarm" for
            the built-in ones).
        version: its version ("" for the built-in ones).
        target: the entry point's object reference, ``module:Class`` ("" for the built-in ones).
    """

    distribution: str = BUILTIN
    version: str = ""
    target: str = ""

    @property
    def builtin(self) -> bool:
        """True for what pybullet_swarm registers itself."""
        return self.distribution == BUILTIN and not self.target

    def __str__(self) -> str:
        if self.builtin:
            return BUILTIN
        version = f" {self.version}" if self.version else ""
        return f"{self.distribution}{version} ({self.target})"


BUILTIN_ORIGIN = Origin()


def entry_points(group: str) -> list[tuple[str, metadata.EntryPoint, Origin]]:
    """The entry points of ``group`` as (name, entry point, origin), sorted by name."""
    out = []
    for ep in metadata.entry_points(group=group):
        dist = ep.dist
        origin = Origin(
            distribution=dist.name if dist is not None else ep.module.partition(".")[0],
            version=dist.version if dist is not None else "",
            target=ep.value,
        )
        out.append((ep.name, ep, origin))
    return sorted(out, key=lambda item: (item[0], item[2].distribution))


def refusal(kind: str, name: str, origin: Origin, why: str) -> PluginRefused:
    """The one-line refusal of the plug-in ``name`` of ``kind`` ("planner", ...) from ``origin``."""
    return PluginRefused(f"{kind} plug-in {name!r} from {origin} refused: {why}")


def load(kind: str, name: str, ep: metadata.EntryPoint, origin: Origin) -> Any:
    """The class an entry point names.

    Raises:
        PluginRefused: it does not import or is not a class.
    """
    try:
        obj = ep.load()
    except Exception as exc:  # whatever a third-party import raises, reported in one line
        raise refusal(kind, name, origin, f"cannot be imported: {type(exc).__name__}: {exc}") from None
    if not inspect.isclass(obj):
        raise refusal(kind, name, origin, f"must name a class, got {type(obj).__name__}")
    return obj


def methods(protocol: type) -> list[str]:
    """The methods a protocol requires (its data members, only annotated, left out), sorted."""
    return sorted(m for m in get_protocol_members(protocol) if m in protocol.__dict__)


def missing(cls: type, protocol: type, *, data: tuple[str, ...] = ()) -> list[str]:
    """What the class ``cls`` lacks of ``protocol``'s methods and of the class attributes ``data``."""
    absent = [m for m in methods(protocol) if not callable(getattr(cls, m, None))]
    return sorted({*absent, *(d for d in data if not hasattr(cls, d))})


def declares(cls: type, protocol: type) -> bool:
    """True when the class ``cls`` has every method of the capability ``protocol``."""
    return not missing(cls, protocol)
