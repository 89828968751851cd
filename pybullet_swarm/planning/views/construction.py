"""The construction task's own types: what an agent sees of boxes and slots, and its observation."""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.base import Observation


def _empty3() -> NDArray[np.float64]:
    return np.zeros((0, 3))


def _empty_ids() -> NDArray[np.int64]:
    return np.zeros(0, dtype=np.int64)


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
