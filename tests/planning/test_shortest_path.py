"""The shortest-path baseline's extension switches, on scripted world views: altitude staggering,
serving again a slot whose box came to rest off it, descents kept apart, the cruise lanes, plumb
descents, soft landings, swapped boxes and keeping out of each other's rotor wake."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.planning.base import TaskInfo, TaskView, WorldView
from pybullet_swarm.planning.views.construction import ConstructionLayout, ConstructionState
from pybullet_swarm.planning.shortest_path import Phase, ShortestPath, ShortestPathParams

GH = 0.065
DEPOT = np.array([[x, y, 0.05] for x in (0.4, 0.6) for y in (0.3, 0.5, 0.7)])
SLOTS = np.array([[2.7, 0.2, 0.05], [2.7, 0.4, 0.05], [2.7, 0.6, 0.05]])


def _planner(
    n: int, slots: np.ndarray = SLOTS, downwash: bool | None = None, avoidance: bool | None = None, **params
) -> ShortestPath:
    sp = ShortestPath(ShortestPathParams(**params))
    extra: dict[str, object] = {}
    if downwash is not None:
        extra["downwash"] = downwash
    if avoidance is not None:
        extra["avoidance"] = avoidance
    info = TaskInfo(
        arena_size=np.array([3.0, 1.0]),
        n_agents=n,
        agent_radius=0.106,
        v_max=np.full(3, 0.15),
        layout=ConstructionLayout(DEPOT.copy(), np.array(slots, dtype=float), box_size=0.1, grasp_height=GH),
        extra=extra,
    )
    sp.reset(n, np.random.default_rng(0), info)
    return sp


def _view(positions, *, slot_filled=None, carrying=None, n_slots: int = len(SLOTS)) -> WorldView:
    n = len(positions)
    filled = np.full(n_slots, -1) if slot_filled is None else np.asarray(slot_filled)
    carrying = np.full(n, -1) if carrying is None else np.asarray(carrying)
    boxes = ConstructionState(DEPOT.copy(), np.zeros(len(DEPOT), dtype=np.int64), SLOTS[:n_slots], filled, filled < 0)
    return WorldView(
        0.0, np.asarray(positions, dtype=float), np.zeros((n, 3)), carrying, TaskView(0.0, carrying, boxes)
    )


def test_altitude_step_staggers_the_cruise_altitudes_and_the_thesis_flies_one():
    starts = [[0.12, 0.1 + 0.2 * i, 0.011] for i in range(3)]
    for params, heights in ((dict(wake_lanes=False), [0.45, 0.65, 0.85]), (dict(preset="thesis"), [0.45, 0.45, 0.45])):
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
    sp = _planner(2, slots, spaced_descents=spaced, wake_lanes=False, wake_clear=False)
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


WAKE_DEPTH = 0.5  # m, the ORCA layer's wake column with downwash (avoidance_params.wake_depth null)
AIRFRAME = 0.02  # m, quad150's height


def test_wake_lanes_put_loaded_and_empty_agents_further_apart_than_a_wake_column():
    """Empty agents (climbing to their boxes) share one lane; a loaded agent flies the lower lane, more
    than a wake column and two airframes below it. Without the switch the altitudes are staggered by
    ``altitude_step`` (0.2 m: every pair within a wake column)."""
    starts = [[0.12, 0.1 + 0.2 * i, 0.011] for i in range(3)]
    for lanes in (True, False):
        sp = _planner(3, wake_lanes=lanes)
        empty = [c.vector[2] for c in sp.plan_all(_view(starts))]
        sp.phase[2], sp.box[2] = Phase.TO_SLOT, 0
        loaded = sp.plan_all(_view([*starts[:2], [1.5, 0.5, 0.3]], carrying=[-1, -1, 0]))[2].vector[2]
        if lanes:
            assert empty == pytest.approx([empty[0]] * 3)
            assert empty[0] - loaded > WAKE_DEPTH + 2 * AIRFRAME
        else:
            assert np.diff(empty) == pytest.approx([0.2, 0.2])


def test_the_wake_rules_act_only_where_the_run_models_downwash_and_lanes_only_with_avoidance():
    """Without downwash there are no wakes to keep out of, and without an avoidance layer agents sharing a lane
    would fly into each other: the staggered altitudes of the switch-off case."""
    starts = [[0.12, 0.1 + 0.2 * i, 0.011] for i in range(3)]
    for downwash, avoidance, lanes, clear in (
        (True, True, True, True),
        (None, None, True, True),
        (False, True, False, False),
        (True, False, False, True),
    ):
        sp = _planner(3, downwash=downwash, avoidance=avoidance)
        assert (sp.wake_lanes, sp.wake_clear) == (lanes, clear)
        empty = [c.vector[2] for c in sp.plan_all(_view(starts))]
        assert (np.diff(empty) == pytest.approx([0.2, 0.2])) is not lanes


@pytest.mark.parametrize("plumb", [True, False])
def test_plumb_legs_brings_a_descent_pushed_aside_back_over_its_column(plumb):
    sp = _planner(1, plumb_legs=plumb, soft_landing=False)
    sp.home = np.zeros((1, 3))
    sp.phase[0], sp.box[0], sp.slot[0] = Phase.DESCEND_BOX, 1, 0
    box = DEPOT[1]
    cmd = sp.plan_all(_view([[box[0] + 0.1, box[1], 0.3]]))[0]
    assert cmd.vector[:2] == pytest.approx(box[:2])
    if plumb:  # back up to the top of the column, not on down beside it
        assert cmd.vector[2] == pytest.approx(sp._alt(0))
    else:
        assert cmd.vector[2] == pytest.approx(box[2] + GH)


@pytest.mark.parametrize("soft", [True, False])
@pytest.mark.parametrize("to_slot", [True, False])
def test_soft_landing_creeps_down_the_last_centimetres(soft, to_slot):
    """A descent to a slot (carrying its box) or to a box, at rest just above the point SETTLE_HEIGHT (4 cm) up."""
    sp = _planner(1, soft_landing=soft)
    sp.home = np.zeros((1, 3))
    if to_slot:
        sp.phase[0], sp.box[0], sp.slot[0] = Phase.DESCEND_SLOT, 0, 0
        point = SLOTS[0] + [0.0, 0.0, sp.clearances[0] + GH]  # agent over the drop point, box hanging GH below
    else:
        sp.phase[0], sp.box[0], sp.slot[0] = Phase.DESCEND_BOX, 1, 0
        point = DEPOT[1] + [0.0, 0.0, GH]
    p = point + [0.0, 0.0, 0.045]  # at rest 5 mm above the point SETTLE_HEIGHT (4 cm) up
    view = _view([p], carrying=[0] if to_slot else None)
    if to_slot:
        view.task.state.objects[0] = p - [0.0, 0.0, GH]
    z = sp.plan_all(view)[0].vector[2]
    if soft:  # at rest near the point SETTLE_HEIGHT up: its target creeps down from there, a few mm below it
        assert 0.0 < p[2] - z <= 0.01
    else:
        assert z == pytest.approx(point[2])


def test_soft_landing_waits_for_a_lagging_airframe_and_backs_up_past_the_point():
    """The creep lowers its target only while the airframe is within CREEP_LEAD of it, and raises it while the
    box hangs more than CREEP_STEP under its drop point: run ahead of the airframe, the creep left a box 1.1 cm
    under its point, out of the release tolerance, for good (suite solid_wall, seed 4)."""
    from pybullet_swarm.planning.shortest_path import CREEP_LEAD, CREEP_STEP

    sp = _planner(1)
    sp.home = np.zeros((1, 3))
    sp.phase[0], sp.box[0], sp.slot[0] = Phase.DESCEND_SLOT, 0, 0
    drop = SLOTS[0] + [0.0, 0.0, sp.clearances[0] + sp.release_tol]  # where the box is let go
    top = drop + [0.0, 0.0, GH]  # the agent there
    sp.creep[0] = top[2] + 0.02  # creeping, 2 cm to go

    def target(z: float) -> float:
        p = np.array([top[0], top[1], z])
        view = _view([p], carrying=[0])
        view.task.state.objects[0] = p - [0.0, 0.0, GH]
        return float(sp.plan_all(view)[0].vector[2])

    start = float(sp.creep[0])
    assert target(start + CREEP_LEAD + 0.002) == pytest.approx(start)  # lagging: the creep waits
    assert target(start + 0.001) == pytest.approx(start - CREEP_STEP)  # caught up: on down
    sp.creep[0] = top[2] - 0.011
    assert target(top[2] - 0.011) == pytest.approx(top[2] - 0.011 + CREEP_STEP)  # 1.1 cm under: back up


@pytest.mark.parametrize("recentre", [True, False])
def test_recentre_box_moves_a_settled_carrier_over_by_its_boxs_error(recentre):
    """The box hangs 7 mm off its drop point (the offset was measured in flight, tilted): once the carrier has
    arrived and the box is still, its target moves by SERVO_GAIN of the error a tick, towards a release."""
    from pybullet_swarm.planning.shortest_path import SERVO_GAIN

    sp = _planner(1, recentre_box=recentre)
    sp.home = np.zeros((1, 3))
    sp.phase[0], sp.box[0], sp.slot[0] = Phase.DESCEND_SLOT, 0, 0
    drop = SLOTS[0] + [0.0, 0.0, sp.clearances[0] + sp.release_tol]
    sp.offset[0] = [-0.007, 0.0, -GH]  # as measured: the box 7 mm behind the airframe
    p = drop - sp.offset[0]  # the agent over its target
    sp.creep[0] = p[2]
    view = _view([p], carrying=[0])
    view.task.state.objects[0] = p + [0.0, 0.0, -GH]  # in fact straight under it: 7 mm off the drop point in x
    xs = [float(sp.plan_all(view)[0].vector[0]) for _ in range(2)]  # the first tick sees the box still
    if recentre:
        assert xs[1] == pytest.approx(p[0] - SERVO_GAIN * 0.007)
    else:
        assert xs == pytest.approx([p[0], p[0]])


@pytest.mark.parametrize("swap", [True, False])
def test_swap_boxes_exchanges_the_boxes_of_two_agents_on_one_line(swap):
    """Agent 0 next to the box at y 0.5 wants it, agent 1 behind it wants the one at y 0.7, beyond agent 0's
    column: in one lane they held each other for ever; swapped, agent 0 flies on and agent 1 follows."""
    sp = _planner(2, swap_boxes=swap)
    sp.home = np.zeros((2, 3))
    sp.phase[:] = Phase.TO_BOX
    sp.box[:], sp.slot[:] = [1, 2], [0, 1]  # boxes at y 0.5 and 0.7
    sp.plan_all(_view([[0.4, 0.54, 1.35], [0.4, 0.36, 1.35]]))
    assert list(sp.box) == ([2, 1] if swap else [1, 2])


@pytest.mark.parametrize("clear", [True, False])
def test_wake_clear_holds_short_of_a_descent_below_and_goes_round_a_waiting_agent(clear):
    """Agent 0 (empty lane) flies west over the depot; agent 1 descends to a box on its way: agent 0 holds
    where it is, farther than ``WAKE_CLEARANCE``. With agent 1 waiting level in the lower lane instead, agent 0
    flies by a point beside it, never within ``WAKE_CLEARANCE`` of its column."""
    from pybullet_swarm.planning.shortest_path import WAKE_CLEARANCE

    sp = _planner(2, wake_clear=clear, swap_boxes=False)
    sp.home = np.zeros((2, 3))
    high = sp._alt(0)
    sp.phase[:] = [Phase.TO_BOX, Phase.DESCEND_BOX]
    sp.box[:], sp.slot[:] = [0, 4], [0, 1]  # agent 0 to (0.4, 0.3), agent 1 to (0.6, 0.5)
    p0 = np.array([1.2, 0.3, high])
    cmd = sp.plan_all(_view([p0, [0.6, 0.3, 0.6]]))[0]  # agent 1 pushed over to y 0.3: on agent 0's line
    if clear:
        assert cmd.vector == pytest.approx(p0)
    else:
        assert cmd.vector[:2] == pytest.approx(DEPOT[0, :2])
    sp.phase[1], sp.box[1] = Phase.TO_SLOT, 4
    low = np.array([0.8, 0.3, sp._alt(1)])
    cmd = sp.plan_all(_view([p0, low], carrying=[-1, 4]))[0]
    if not clear:
        assert cmd.vector[:2] == pytest.approx(DEPOT[0, :2])
        return
    p = p0.copy()  # fly agent 0 along its commands, 2 cm a tick: it passes, never over agent 1's column
    gaps = []
    for _ in range(100):
        target = sp.plan_all(_view([p, low], carrying=[-1, 4]))[0].vector
        step = target[:2] - p[:2]
        p[:2] += step * min(1.0, 0.02 / max(float(np.linalg.norm(step)), 1e-9))
        gaps.append(float(np.linalg.norm(p[:2] - low[:2])))
        assert np.all(p[:2] >= 0.0) and p[1] <= 1.0  # within the arena
    assert min(gaps) >= WAKE_CLEARANCE
    assert np.linalg.norm(p[:2] - DEPOT[0, :2]) < 0.02


@pytest.mark.parametrize("clear", [True, False])
def test_wake_clear_holds_a_carrier_short_of_its_column_while_an_agent_climbs_above_it(clear):
    """Agent 1 climbs from slot 1 after its release; agent 0, carrying a box to the slot above it, holds in its
    lane instead of flying in under agent 1's wake."""
    sp = _planner(2, wake_clear=clear)
    sp.home = np.zeros((2, 3))
    sp.phase[:] = [Phase.TO_SLOT, Phase.CLIMB]
    sp.box[:], sp.slot[:] = [0, 1], [0, 1]
    sp.offset[0] = [0.0, 0.0, -GH]
    p0 = np.array([2.2, 0.2, sp._alt(0)])
    view = _view([p0, [2.7, 0.2, 0.9]], carrying=[0, -1], slot_filled=[-1, 1, -1])
    cmd = sp.plan_all(view)[0]
    if clear:
        assert cmd.vector == pytest.approx(p0)
    else:
        assert cmd.vector[:2] == pytest.approx(SLOTS[0, :2])


@pytest.mark.parametrize("round_parked", [True, False])
def test_round_parked_takes_a_carrier_round_one_waiting_on_its_way(round_parked):
    """Agent 1 waits (at rest) in the loaded agents' lane on agent 0's straight way to its slot's column:
    agent 0 flies by a point beside it, never within ``PARKED_CLEARANCE`` of it."""
    from pybullet_swarm.planning.shortest_path import PARKED_CLEARANCE

    sp = _planner(2, round_parked=round_parked)
    sp.home = np.zeros((2, 3))
    sp.phase[:] = [Phase.TO_SLOT, Phase.TO_SLOT]
    sp.box[:], sp.slot[:] = [0, 1], [1, 2]
    sp.offset[:] = [0.0, 0.0, -GH]
    lane = sp._alt(0)
    parked = np.array([2.3, 0.42, lane])
    p = np.array([1.4, 0.4, lane])
    filled = [-1, -1, 1]  # slot 2 taken: agent 1 waits for nothing here, at rest
    if not round_parked:
        cmd = sp.plan_all(_view([p, parked], carrying=[0, 1], slot_filled=filled))[0]
        assert cmd.vector[:2] == pytest.approx(SLOTS[1, :2])
        return
    gaps = []
    for _ in range(120):
        target = sp.plan_all(_view([p, parked], carrying=[0, 1], slot_filled=filled))[0].vector
        step = target[:2] - p[:2]
        p[:2] += step * min(1.0, 0.02 / max(float(np.linalg.norm(step)), 1e-9))
        gaps.append(float(np.linalg.norm(p[:2] - parked[:2])))
    assert min(gaps) >= PARKED_CLEARANCE - 0.02
    assert np.linalg.norm(p[:2] - SLOTS[1, :2]) < 0.03


def test_wake_clear_waits_farthest_off_the_columns_when_no_point_is_clear_of_them(monkeypatch: pytest.MonkeyPatch):
    """A waiting point out along the way from a column must lie ``LEG_SPACING`` off every column of boxes and
    slots; in a dense depot no point tried does, and the agent waits at the one farthest off them, not at the
    first (a column's width from another box's column, where it blocked that box's agent for good)."""
    from pybullet_swarm.planning import shortest_path as sp_module

    xs = np.round(np.arange(0.15, 2.5, 0.25), 3)  # a depot over the arena, columns 25 cm apart
    dense = np.array([[x, y, 0.05] for x in xs for y in (0.15, 0.4, 0.65, 0.9)])
    sp = _planner(1, wake_clear=True)
    sp.home = np.zeros((1, 3))
    boxes = ConstructionState(
        dense, np.zeros(len(dense), dtype=np.int64), SLOTS, np.full(len(SLOTS), -1), np.ones(len(SLOTS), dtype=bool)
    )
    view = WorldView(
        0.0,
        np.array([[1.0, 0.9, sp._alt(0)]]),  # at its cruise altitude: the command is the waiting point
        np.zeros((1, 3)),
        np.full(1, -1),
        TaskView(0.0, np.full(1, -1), boxes),
    )
    columns = sp._columns(0, view)
    above = np.array([0.4, 0.4, sp._alt(0)])

    def off(q: np.ndarray) -> float:
        return float(np.min(np.max(np.abs(columns - q), axis=1)))

    chosen = sp._wait_aside(0, view, above).vector[:2]
    monkeypatch.setattr(sp_module, "WAIT_TRIES", 1)  # only the first point out
    first = sp._wait_aside(0, view, above).vector[:2]
    assert off(chosen) < sp_module.LEG_SPACING  # none of the points tried is clear of every column
    assert off(chosen) > off(first) + 0.005  # the farthest off them, not the first


@pytest.mark.parametrize("away", [True, False])
def test_wait_away_keeps_waiting_carriers_off_the_way_from_the_depot(away: bool):
    """Waiting for a tower's column at the far end of the arena, carriers waited on the side facing the
    arena's centre: between the depot and the tower, in the loaded agents' lane, where the carrier whose turn
    it was came through (the suite's tower5 stalled). With ``wait_away`` an agent whose point on that arc lies
    nearer the way from the depot (or the columns) than the point on the arc facing away waits there."""
    from pybullet_swarm.planning import shortest_path as sp_module

    tower = np.array([[2.6, 0.5, 0.05 + 0.1 * k] for k in range(5)])
    sp = _planner(5, slots=tower, wait_away=away)
    above = np.array([2.6, 0.5, sp._alt(0)])
    view = _view(np.array([[1.0, 0.1 + 0.2 * i, above[2]] for i in range(5)]), n_slots=len(tower))  # at altitude
    depot = DEPOT[:, :2].mean(axis=0)
    gaps = []
    for i in range(5):
        xy = sp._wait_aside(i, view, above, sp.depot_xy).vector[:2]
        assert np.linalg.norm(xy - above[:2]) > 0.2  # aside from the column either way
        gaps.append(sp_module._to_segment(xy, depot, above[:2]))
    if away:
        assert min(gaps) > 0.25  # every one off the carriers' way (a wall clips one to 0.29 m)
    else:
        assert min(gaps) < 0.1  # one right in it


@pytest.mark.parametrize("round_parked", [True, False])
def test_round_parked_takes_a_carrier_round_the_top_of_a_descent_at_its_altitude(round_parked):
    """Agent 1 has just started its descent to slot 0 (at the top of the leg, in the loaded agents' lane) on
    agent 0's straight way to its slot's column: agent 0 goes round it, not through it (flying through, a
    carrier pushed one starting its descent 1 m along ahead of it on the suite's ring, and then stood
    between it and its column)."""
    from pybullet_swarm.planning.shortest_path import PARKED_CLEARANCE

    sp = _planner(2, round_parked=round_parked)
    sp.home = np.zeros((2, 3))
    sp.phase[:] = [Phase.TO_SLOT, Phase.DESCEND_SLOT]
    sp.box[:], sp.slot[:] = [0, 1], [2, 1]
    sp.offset[:] = [0.0, 0.0, -GH]
    lane = sp._alt(0)
    top = np.array([2.4, 0.3, lane])  # agent 1 at the top of its leg, on agent 0's way
    p = np.array([1.4, 0.27, lane])
    sp.columns[1] = top[:2]
    gaps = []
    for _ in range(120):
        view = _view([p, top], carrying=[0, 1])
        target = sp._cruise(0, view, np.array([*SLOTS[2, :2], lane])).vector
        step = target[:2] - p[:2]
        p[:2] += step * min(1.0, 0.02 / max(float(np.linalg.norm(step)), 1e-9))
        gaps.append(float(np.linalg.norm(p[:2] - top[:2])))
    assert (min(gaps) >= PARKED_CLEARANCE - 0.02) is round_parked


def test_wait_away_never_waits_where_the_arena_edge_pulls_the_point_onto_the_column():
    """A slot 15 cm from the arena's edge: the arc facing away from the depot is clipped to the edge, 4 cm off
    the column, where a waiting carrier stands in the way of the one it waits for (random_8 of the suite, seed
    0: held 14 cm from its slot, the slot's carrier never reached it). Such a point comes last."""
    from pybullet_swarm.planning import shortest_path as sp_module

    tower = np.array([[2.85, 0.5, 0.05 + 0.1 * k] for k in range(3)])
    sp = _planner(5, slots=tower, wait_away=True)
    above = np.array([2.85, 0.5, sp._alt(0)])
    view = _view(np.array([[1.0, 0.1 + 0.2 * i, above[2]] for i in range(5)]), n_slots=len(tower))
    for i in range(5):
        xy = sp._wait_aside(i, view, above, sp.depot_xy).vector[:2]
        assert np.max(np.abs(xy - above[:2])) >= sp_module.WAKE_CLEARANCE
    lane = (sp.depot_xy, above[:2])
    assert sp_module._wait_clearance(np.array([2.894, 0.5]), 0.044, lane) < 0.0


@pytest.mark.parametrize("park_clear", [True, False])
def test_park_clear_parks_off_free_boxes_and_agents_below(park_clear: bool):
    """With the starts beside the depot, two agents with nothing left to carry stood over free boxes on their
    way to their starts, held there by the agents that waited under those starts for those very boxes, which
    they held in turn: neither moved again (the suite's random_3, seed 2, shortest_path + orca). With
    ``park_clear`` an agent parks at its start only when that is clear of free boxes, slots and agents below
    it, and else at a point off them."""
    from pybullet_swarm.planning.shortest_path import WAKE_CLEARANCE

    sp = _planner(3, park_clear=park_clear)
    park = sp._alt(0)
    below = np.array([0.4, 0.8, park - 0.6])  # agent 2 waits in a lower lane
    sp.home = np.array([[*DEPOT[0, :2], 0.011], [below[0], below[1], 0.011], [1.5, 0.5, 0.011]])
    sp.phase[:] = [Phase.DONE, Phase.DONE, Phase.TO_BOX]
    view = _view([[1.0, 0.5, park], [1.0, 0.7, park], below])
    columns = np.vstack([DEPOT[:, :2], SLOTS[:, :2], below[:2]])
    for i in (0, 1):
        sp._step(i, view)  # the parking agent's step chooses its point
        target = sp._park_point(i, view)
        assert (sp.park is not None and np.allclose(sp.park[i], target)) is park_clear
        off = float(np.min(np.max(np.abs(columns - target), axis=1)))
        if park_clear:
            assert off >= WAKE_CLEARANCE
        else:
            assert np.allclose(target, sp.home[i, :2]) and off < WAKE_CLEARANCE
    sp.home[0, :2] = [2.0, 0.9]  # a clear start: parked there
    sp.park = None
    assert np.allclose(sp._park_point(0, view), [2.0, 0.9])


@pytest.mark.parametrize("held_pass", [True, False])
def test_held_pass_breaks_two_agents_holding_each_other_over_their_targets(held_pass):
    """Agent 0 carries its box to slot 0 in the lower lane; agent 1, empty, flies to a free box lying under agent
    0, in the upper lane over slot 0: each hovers over the other's target, and ``wake_clear`` held both for 150 s
    (suite double_wall, seed 1). With ``held_pass`` the agent held there does not hold the other up."""
    sp = _planner(2, held_pass=held_pass, swap_boxes=False)
    sp.home = np.zeros((2, 3))
    sp.phase[:] = [Phase.TO_SLOT, Phase.TO_BOX]
    sp.box[:], sp.slot[:] = [0, 1], [0, 1]
    sp.offset[0] = [0.0, 0.0, -GH]
    p0 = np.array([2.05, 0.25, sp._alt(0)])
    p1 = np.array([2.65, 0.25, sp._alt(1)])
    assert sp._alt(1) - sp._alt(0) > 0.5
    view = _view([p0, p1], carrying=[0, -1])
    view.task.state.objects[1] = [2.05, 0.25, 0.05]  # agent 1's box, under agent 0
    moved = []
    for _ in range(3):
        cmds = sp.plan_all(view)
        moved.append([bool(np.linalg.norm(c.vector[:2] - q[:2]) > 0.05) for c, q in zip(cmds, (p0, p1))])
    if held_pass:
        assert any(any(m) for m in moved)
    else:
        assert not any(any(m) for m in moved)  # both hold where they are


@pytest.mark.parametrize("clear", [True, False])
def test_wake_clear_sends_a_waiting_agent_beside_a_column_a_lower_one_must_come_under(clear):
    """Without avoidance (no lanes) agent 0 cruises higher, its slot (the tower's second) not yet open; agent 1,
    lower, carries the box of the first. With ``wake_clear`` agent 1 may not fly in under agent 0, so agent 0
    waits beside the column (on the tower of 5 the carrier of the third box waited 150 s under the one over
    the column); without it, the lower agent's way does not pass agent 0 and agent 0 waits over the column."""
    tower = np.array([[2.7, 0.4, 0.05], [2.7, 0.4, 0.15]])
    sp = _planner(2, slots=tower, downwash=True, avoidance=False, wake_clear=clear, wake_lanes=False)
    sp.hs[:] = [0.65, 0.45]
    sp.phase[:] = [Phase.TO_SLOT, Phase.TO_SLOT]
    sp.box[:], sp.slot[:] = [0, 1], [1, 0]
    assert sp._overflown(0, 1) is clear
