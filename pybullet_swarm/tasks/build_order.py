"""The order in which a structure can be built by agents that carry boxes hanging under them.

An agent places a box by hovering over its slot and descending straight down until the box
rests in it: at that moment the box fills the slot and the airframe hangs ``grasp_gap`` above the
box's top, reaching ``reach`` (its collision box's half extents and ``REACH_MARGIN``) from the
slot's centre horizontally. A filled slot ``t`` therefore makes slot ``s`` unreachable when ``t``
is higher than ``s`` and its box overlaps the column the descent sweeps: the box's own footprint
(a box over ``s``, an overhang) or the airframe's (a taller neighbour the airframe would strike).
So ``s`` comes before every such ``t``; with the slots that support ``t`` this is the partial
order of the build (in the spirit of compiled termite-inspired construction, where a structure is
turned into an order that guarantees completion). Every constraint points upwards (a slot only
waits for lower slots), so an order always exists for slots that can be reached at all; what no
order can build is a slot the airframe cannot hover over (the arena's edge, an obstacle, the
ceiling), refused when the scenario is loaded.

The model is geometric and static: the airframe flies level at yaw 0 (as the construction
planners command), the box hangs straight under it, and sway, tilt and the box's lateral
placement error beyond ``REACH_MARGIN`` are not modelled.
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

REACH_MARGIN = 0.01
"""m: added to the airframe's half extents (tracking and release error at the placement)."""
LEVEL_TOL = 1e-6
"""m: slots whose centres differ by less than this in height are on one level."""


@dataclasses.dataclass(frozen=True)
class Reach:
    """The column an agent sweeps when it sets a box down.

    Attributes:
        box_half: m, half the box's edge.
        airframe_half: (2,) m, half extents of the airframe's collision box in x and y, with ``REACH_MARGIN``.
        airframe_height: m, height of the airframe's collision box.
        grasp_gap: m, airframe bottom to box top while the box is held.
    """

    box_half: float
    airframe_half: NDArray[np.float64]
    airframe_height: float
    grasp_gap: float

    @staticmethod
    def of(box_size: float, collision_size: Sequence[float] | NDArray[np.float64], grasp_gap: float) -> Reach:
        """The reach of an airframe with collision box ``collision_size`` (3,) m carrying a ``box_size`` m cube."""
        c = np.asarray(collision_size, dtype=float)
        return Reach(0.5 * float(box_size), 0.5 * c[:2] + REACH_MARGIN, float(c[2]), float(grasp_gap))

    @property
    def half(self) -> NDArray[np.float64]:
        """(2,) m, half extents of the column swept (airframe or box, whichever is wider)."""
        return np.maximum(self.airframe_half, self.box_half)


def prerequisites(slots: NDArray[np.float64], reach: Reach) -> list[NDArray[np.int64]]:
    """For each slot (S, 3) m, the slots (indices) that must be filled before it.

    Slot ``s`` must come before ``t`` when ``t`` is higher than ``s`` and ``t``'s box overlaps the
    column swept over ``s`` (see the module's docstring); that includes the slots under ``t``.
    """
    slots = np.asarray(slots, dtype=float).reshape(-1, 3)
    reach_xy = reach.box_half + reach.half  # (2,) m: centre distances at which t's box enters s's column
    d = np.abs(slots[:, None, :2] - slots[None, :, :2])  # (t, s, 2) m
    near = np.all(d < reach_xy - 1e-9, axis=2)
    below = slots[None, :, 2] < slots[:, None, 2] - LEVEL_TOL  # s lower than t
    return [np.flatnonzero(row) for row in near & below]


def build_order(prereq: list[NDArray[np.int64]]) -> list[int] | None:
    """One order (slot indices) that honours ``prereq``, or None when the prerequisites are cyclic."""
    n = len(prereq)
    waiting = np.array([len(p) for p in prereq])
    after: list[list[int]] = [[] for _ in range(n)]
    for t, ps in enumerate(prereq):
        for s in ps:
            after[int(s)].append(t)
    ready = [t for t in range(n) if waiting[t] == 0]
    out: list[int] = []
    while ready:
        s = ready.pop(0)
        out.append(s)
        for t in after[s]:
            waiting[t] -= 1
            if waiting[t] == 0:
                ready.append(t)
    return out if len(out) == n else None
