"""Optional abilities of planners, avoidance layers and shared media, as small protocols.

A plug-in declares an ability by having its methods; the registry checks every class against the
protocols when it registers and records what it found in the plug-in's entry
(``planning.registry.PlannerEntry``, ``AvoidanceEntry``), so that the simulation asks the entry, never
the object.

- ``ProvidesMedium``: a planner class that brings a medium every agent shares (a pheromone grid).
- ``ChecksTask``: a planner class that refuses, at load, a task it cannot fly (a formation-keeping
  planner on a route without a formation).
- ``ReportsActivity``: a decentralised planner that says what it is doing (its phase and target).
- ``ReportsActivities``: a centralised planner that says what each agent is doing.
- ``PublishesArtefacts``: a planner or a layer that publishes data for the run directory (a tour plan).
- ``Medium``: what a shared medium must do (advance, report metrics and files).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from pybullet_swarm.planning.base import TaskInfo


@runtime_checkable
class Medium(Protocol):
    """A medium shared by every agent's planner (e.g. a pheromone grid), given to ``Planner.plan``."""

    def step(self, dt: float) -> None:
        """Advance by ``dt`` s (evaporation, diffusion) after every planner tick."""

    def metrics(self) -> dict[str, Any]:
        """The medium's counters of the run (merged into metrics.json)."""

    def artefacts(self) -> dict[str, Any]:
        """Files for the run directory, as data by file name."""


@runtime_checkable
class ProvidesMedium(Protocol):
    """A planner class that brings a shared medium."""

    @classmethod
    def make_medium(cls, params: Any, info: TaskInfo) -> Medium:
        """The medium of a run, from the planner's validated parameters and the task's static layout."""


@runtime_checkable
class ChecksTask(Protocol):
    """A planner class that checks, when a scenario is loaded, that it can fly the task."""

    @classmethod
    def check_task(cls, task: Any) -> None:
        """Raise ``ConfigError`` (field path, no file) for a task model it cannot fly."""


@runtime_checkable
class ReportsActivity(Protocol):
    """A decentralised planner that says what its agent is doing."""

    def activity(self) -> str:
        """One short line: the agent's phase and target ('' when it has nothing to say)."""


@runtime_checkable
class ReportsActivities(Protocol):
    """A centralised planner that says what each agent is doing."""

    def activities(self) -> list[str]:
        """One short line per agent."""


@runtime_checkable
class PublishesArtefacts(Protocol):
    """A planner or avoidance layer that publishes data (files for the run directory, a tour plan)."""

    def artefacts(self) -> dict[str, Any]:
        """Data by name (``.json``: plain data, ``.npz``: arrays; ``tour_plan``: a ``TourPlan``)."""
