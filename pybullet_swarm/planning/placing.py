"""How high above its slot a construction planner lets a box go.

A box lowered into a gap of its own width (boxes side by side, pitch = box size) is held against the
boxes beside it before it reaches its slot: in a rigid-body simulation, as with real bricks without
play, its bottom edges catch on their top edges, and the carrier, pressing on, tips over. Under guided
placement (``task.placement: guided``) the guide takes a box let go up to ``task.guide_height`` above
its slot and slides it in past its neighbours; ``release_over_neighbours`` lets the box go above their
tops where the guide reaches that high.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.views.construction import ConstructionInfo

OVER_NEIGHBOURS_CLEARANCE = 0.01
"""m: with ``release_over_neighbours`` a box is let go this far above the tops of the boxes beside its slot."""
GUIDE_MARGIN = 0.005
"""m: the release point stays this far inside the guide's reach (the agent lets go within ``release_tol``)."""
LEVEL_TOL = 1e-6
"""m: slots whose centres differ by less than this in height are on one level."""


def side_by_side(slots: NDArray[np.float64], box_size: float) -> NDArray[np.bool_]:
    """(S,) True for the slots (S, 3) m with another slot on their level touching them (face, edge or corner)."""
    slots = np.asarray(slots, dtype=float).reshape(-1, 3)
    d = np.max(np.abs(slots[:, None, :2] - slots[None, :, :2]), axis=2)  # (S, S) m, per-axis distance
    level = np.abs(slots[:, None, 2] - slots[None, :, 2]) < LEVEL_TOL
    touching = level & (d <= box_size * (1.0 + 1e-6)) & (d > 1e-9)
    return np.any(touching, axis=1)


def release_clearances(info: ConstructionInfo, base: float, *, over_neighbours: bool) -> NDArray[np.float64]:
    """(S,) m, how far above each slot's centre the box's centre is when it is let go: ``base``; with
    ``over_neighbours``, for a slot with boxes beside it, ``OVER_NEIGHBOURS_CLEARANCE`` above their tops
    when the task's guide (``info.layout.guide_height``, m; 0: no guide) captures a box
    from there."""
    slots = np.asarray(info.layout.slots, dtype=float).reshape(-1, 3)
    out = np.full(len(slots), float(base))
    if not over_neighbours or len(slots) == 0:
        return out
    over = info.layout.box_size + OVER_NEIGHBOURS_CLEARANCE
    if float(info.layout.guide_height) < over + GUIDE_MARGIN:
        return out
    out[side_by_side(slots, info.layout.box_size)] = max(over, float(base))
    return out
