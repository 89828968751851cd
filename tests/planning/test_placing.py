"""Where a construction planner lets a box go: above the boxes beside its slot when the guide reaches that
high, and a slab of boxes side by side built that way with no contact."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

import pybullet_swarm
from pybullet_swarm.experiment.layouts import compose_layout
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.planning.base import TaskInfo
from pybullet_swarm.planning.views.construction import ConstructionLayout
from pybullet_swarm.planning.placing import OVER_NEIGHBOURS_CLEARANCE, release_clearances, side_by_side

WALL_10 = np.array([[2.7, 0.3 + 0.1 * k, 0.05] for k in range(3)] + [[2.7, 0.35, 0.15]])  # 3 side by side, 1 on top
WALL_20 = np.array([[2.7, 0.2 + 0.2 * k, 0.05] for k in range(3)])  # the thesis's pitch


def _info(slots: np.ndarray, guide: float) -> TaskInfo:
    return TaskInfo(
        arena_size=np.array([3.0, 1.0]),
        n_agents=1,
        agent_radius=0.106,
        v_max=np.full(3, 0.15),
        layout=ConstructionLayout(np.zeros((0, 3)), slots, box_size=0.1, grasp_height=0.065, guide_height=guide),
    )


def test_slots_side_by_side_are_those_touching_another_on_their_level():
    assert side_by_side(WALL_10, 0.1).tolist() == [True, True, True, False]  # the top box has none beside it
    assert not side_by_side(WALL_20, 0.1).any()
    diagonal = np.array([[2.5, 0.4, 0.05], [2.6, 0.5, 0.05]])
    assert side_by_side(diagonal, 0.1).all()


@pytest.mark.parametrize(
    "slots, guide, over, expected",
    [
        (WALL_10, 0.12, True, [0.11, 0.11, 0.11, 0.004]),  # above the neighbours' tops, the guide reaches
        (WALL_10, 0.12, False, [0.004] * 4),  # switched off
        (WALL_10, 0.05, True, [0.004] * 4),  # the guide does not reach that high
        (WALL_10, 0.0, True, [0.004] * 4),  # free placement: no guide
        (WALL_20, 0.12, True, [0.004] * 3),  # nothing beside the slots
    ],
)
def test_release_clearances(slots, guide, over, expected):
    got = release_clearances(_info(slots, guide), 0.004, over_neighbours=over)
    assert got == pytest.approx(expected)
    assert 0.1 + OVER_NEIGHBOURS_CLEARANCE == pytest.approx(0.11)


@pytest.mark.parametrize("over, guide_carried", [(True, True), (False, True), (True, False), (False, False)])
def test_a_slab_of_boxes_side_by_side_is_built_when_boxes_pass_their_neighbours(over, guide_carried, tmp_path: Path):
    """The suite's 3 x 3 slab (pitch = box size) with shortest_path and orca, without downwash: let go above
    the neighbours' tops, or lowered past them by the chamfers (``task.guide_carried``), every box is placed
    with no contact; with neither, a box lowered into a gap catches on a neighbour's edge and its carrier
    tips over (or the run is held up)."""
    data = compose_layout({"shape": "slab", "origin": [2.4, 0.4], "size": [3, 3]}, agents=5, arena=[3.0, 1.5])
    path = tmp_path / "slab.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    overrides = {
        "sim.downwash": False,
        "planner.params.release_over_neighbours": over,
        "task.guide_carried": guide_carried,
    }
    sc = load_scenario(path, overrides, planner="shortest_path")
    m = pybullet_swarm.run(sc, planner="shortest_path", avoidance="orca", seed=0).metrics
    c = m["collisions"]
    if over or guide_carried:
        assert m["exit_status"] == "completed" and m["boxes_placed"] == 9, m
        assert c["agent_agent"] == c["agent_structure"] == c["load_structure"] == 0, c
    else:
        assert m["exit_status"] != "completed" or c["load_structure"] > 0, m
