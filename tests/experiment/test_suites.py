"""Suite files: the bundled construction suite keeps its promises; bad files are refused in one line."""

from __future__ import annotations

import copy
import importlib.util
from pathlib import Path

import pytest
import yaml

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.layouts import SHAPES
from pybullet_swarm.experiment.scenario import build_scenario
from pybullet_swarm.experiment.suites import (
    HOLDOUT_SEED,
    ComposedLayout,
    GeneratedLayout,
    load_suite,
    resolve_suite_path,
)

ROOT = Path(__file__).resolve().parents[2]


def test_the_construction_suite_holds_a_dev_and_a_holdout_split():
    suite = load_suite("construction")
    assert suite.name == "construction" and suite.version >= 1 and len(suite.digest) == 12
    dev, holdout = suite.split("dev"), suite.split("holdout")
    assert dev.seeds == tuple(range(50))
    assert len(holdout.layouts) >= 20 and all(isinstance(lay, GeneratedLayout) for lay in holdout.layouts)
    assert min(lay.generator_seed for lay in holdout.layouts) >= HOLDOUT_SEED
    assert min(holdout.seeds) >= HOLDOUT_SEED
    assert set(holdout.planners) == {"shortest_path", "stigmergy", "layered_stigmergy"}
    assert holdout.avoidance == ("orca",)


def test_dev_layouts_are_those_of_the_construction_suite_script():
    spec = importlib.util.spec_from_file_location("construction_suite", ROOT / "scripts" / "construction_suite.py")
    script = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(script)
    suite = load_suite("construction")
    dev = suite.split("dev")
    assert [lay.name for lay in dev.layouts] == list(script.LAYOUTS)
    for lay in dev.layouts:
        if isinstance(lay, ComposedLayout) and not lay.name.startswith("random_"):
            ours, theirs = suite.layout_data(lay, dev), script.layout_data(lay.name)
            assert ours["task"] == theirs["task"] and ours["agents"] == theirs["agents"], lay.name


def test_holdout_layouts_cover_every_shape_family_swarm_size_and_depot_count():
    suite = load_suite("construction")
    holdout = suite.split("holdout")
    shapes, depots, agents, arenas = set(), set(), [], []
    for lay in holdout.layouts:
        data = suite.layout_data(lay, holdout)
        s = build_scenario(copy.deepcopy(data), source=lay.name)
        assert lay.shape in data["description"]
        shapes.add(lay.shape)
        boxes = data["task"]["boxes"]
        depots.add(len(boxes) if isinstance(boxes, list) else 1)
        agents.append(s.agents.count)
        arenas.append(tuple(s.arena.size))
    assert shapes == set(SHAPES) and depots == {1, 2}
    assert 3 <= min(agents) and max(agents) <= 20 and max(agents) - min(agents) >= 10
    assert all(lx <= 6.0 and ly <= 4.0 for lx, ly in arenas) and max(ly for _, ly in arenas) > 3.0


GOOD = {
    "suite": "tiny",
    "version": 1,
    "planners": ["shortest_path"],
    "avoidance": ["none"],
    "splits": {
        "dev": {
            "seeds": {"start": 0, "count": 2},
            "layouts": [{"name": "t1", "structure": {"shape": "tower", "origin": [1.6, 0.5], "height": 1},
                         "agents": 1, "arena": [2.0, 1.0]}],
        },
        "holdout": {
            "seeds": [1000],
            "layouts": [{"name": "g1", "generator_seed": 1000, "shape": "tower", "agents": 2}],
        },
    },
}  # fmt: skip


def _write(tmp_path: Path, data: dict) -> Path:
    path = tmp_path / "suite.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_a_good_suite_loads(tmp_path):
    suite = load_suite(_write(tmp_path, GOOD))
    assert suite.split("dev").seeds == (0, 1) and suite.split("holdout").seeds == (1000,)
    assert resolve_suite_path(tmp_path / "suite.yaml").name == "suite.yaml"


def _mutate(path: str, value: object) -> dict:
    data = copy.deepcopy(GOOD)
    node = data
    keys = path.split("/")
    for k in keys[:-1]:
        node = node[int(k)] if isinstance(node, list) else node[k]
    last = keys[-1]
    if value is KeyError:
        del node[last]
    elif isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value
    return data


@pytest.mark.parametrize(
    ("path", "value", "field", "words"),
    [
        ("splits/holdout", KeyError, "splits", "dev and holdout"),
        ("splits/holdout/seeds", [999], "splits.holdout.seeds", ">= 1000"),
        ("splits/dev/seeds", {"start": 998, "count": 3}, "splits.dev.seeds", "< 1000"),
        ("splits/holdout/layouts/0/generator_seed", 12, "splits.holdout.layouts[0].generator_seed", ">= 1000"),
        ("splits/holdout/layouts/0", GOOD["splits"]["dev"]["layouts"][0], "splits.holdout.layouts[0]", "generator"),
        ("splits/dev/layouts/0/scenario", "construction", "splits.dev.layouts[0]", "exactly one of"),
        ("splits/dev/layouts/0/colour", "red", "splits.dev.layouts[0].colour", ""),
        ("splits/holdout/layouts/0/shape", "cube", "splits.holdout.layouts[0].shape", "wall"),
        ("splits/holdout/layouts/0/agents", [9, 3], "splits.holdout.layouts[0].agents", "lo <= hi"),
        ("splits/holdout/layouts/0/depots", 3, "splits.holdout.layouts[0].depots", ""),
        ("version", 0, "version", ""),
        ("planners", [], "planners", ""),
        ("splits/dev/layouts", [GOOD["splits"]["dev"]["layouts"][0]] * 2, "splits.dev.layouts[1].name", "repeats"),
    ],
)
def test_bad_suite_files_are_refused_in_one_line(tmp_path, path, value, field, words):
    with pytest.raises(ConfigError) as err:
        load_suite(_write(tmp_path, _mutate(path, value)))
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("suite.yaml: ") and err.value.field == field, msg
    assert words in msg


def test_an_unknown_suite_and_split_are_refused():
    with pytest.raises(ConfigError, match="no suite file"):
        load_suite("no_such_suite")
    with pytest.raises(ConfigError, match="must be one of dev, holdout"):
        load_suite("construction").split("test")


def test_a_holdout_layout_is_what_the_layout_command_draws(tmp_path, capsys):
    from pybullet_swarm.cli.main import main

    suite = load_suite("construction")
    holdout = suite.split("holdout")
    lay = next(x for x in holdout.layouts if x.depots == 2)
    out = tmp_path / "h.yaml"
    argv = ["layout", "--seed", str(lay.generator_seed), "--shape", str(lay.shape), "--depots", "2",
            "--agents", "3:20", "--max-arena", "6", "4", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    drawn = yaml.safe_load(out.read_text())
    ours = suite.layout_data(lay, holdout)
    assert {k: v for k, v in drawn.items() if k != "name"} == {k: v for k, v in ours.items() if k != "name"}
