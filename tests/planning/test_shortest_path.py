"""The shortest-path baseline's extension switches, on scripted world views: altitude staggering,
serving again a slot whose box came to rest off it, and descents kept apart."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.planning.base import TaskInfo, WorldView
from pybullet_swarm.planning.shortest_path import Phase, ShortestPath, ShortestPathParams

GH = 0.065
DEPOT = np.array([[x, y, 0.05] for x in (0.4, 0.6) for y in (0.3, 0.5, 0.7)])
SLOTS = np.array([[2.7, 0.2, 0.05], [2.7, 0.4, 0.05], [2.7, 0.6, 0.05]])


def _planner(n: int, slots: np.ndarray = SLOTS, **params) -> ShortestPath:
    sp = ShortestPath(ShortestPathParams(**params))
    info = TaskInfo(
        arena_size=np.array([3.0, 1.0]),
        n_agents=n,
        agent_radius=0.106,
        v_max=np.full(3, 0.15),
        depot=DEPOT.copy(),
        slots=np.array(slots, dtype=float),
        box_size=0.1,
        grasp_height=GH,
        extra={"search_height": 0.45, "attach_threshold": 0.02},
    )
    sp.reset(n, np.random.default_rng(0), info)
    return sp


def _view(positions, *, slot_filled=None, carrying=None, n_slots: int = len(SLOTS)) -> WorldView:
    n = len(positions)
    filled = np.full(n_slots, -1) if slot_filled is None else np.asarray(slot_filled)
    return WorldView(
        0.0,
        np.asarray(positions, dtype=float),
        np.zeros((n, 3)),
        np.full(n, -1) if carrying is None else np.asarray(carrying),
        DEPOT.copy(),
        np.zeros(len(DEPOT), dtype=np.int64),
        filled,
        filled < 0,
    )


def test_altitude_step_staggers_the_cruise_altitudes_and_the_thesis_flies_one():
    starts = [[0.12, 0.1 + 0.2 * i, 0.011] for i in range(3)]
    for params, heights in ((dict(), [0.45, 0.65, 0.85]), (dict(preset="thesis"), [0.45, 0.45, 0.45])):
        sp = _planner(3, **params)
        cmds = sp.plan_all(_view(starts))
        assert [c.vector[2] for c in cmds] == pytest.approx(heights)  # each climbs first, to its altitude


def test_retry_slots_serves_again_a_slot_left_behind_empty():
    """Slot 0 was served (next_slot moved past it) but its box came to rest off it: with retry_slots
    the next idle agent serves it again, without it the agent takes the next slot in order."""
    for retry, slot in ((True, 0), (False, 1)):
        sp = _planner(1, retry_slots=retry)
        sp.next_slot = 1
        sp.plan_all(_view([[0.12, 0.5, 0.011]]))
        assert sp.phase[0] == Phase.TO_BOX and sp.slot[0] == sp.order[slot]


@pytest.mark.parametrize("pitch, spaced, held", [(0.1, True, True), (0.1, False, False), (0.2, True, False)])
def test_spaced_descents_holds_a_descent_beside_another_at_a_box_pitch_not_at_the_thesis_pitch(pitch, spaced, held):
    """Agent 0 sets a box down on slot 0; agent 1, over the next slot at its cruise altitude with its box,
    waits beside it while that column is within an airframe's width (slots side by side, 10 cm), and starts
    its descent without ``spaced_descents`` or at the thesis's 20 cm pitch."""
    slots = np.array([[2.7, 0.4, 0.05], [2.7, 0.4 + pitch, 0.05]])
    sp = _planner(2, slots, spaced_descents=spaced)
    sp.home = np.zeros((2, 3))
    sp.phase[:] = [Phase.DESCEND_SLOT, Phase.TO_SLOT]
    sp.box[:], sp.slot[:] = [0, 1], [0, 1]
    sp.columns[0] = slots[0, :2]
    above = [*slots[1, :2], sp.hs[1]]
    view = _view([slots[0] + [0.0, 0.0, 0.2], above], carrying=[0, 1], n_slots=2)
    cmds = sp.plan_all(view)
    assert sp.phase[1] == (Phase.TO_SLOT if held else Phase.DESCEND_SLOT)
    if held:  # waits aside from its column, at its cruise altitude
        aside = cmds[1].vector
        assert np.hypot(*(aside[:2] - slots[1, :2])) > 2.0 * sp.info.agent_radius and aside[2] == pytest.approx(
            sp.hs[1]
        )
