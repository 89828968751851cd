"""The build order: a slot waits for the lower slots whose column a box placed in it would block."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.tasks.build_order import Reach, build_order, prerequisites
from pybullet_swarm.tasks.layouts import expand_boxes

QUAD150 = [0.15, 0.15, 0.02]  # m, collision box of the reference airframe
REACH = Reach.of(0.1, QUAD150, 0.005)
DEPOT = {"shape": "grid", "origin": [0.4, 0.2], "size": [4, 4], "pitch": 0.2}


def _slots(spec):
    return np.asarray(expand_boxes(spec, 0.1, "structure"))


def _index(slots, p):
    return int(np.flatnonzero(np.all(np.isclose(slots, p), axis=1))[0])


def test_thesis_wall_waits_only_for_its_own_column():
    slots = np.asarray(load_scenario("construction").task.structure)
    pre = prerequisites(slots, REACH)
    for t, ps in enumerate(pre):
        below = np.flatnonzero(np.isclose(slots[:, 1], slots[t, 1]) & (slots[:, 2] < slots[t, 2] - 1e-9))
        assert sorted(ps.tolist()) == sorted(below.tolist())  # columns 20 cm apart never block each other


def test_solid_wall_waits_for_neighbours_the_airframe_would_strike():
    slots = _slots({"shape": "wall", "origin": [2.0, 0.5], "length": 5, "height": 2})
    pre = prerequisites(slots, REACH)
    top_middle = _index(slots, [2.2, 0.5, 0.15])
    # the airframe (15 cm + margin) over a slot reaches the neighbouring columns at 10 cm, not those at 20 cm
    assert {tuple(slots[s]) for s in pre[top_middle]} == {(2.1, 0.5, 0.05), (2.2, 0.5, 0.05), (2.3, 0.5, 0.05)}
    assert all(len(pre[s]) == 0 for s in range(5))  # the bottom layer first, in any order


def test_overhang_waits_for_the_slot_it_covers():
    # a box bridging two columns 20 cm apart covers part of neither column's top, but its own column
    slots = np.array([[2.0, 0.5, 0.05], [2.1, 0.5, 0.05], [2.05, 0.5, 0.15], [2.3, 0.5, 0.05]])
    pre = prerequisites(slots, REACH)
    assert set(pre[2].tolist()) == {0, 1}  # the slots under it and beside it
    assert len(pre[3]) == 0


def test_order_honours_every_prerequisite_and_a_cycle_has_none():
    slots = _slots({"shape": "pyramid", "origin": [2.0, 0.3], "base": 4})
    pre = prerequisites(slots, REACH)
    order = build_order(pre)
    assert order is not None and sorted(order) == list(range(len(slots)))
    rank = {s: k for k, s in enumerate(order)}
    assert all(rank[int(s)] < rank[t] for t, ps in enumerate(pre) for s in ps)
    assert build_order([np.array([1]), np.array([0])]) is None


def test_runtime_opens_slots_in_the_derived_order(make_sim):
    structure = {"shape": "wall", "origin": [2.0, 0.5], "length": 3, "height": 2}
    sim = make_sim(load_scenario("construction", {"task.structure": structure, "task.boxes": DEPOT}))
    c = sim.task
    top = _index(c.slots, [2.1, 0.5, 0.15])
    assert np.array_equal(c.slot_open, np.isclose(c.slots[:, 2], 0.05))
    c.slot_box[:] = -1
    c.slot_box[_index(c.slots, [2.1, 0.5, 0.05])] = 0  # the slot under it: supported, but the neighbours are empty
    assert not c.slot_open[top]
    c.slot_box[_index(c.slots, [2.0, 0.5, 0.05])] = 1
    c.slot_box[_index(c.slots, [2.2, 0.5, 0.05])] = 2
    assert c.slot_open[top]
    assert c.slot_open[_index(c.slots, [2.0, 0.5, 0.15])]


@pytest.mark.parametrize(
    ("override", "field", "text"),
    [
        ({"task.structure": [[2.94, 0.5, 0.05]]}, "task.structure[0]", "too near the arena's edge"),
        ({"task.boxes": [[0.4, 0.06, 0.05]], "task.structure": [[2.7, 0.5, 0.05]]}, "task.boxes[0]", "edge"),
        (
            {
                "task.structure": [[2.7, 0.5, 0.05]],
                "arena.obstacles": [{"shape": "box", "size": [0.1, 0.1, 0.3], "position": [2.82, 0.5]}],
            },
            "task.structure[0]",
            "arena.obstacles[0]",
        ),
        (
            {"task.structure": {"shape": "tower", "origin": [2.7, 0.5], "height": 5}, "arena.height": 0.6},
            "arena.height",
            "above the ceiling",
        ),
    ],
)
def test_slots_no_agent_can_reach_are_refused(override, field, text):
    over = {"task.boxes": DEPOT, **override}
    with pytest.raises(ConfigError) as exc:
        load_scenario("construction", over)
    assert exc.value.field == field
    assert text in str(exc.value)


def test_a_low_obstacle_beside_a_slot_is_no_obstacle():
    ob = {"shape": "box", "size": [0.1, 0.1, 0.1], "position": [2.82, 0.5]}  # lower than the slot's top
    s = load_scenario("construction", {"task.structure": [[2.7, 0.5, 0.05]], "arena.obstacles": [ob]})
    assert len(s.task.structure) == 1
