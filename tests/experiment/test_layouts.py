"""Random construction layouts: valid for many seeds, reproducible, accepted by `check`."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from pybullet_swarm.cli.main import main
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.layouts import SHAPES, random_layout
from pybullet_swarm.experiment.scenario import build_scenario


@pytest.mark.parametrize("seed", range(40))
def test_layouts_of_many_seeds_load(seed):
    data = random_layout(seed)
    s = build_scenario(data, source="layout")
    lx, ly = s.arena.size
    assert 2.0 <= lx <= 6.0 and 1.0 <= ly <= 3.0
    assert 1 <= s.agents.count <= 20
    assert len(s.task.boxes) == len(s.task.structure) >= 1
    slots, boxes = np.asarray(s.task.structure), np.asarray(s.task.boxes)
    assert boxes[:, 0].max() < slots[:, 0].min()  # the depot lies between the swarm and the structure
    assert random_layout(seed) == data  # a seed always gives the same layout


@pytest.mark.parametrize("shape", SHAPES)
def test_every_shape_can_be_asked_for(shape):
    data = random_layout(3, shape=shape, agents=12, arena=[5.0, 3.0])
    assert data["agents"]["count"] == 12 and data["arena"]["size"] == [5.0, 3.0]
    assert shape in data["description"]
    structure = data["task"]["structure"]
    if shape == "several":
        assert isinstance(structure, list) and len(structure) >= 2
    else:
        assert structure["shape"] == shape


def test_a_swarm_that_cannot_fit_is_refused_in_one_line():
    with pytest.raises(ConfigError, match="no layout fits"):
        random_layout(0, agents=20, arena=[0.6, 0.6])


@pytest.mark.parametrize("seed", [1, 5, 11])
def test_cli_writes_a_layout_that_check_accepts(tmp_path, capsys, seed):
    out = tmp_path / f"layout{seed}.yaml"
    assert main(["layout", "--seed", str(seed), "--out", str(out)]) == 0
    assert yaml.safe_load(out.read_text())["seed"] == seed
    capsys.readouterr()
    assert main(["check", str(out), "--quiet"]) == 0
    assert main(["check", str(out), "--quiet", "--set", "planner.name=stigmergy"]) == 0


def test_cli_refuses_bad_layout_arguments(capsys):
    assert main(["layout", "--agents", "0"]) == 2
    assert main(["layout", "--shape", "cube"]) == 2
    assert main(["layout", "--arena", "0.1", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3


@pytest.mark.parametrize("shape", SHAPES)
def test_cli_draws_every_shape_family_and_check_accepts_it_with_every_planner(tmp_path, capsys, shape):
    out = tmp_path / f"{shape}.yaml"
    assert main(["layout", "--seed", "1", "--shape", shape, "--out", str(out)]) == 0
    data = yaml.safe_load(out.read_text())
    structure = data["task"]["structure"]
    shapes = [s["shape"] for s in structure] if isinstance(structure, list) else [structure["shape"]]
    assert (len(shapes) >= 2) if shape == "several" else shapes == [shape]
    capsys.readouterr()
    for planner in ("shortest_path", "stigmergy", "layered_stigmergy"):
        assert main(["check", str(out), "--quiet", "--set", f"planner.name={planner}"]) == 0


@pytest.mark.parametrize("seed", [0, 4, 9])
def test_two_depots_lie_along_the_long_sides_and_hold_every_box(tmp_path, capsys, seed):
    out = tmp_path / "two.yaml"
    assert main(["layout", "--seed", str(seed), "--depots", "2", "--arena", "4", "3", "--out", str(out)]) == 0
    data = yaml.safe_load(out.read_text())
    depots = data["task"]["boxes"]
    assert isinstance(depots, list) and len(depots) == 2 and "2 depots" in data["description"]
    s = build_scenario(data, source="two")
    boxes, slots = np.asarray(s.task.boxes), np.asarray(s.task.structure)
    assert len(boxes) == len(slots)
    low, high = boxes[boxes[:, 1] < 1.5], boxes[boxes[:, 1] > 1.5]
    assert len(low) == len(boxes) - len(boxes) // 2 and len(high) == len(boxes) // 2
    assert low[:, 1].max() <= 1.0 + 1e-9 and high[:, 1].min() >= 2.0 - 1e-9  # a free lane down the middle
    assert boxes[:, 0].max() < slots[:, 0].min()


def test_drawn_ranges_of_swarm_size_and_arena():
    for seed in range(1000, 1012):
        data = random_layout(seed, agents=(3, 20), max_arena=(6.0, 4.0))
        assert 3 <= data["agents"]["count"] <= 20
        lx, ly = data["arena"]["size"]
        assert 2.0 <= lx <= 6.0 and 1.0 <= ly <= 4.0


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [({"depots": 3}, "--depots"), ({"agents": (5, 2)}, "--agents"), ({"max_arena": (30.0, 2.0)}, "--max-arena")],
)
def test_generator_arguments_no_draw_can_satisfy_are_refused(kwargs, words):
    with pytest.raises(ConfigError, match=words):
        random_layout(0, **kwargs)
