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
