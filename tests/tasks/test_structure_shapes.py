"""Structures and depots written as voxels and named shapes: expansion at load, one-line refusals."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.cli.main import main
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.tasks.layouts import LayoutError, expand_boxes

DEPOT = {"shape": "grid", "origin": [0.4, 0.3], "size": [3, 3], "pitch": 0.2, "height": 1}


def _load(structure, boxes=None, **extra):
    over = {"task.structure": structure, "task.boxes": boxes if boxes is not None else DEPOT, **extra}
    return load_scenario("construction", over)


def _set(points):
    return {tuple(np.round(p, 9)) for p in np.asarray(points, dtype=float)}


def test_the_thesis_wall_as_a_stepped_wall_is_its_list_of_slots():
    thesis = load_scenario("construction")
    shape = {"shape": "stepped_wall", "origin": [2.7, 0.2], "length": 4, "height": 3, "axis": "y", "pitch": 0.2}
    s = load_scenario("construction", {"task.structure": shape})
    assert s.task.structure == thesis.task.structure  # same slots, same order
    assert s.data["task"]["structure"] == thesis.data["task"]["structure"]  # the resolved scenario lists them


def test_voxel_layers_stand_on_each_other_at_the_box_size():
    v = {"voxels": {"origin": [2.0, 0.3], "pitch": 0.2, "layers": [["XX", "X."], "X"]}}
    got = expand_boxes(v, 0.1, "structure")
    assert _set(got) == _set([[2.0, 0.3, 0.05], [2.2, 0.3, 0.05], [2.0, 0.5, 0.05], [2.0, 0.3, 0.15]])
    along_y = expand_boxes({"voxels": {**v["voxels"], "rows": "y"}}, 0.1, "structure")
    assert _set(along_y) == _set([[2.0, 0.3, 0.05], [2.0, 0.5, 0.05], [2.2, 0.3, 0.05], [2.0, 0.3, 0.15]])
    raised = expand_boxes({"voxels": {"origin": [1.0, 1.0, 0.25], "layers": ["#-#"]}}, 0.1, "structure")
    assert _set(raised) == _set([[1.0, 1.0, 0.25], [1.2, 1.0, 0.25]])  # default pitch: the box size


@pytest.mark.parametrize(
    ("spec", "count", "top_layer"),
    [
        ({"shape": "wall", "origin": [2, 0.3], "length": 4, "height": 2}, 8, 4),
        ({"shape": "stepped_wall", "origin": [2, 0.3], "length": 4}, 10, 1),
        ({"shape": "stepped_wall", "origin": [2, 0.3], "length": 5, "step": 2}, 9, 1),
        ({"shape": "slab", "origin": [2, 0.3], "size": [3, 3]}, 9, 9),
        ({"shape": "grid", "origin": [2, 0.3], "size": [3, 3], "count": 7}, 7, 7),
        ({"shape": "tower", "origin": [2, 0.3], "height": 5}, 5, 1),
        ({"shape": "pyramid", "origin": [2, 0.3], "base": 3}, 10, 1),
        ({"shape": "pyramid", "origin": [2, 0.3], "base": 4}, 20, 4),
        ({"shape": "ring", "origin": [2, 0.3], "size": [3, 4], "height": 2}, 20, 10),
    ],
)
def test_named_shapes_expand_to_their_boxes(spec, count, top_layer):
    pts = np.asarray(expand_boxes(spec, 0.1, "structure"))
    assert len(pts) == count
    assert len(_set(pts)) == count  # no cell twice
    assert np.count_nonzero(np.isclose(pts[:, 2], pts[:, 2].max())) == top_layer
    assert np.all(np.diff(pts[:, 2]) >= -1e-12)  # layer by layer from the ground up
    assert np.allclose(pts[0], [2.0, 0.3, 0.05])  # the origin is the first cell of the bottom layer


def test_a_ring_leaves_its_inside_empty_and_a_wall_turns_with_its_axis():
    ring = np.asarray(expand_boxes({"shape": "ring", "origin": [0, 0], "size": [3, 3]}, 0.1, "structure"))
    assert not np.any(np.all(np.isclose(ring[:, :2], [0.1, 0.1]), axis=1))
    wall = np.asarray(expand_boxes({"shape": "wall", "origin": [1, 2], "length": 3, "axis": "y"}, 0.1, "structure"))
    assert np.allclose(wall[:, 0], 1.0) and np.allclose(wall[:, 1], [2.0, 2.1, 2.2])


def test_several_structures_and_a_depot_grid_load_and_check():
    structure = [
        {"shape": "tower", "origin": [2.3, 0.3], "height": 2},
        {"voxels": {"origin": [2.7, 0.2], "pitch": 0.2, "rows": "y", "layers": ["XXX"]}},
    ]
    s = _load(structure, {"shape": "grid", "origin": [0.4, 0.3], "size": [3, 3], "pitch": 0.2, "count": 5})
    assert len(s.task.structure) == 5 and len(s.task.boxes) == 5
    assert main(["check", "construction", "--quiet", "--set", f"task.structure={structure}"]) == 0


@pytest.mark.parametrize(
    ("structure", "field", "text"),
    [
        ({"voxels": {"origin": [2.5, 0.3], "layers": ["XX", ["X?"]]}}, "task.structure.voxels.layers[1][0]", "'?'"),
        ({"voxels": {"origin": [2.5, 0.3], "layers": ["..."]}}, "task.structure.voxels.layers", "no box"),
        ({"voxels": {"origin": [2.5], "layers": ["X"]}}, "task.structure.voxels.origin", "at least 2"),
        ({"voxels": {"origin": [2.5, 0.3], "layers": ["X"], "pich": 0.2}}, "task.structure.voxels.pich", "unknown"),
        ({"shape": "wal", "origin": [2.5, 0.3]}, "task.structure.shape", "must be one of"),
        ({"shape": "wall", "origin": [2.5, 0.3]}, "task.structure.length", "is required"),
        ({"shape": "wall", "origin": [2.5, 0.3], "length": 0}, "task.structure.length", ">= 1"),
        ({"shape": "wall", "origin": [2.5, 0.3], "length": 2, "axis": "z"}, "task.structure.axis", "'x' or 'y'"),
        (
            {"shape": "stepped_wall", "origin": [2.5, 0.3], "length": 3, "height": 4},
            "task.structure.height",
            "at most 3",
        ),
        ({"shape": "slab", "origin": [2, 0.3], "size": [400, 400], "height": 400}, "task.structure", "more than 500"),
        ({"sape": "wall"}, "task.structure", "voxels: or shape:"),
        ([{"shape": "tower", "origin": [2.5, 0.3], "height": 2}, [2.7, 0.2, 0.05]], "task.structure[1]", "a list of"),
        ([{"shape": "tower", "origin": [2.5, 0.3], "height": "2"}], "task.structure[0].height", "integer"),
        ({"shape": "tower", "origin": [2.5, 0.3], "height": 12}, "task.structure", "at most as many slots as boxes"),
        ({"shape": "wall", "origin": [2.9, 0.3], "length": 3}, "task.structure[1]", "outside the arena"),
    ],
)
def test_bad_structures_are_refused_naming_the_field(structure, field, text):
    with pytest.raises(ConfigError) as exc:
        _load(structure)
    assert exc.value.field == field
    assert text in str(exc.value)
    assert "\n" not in str(exc.value)


def test_bad_depot_is_refused_naming_the_field():
    with pytest.raises(ConfigError) as exc:
        _load([[2.7, 0.2, 0.05]], {"shape": "grid", "origin": [0.4, 0.3], "size": [2, 2], "count": 5})
    assert exc.value.field == "task.boxes.count"


def test_check_exits_2_with_one_line_on_a_bad_voxel(capsys):
    bad = "task.structure={voxels: {origin: [2.5, 0.3], layers: [XQ]}}"
    assert main(["check", "construction", "--quiet", "--set", bad]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "task.structure.voxels.layers[0]" in err


def test_expansion_is_bounded_before_anything_is_made():
    with pytest.raises(LayoutError):
        expand_boxes({"shape": "grid", "origin": [0, 0], "size": [500, 500], "height": 500}, 0.1, "boxes")
    got = expand_boxes({"shape": "grid", "origin": [0, 0], "size": [500, 500], "height": 500, "count": 3}, 0.1, "boxes")
    assert len(got) == 3
    assert expand_boxes([[1.0, 2.0, 0.05]], 0.1, "boxes") == [[1.0, 2.0, 0.05]]  # a list of centres as it is
