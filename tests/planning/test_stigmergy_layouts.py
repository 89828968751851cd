"""Stigmergy derives its altitudes from any layout; what cannot work is refused when the scenario loads."""

from __future__ import annotations

import numpy as np
import pytest

import pybullet_swarm
from pybullet_swarm.cli.main import main
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.experiment.simulation import Simulation
from pybullet_swarm.planning.base import view_distance
from pybullet_swarm.planning.stigmergy import ALTITUDE_TOL
from pybullet_swarm.types import ExitStatus

TOWER = {
    "task.structure": {"shape": "tower", "origin": [2.7, 0.5], "height": 5},
    "task.boxes": {"shape": "grid", "origin": [0.4, 0.3], "size": [3, 3], "pitch": 0.2, "count": 5},
}
TWELVE = [[0.12 + 0.2 * (k // 5), 0.1 + 0.2 * (k % 5), 0.011] for k in range(12)]
DOUBLE_WALL = {  # without downwash, as measured (with it, contacts follow: an open re-tune)
    "sim.downwash": False,
    "agents.count": 12,
    "agents.start": TWELVE,
    "task.time_limit_s": 800.0,
    "task.boxes": {"shape": "grid", "origin": [0.8, 0.2], "size": [5, 4], "pitch": 0.2},
    "task.structure": [
        {"shape": "stepped_wall", "origin": [2.2, 0.2], "length": 4, "height": 4, "axis": "y", "pitch": 0.2},
        {"shape": "stepped_wall", "origin": [2.7, 0.2], "length": 4, "height": 4, "axis": "y", "pitch": 0.2},
    ],
}
SLAB3 = {  # three layers of 3 x 3 boxes side by side: the middle column is out of view from beside the slab
    "task.structure": {"shape": "slab", "origin": [2.4, 0.4], "size": [3, 3], "height": 3},
    "task.boxes": {"shape": "grid", "origin": [0.4, 0.1], "size": [5, 6], "pitch": 0.15, "count": 27},
}
SLAB2 = {**SLAB3, "task.structure": {**SLAB3["task.structure"], "height": 2}}


def _geometry(overrides, planner="stigmergy"):
    sim = Simulation(load_scenario("construction", overrides, planner=planner))
    try:
        return sim.agent_planners[0].geo, sim.info
    finally:
        sim.close()


@pytest.mark.parametrize("planner", ["stigmergy", "layered_stigmergy"])
@pytest.mark.parametrize("layout", [TOWER, DOUBLE_WALL], ids=["tower5", "double_wall12"])
def test_tall_structures_get_altitudes_that_see_every_slot_and_the_depot(layout, planner):
    geo, info = _geometry(layout, planner)
    assert geo.floor_altitude <= geo.look_altitude <= geo.cruise_altitude
    view = geo.view_range
    grasp = info.layout.slots[:, 2] + info.layout.grasp_height
    assert np.all(np.abs(grasp - geo.floor_altitude) <= view - ALTITUDE_TOL)  # every layer from beside it
    assert np.all(
        np.abs(info.layout.depot[:, 2] + info.layout.grasp_height - geo.look_altitude) <= view
    )  # the depot's boxes
    top = info.layout.slots[:, 2].max() + 0.5 * info.layout.box_size
    assert geo.cruise_altitude - info.layout.grasp_height - 0.5 * info.layout.box_size > top  # a carried box clears it
    assert len(geo.hidden) == 0


def test_thesis_layout_keeps_its_altitudes():
    geo, _ = _geometry({})
    assert (geo.floor_altitude, geo.look_altitude, geo.cruise_altitude) == pytest.approx(
        (0.245, 0.25357, 0.45), abs=1e-5
    )


def test_explicit_altitudes_that_do_not_rise_are_refused_when_the_scenario_loads(capsys):
    with pytest.raises(ConfigError) as exc:
        load_scenario("construction", {**TOWER, "planner.params.cruise_altitude": 0.3}, planner="stigmergy")
    assert exc.value.field == "planner.params.cruise_altitude"
    assert "altitudes must rise" in str(exc.value)
    assert main(["check", "construction", "--quiet", "--set", "planner.name=stigmergy", "--set",
                 "planner.params.cruise_altitude=0.2"]) == 2  # fmt: skip
    assert "planner.params.cruise_altitude" in capsys.readouterr().err


def test_slots_out_of_every_view_derive_the_view_radius_and_a_set_one_too_small_is_refused():
    derived = load_scenario("construction", SLAB3, planner="stigmergy").task.view_radius  # unset: from the layout
    assert derived is not None and derived > 0.15
    with pytest.raises(ConfigError) as exc:
        load_scenario("construction", {**SLAB3, "task.view_radius": 0.15}, planner="stigmergy")  # set: refused
    assert exc.value.field == "task.view_radius"
    assert "out of view" in str(exc.value) and f"at least {derived:.3f} m" in str(exc.value)
    assert load_scenario("construction", SLAB3, planner="shortest_path").task.view_radius is None  # sees everything
    load_scenario("construction", {**SLAB3, "task.view_radius": derived}, planner="stigmergy")  # the least that works


def test_hidden_columns_are_searched_for_from_above():
    geo, info = _geometry(SLAB2)
    assert geo.hidden.shape == (1, 2) and np.allclose(geo.hidden, [[2.5, 0.5]])  # the middle column only
    assert geo.outside(np.array([2.52, 0.47]), np.array([1.0, 0.5]), keep_hidden=True) == pytest.approx([2.5, 0.5])
    assert not geo.inside(geo.outside(np.array([2.52, 0.47]), np.array([1.0, 0.5])))  # boxes: from beside
    lowest = (
        info.layout.slots[np.all(np.isclose(info.layout.slots[:, :2], [2.5, 0.5]), axis=1), 2].min()
        + info.layout.grasp_height
    )
    assert geo.cruise_altitude - lowest <= geo.view_range - ALTITUDE_TOL
    rel = np.array([0.0, 0.0, lowest - geo.cruise_altitude])
    assert view_distance(rel, "chebyshev") <= geo.view_range


def test_a_slot_search_point_over_a_deep_structure_goes_to_an_edge_where_its_column_is_in_view():
    """Over the far column of a 3-deep slab, the edge on the agent's side is out of view of it: the search for a
    slot goes round to an edge that sees it; a box search, and the thesis's one-deep wall, keep the near edge."""
    geo, _ = _geometry(SLAB2)
    far, start = np.array([2.6, 0.5]), np.array([1.0, 0.5])
    q = geo.outside(far, start, keep_hidden=True)
    assert not geo.inside(q) and np.max(np.abs(q - far)) <= geo.sight
    near = geo.outside(far, start)  # boxes: the shortest way, the near edge
    assert near[0] < 2.4 and np.max(np.abs(near - far)) > geo.sight
    thesis, _ = _geometry({})
    column = np.array([2.7, 0.4])
    assert thesis.outside(column, start, keep_hidden=True) == pytest.approx(thesis.outside(column, start))


def test_a_five_box_tower_is_built_with_stigmergy_and_orca():
    res = pybullet_swarm.run(load_scenario("construction", TOWER), planner="stigmergy", avoidance="orca", seed=0)
    m = res.metrics
    assert res.exit_status is ExitStatus.COMPLETED, m
    assert m["boxes_placed"] == 5 and m["collisions"]["agent_structure"] == 0


def test_two_four_high_walls_with_twelve_agents_start_placing_boxes():
    sc = load_scenario("construction", {**DOUBLE_WALL, "task.time_limit_s": 60.0})
    m = pybullet_swarm.run(sc, planner="stigmergy", avoidance="orca", seed=0).metrics
    assert m["exit_status"] == "timeout" and m["boxes_placed"] >= 3, m
    assert m["collisions"]["agent_structure"] == 0 and m["collisions"]["agent_agent"] == 0


@pytest.mark.slow
def test_two_four_high_walls_with_twelve_agents_are_built():
    sc = load_scenario("construction", DOUBLE_WALL)
    m = pybullet_swarm.run(sc, planner="stigmergy", avoidance="orca", seed=0).metrics
    assert m["exit_status"] == "completed" and m["boxes_placed"] == 20, m
    # seeds 0..3 of this set-up gave one agent-agent contact in all (a follower catching up with a leader
    # that stops at the same search point; on seed 0 with clear_spent_goals, on another without it)
    assert m["collisions"]["agent_agent"] <= 1 and m["collisions"]["agent_structure"] == 0, m
