"""The construction task's own types: its static layout, its public state, what an agent sees."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.base import Observation, Payload, TaskInfo, TaskView, WorldView


def _empty3() -> NDArray[np.float64]:
    return np.zeros((0, 3))


def _empty_ids() -> NDArray[np.int64]:
    return np.zeros(0, dtype=np.int64)


@dataclasses.dataclass(frozen=True)
class ConstructionLayout:
    """What every agent of a construction run is told before it starts (``TaskInfo.layout``).

    The thesis's agents are told where the boxes start and where the structure goes; what the boxes
    are doing now they only learn by seeing them (``Observation.seen``).

    Attributes:
        depot: (B, 3) m, box start positions.
        slots: (S, 3) m, goal slot centres.
        box_size: m, edge of a box.
        grasp_height: m, agent centre above a box centre when holding it.
        search_height: m, cruise altitude of the planners.
        attach_threshold: m, an agent grasps a box whose grasp point is this close.
        view_radius: m, boxes and slots within it (in ``view_norm``) are seen.
        view_norm: "chebyshev" (largest per-axis difference, as the thesis measures it) or "euclidean".
        guide_height: m, how far above its slot a released box is still captured by the guide
            (0: free placement).
        box_mass: kg, mass of a box (the payload a carrier lifts).
    """

    depot: NDArray[np.float64]
    slots: NDArray[np.float64]
    box_size: float
    grasp_height: float
    search_height: float = 0.45
    attach_threshold: float = 0.02
    view_radius: float = 0.3
    view_norm: str = "chebyshev"
    guide_height: float = 0.0
    box_mass: float = 0.0

    @property
    def payload(self) -> Payload:
        """A box, as it hangs under its carrier (``planning.base.CarriesPayload``)."""
        return Payload(float(self.box_size), float(self.grasp_height), float(self.box_mass))


#: ``ConstructionState.object_state`` of a box that lies free, hangs under its carrier, sits in its slot
FREE, CARRIED, PLACED = 0, 1, 2


@dataclasses.dataclass(frozen=True)
class ConstructionState:
    """The boxes and slots now (``TaskView.state`` of a construction run, world frame).

    Attributes:
        objects: (B, 3) m, every box now.
        object_state: (B,) ``FREE``, ``CARRIED`` or ``PLACED``.
        slots: (S, 3) m, goal slot centres.
        slot_filled: (S,) box in each slot, or -1.
        slot_open: (S,) True when a slot is empty and can be filled now (supported).
    """

    objects: NDArray[np.float64] = dataclasses.field(default_factory=_empty3)
    object_state: NDArray[np.int64] = dataclasses.field(default_factory=_empty_ids)
    slots: NDArray[np.float64] = dataclasses.field(default_factory=_empty3)
    slot_filled: NDArray[np.int64] = dataclasses.field(default_factory=_empty_ids)
    slot_open: NDArray[np.bool_] = dataclasses.field(default_factory=lambda: np.zeros(0, dtype=bool))


@dataclasses.dataclass(frozen=True)
class ConstructionLocalView:
    """The boxes and slots one agent sees now (within its view), in the agent's own frame of reference
    (``Observation.seen`` of a construction run).

    Attributes:
        boxes: (b, 3) m, free boxes in view (not carried, not placed).
        box_ids: (b,) their ids.
        slots: (s, 3) m, open slots in view (empty and supported).
        slot_ids: (s,) their ids.
    """

    boxes: NDArray[np.float64] = dataclasses.field(default_factory=_empty3)
    box_ids: NDArray[np.int64] = dataclasses.field(default_factory=_empty_ids)
    slots: NDArray[np.float64] = dataclasses.field(default_factory=_empty3)
    slot_ids: NDArray[np.int64] = dataclasses.field(default_factory=_empty_ids)


#: an agent that sees no box and no slot
NOTHING_IN_VIEW = ConstructionLocalView()

#: what a construction planner's agent knows at a planner tick (``Observation.seen``: boxes and slots)
ConstructionObservation = Observation[ConstructionLocalView]

#: what every agent of a construction run knows before it starts (the layout: ``ConstructionLayout``)
ConstructionInfo = TaskInfo[ConstructionLayout]
#: what a construction task shows at a planner tick (``TaskView.state``: boxes and slots)
ConstructionView = TaskView[ConstructionState]
#: what a centralised construction planner sees
ConstructionWorldView = WorldView[ConstructionState]

#: the state of a task without boxes
NO_BOXES = ConstructionState()


def boxes_of(view: TaskView[Any]) -> ConstructionState:
    """The boxes and slots a view shows (``NO_BOXES`` when its task has none): for consumers that serve
    several task kinds (the learning environments, the GUI)."""
    return view.state if isinstance(view.state, ConstructionState) else NO_BOXES
