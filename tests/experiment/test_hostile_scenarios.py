"""Hostile input through the Python API (issue 23): YAML limits, finiteness, physical ranges, memory
budgets, run directories and saved results. The command-line side is ``tests/cli/test_hostile_input.py``."""

from __future__ import annotations

import copy
import json
import shutil
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from pybullet_swarm import memory
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.rundir import check_output_dir, check_run_dir, clear_run_dir, safe_name
from pybullet_swarm.experiment.scenario import build_scenario, load_scenario
from pybullet_swarm.resources import scenarios_dir
from pybullet_swarm.validation import MAX_NODES, _check_expansion, _UniqueKeyLoader, parse_yaml

HOVER: dict[str, Any] = yaml.safe_load((scenarios_dir() / "hover.yaml").read_text())
CONSTRUCTION: dict[str, Any] = yaml.safe_load((scenarios_dir() / "construction.yaml").read_text())


def bad(data: dict[str, Any]) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        build_scenario(copy.deepcopy(data), source="bad.yaml")
    assert "\n" not in str(info.value)
    return info.value


def with_(data: dict[str, Any], **changes: Any) -> dict[str, Any]:
    """A deep copy of ``data`` with ``a__b=value`` set."""
    out = copy.deepcopy(data)
    for key, value in changes.items():
        node = out
        parts = key.split("__")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return out


# -------------------------------------------------------------- 1. YAML limits
@pytest.mark.parametrize("levels", [1, 2, 3, 4, 5])
def test_1_expanded_size_is_counted_exactly(levels: int) -> None:
    # a: 9 scalars; each further anchor: 9 aliases of the previous one -> 1 + 9 (1 + 9 (...)) values
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 9)}]" for k in range(1, levels)]
    node = yaml.compose("\n".join(lines), Loader=_UniqueKeyLoader)
    per = [10]
    for _ in range(1, levels):
        per.append(1 + 9 * per[-1])
    # the mapping, each key and each anchored list (as expanded where it stands)
    assert _check_expansion(node) == 1 + levels + sum(per)


def test_1_billion_laughs_is_refused_before_construction() -> None:
    lines = ["a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    lines += [f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 9)}]" for k in range(1, 10)]  # 9^10 = 3.5e9 values
    tracemalloc.start()
    with pytest.raises(ConfigError, match=f"x.yaml: too large: the document expands to more than {MAX_NODES}"):
        parse_yaml("\n".join(lines), source="x.yaml")
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak < 5 << 20  # bytes: the graph of the text, never its expansion


def test_1_shared_aliases_below_the_limit_are_fine() -> None:
    data = parse_yaml("a: &a [1, 2, 3]\nb: *a\nc: {<<: {x: 1}, y: 2}\n", source="ok.yaml")
    assert data == {"a": [1, 2, 3], "b": [1, 2, 3], "c": {"x": 1, "y": 2}}


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("1e6", 1e6),
        ("-2E-3", -2e-3),
        (".5e1", 5.0),
        ("1.5e+3", 1500.0),
        ("1_000", 1000),
        ("12", 12),
        ("1e", "1e"),
        ("e5", "e5"),
        ("0x10", 16),
        ("1.0", 1.0),
        (".inf", float("inf")),
    ],
)
def test_1_numbers_are_read_as_people_write_them(text: str, value: Any) -> None:
    got = parse_yaml(f"v: {text}", source="n.yaml")["v"]
    assert got == value and type(got) is type(value)


# ---------------------------------------------------- 2. finite and physical
@pytest.mark.parametrize(
    ("key", "value", "field"),
    [
        ("task__boxes", [[0.25, 0.25, float("nan")]], "task.boxes[0][2]"),
        ("task__structure", [[2.5, 0.5, float("inf")]], "task.structure[0][2]"),
        ("task__box_size", float("nan"), "task.box_size"),
        ("avoidance_params__zz", float("-inf"), "avoidance_params.zz"),
    ],
)
def test_2_non_finite_numbers_are_refused_anywhere(key: str, value: Any, field: str) -> None:
    err = bad(with_(CONSTRUCTION, **{key: value}))
    assert err.field == field and "must be a finite number" in err.detail


@pytest.mark.parametrize("gravity", [0.0, 0.05])
def test_2_gravity_too_small_for_the_hover_controller(gravity: float) -> None:
    err = bad(with_(HOVER, sim__gravity=gravity))
    assert err.field == "sim.gravity" and "must be >= 0.1 m/s^2" in err.detail


def test_2_gravity_the_rotors_cannot_lift() -> None:
    # quad150: 4 kf wmax^2 = 2.94 N for 0.150 kg: it hovers up to 19.6 m/s^2
    err = bad(with_(HOVER, sim__gravity=19.7))
    assert err.field == "sim.gravity" and "cannot lift its own weight" in err.detail
    # just below, the controller design finds the vehicle cannot manoeuvre (rotors near their maximum)
    err = bad(with_(HOVER, sim__gravity=19.5))
    assert err.field == "agents.vehicle" and err.detail.startswith("quad150.yaml: z: ")
    assert "(with sim.gravity 19.5 m/s^2, sim.physics_hz 240, sim.control_hz 48)" in err.detail
    assert load_scenario("hover", {"sim.gravity": 15.0}).sim.gravity == 15.0


def test_2_coordinates_are_bounded() -> None:
    err = bad(with_(HOVER, agents__start=[[1.0, 1.0, 1e6]]))
    assert err.field == "agents.start[0][2]" and "must be <= 100000.0" in err.detail
    # any real number beyond 1e12 (a tour point at 1e308 overflowed the neighbour search)
    tour = yaml.safe_load((scenarios_dir() / "tour.yaml").read_text())
    err = bad(with_(tour, task__points=[[1.0, 1.0, 1e308]]))
    assert err.field == "task.points[0][2]" and "must be a number of magnitude at most 1e+12" in err.detail
    # and a non-zero one below 1e-12 (a range sensor of 5e-324 m overflowed when readings were scaled)
    err = bad(with_(HOVER, sensing__range__range_m=5e-324))
    assert err.field == "sensing.range.range_m" and "must be 0 or a number of magnitude at least 1e-12" in err.detail
    assert load_scenario("hover", {"sensing.range.range_m": 1e-12}).sensing.range.range_m == 1e-12


def test_2_raised_obstacle_compares_vertical_extents() -> None:
    base = with_(HOVER, arena__obstacles=[{"shape": "box", "size": [0.4, 0.4, 0.2], "position": [1.5, 1.5, 1.0]}])
    for z, inside in ((0.011, False), (0.85, False), (0.90, True), (1.0, True), (1.10, True), (1.12, False)):
        data = with_(base, agents__start=[[1.5, 1.5, z]], task__waypoints=[{"t_s": 0, "position": [0.0, 0.0, 0.0]}])
        if inside:
            err = bad(data)
            assert err.field == "arena.obstacles[0]" and "starts inside this obstacle" in err.detail
        else:
            build_scenario(data, source="ok.yaml")


def test_2_start_above_the_ceiling() -> None:
    err = bad(
        with_(
            HOVER,
            arena__height=2.0,
            agents__start=[[1.0, 1.0, 2.5]],
            task__waypoints=[{"t_s": 0, "position": [0.0, 0.0, -1.0]}],
        )
    )
    assert err.field == "agents.start[0]" and "above the ceiling" in err.detail


# ------------------------------------------------------------ memory budget
def test_2_budget_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    for text, size in (
        ("", memory.DEFAULT_BUDGET),
        ("512", 512 << 20),
        ("512M", 512 << 20),
        ("16G", 16 << 30),
        ("16GiB", 16 << 30),
        ("1.5g", 3 << 29),
        ("100k", 100 << 10),
    ):
        monkeypatch.setenv(memory.ENV_VAR, text)
        assert memory.memory_budget() == size
    for text in ("lots", "-1", "0", "1e400", "12 parsecs"):
        monkeypatch.setenv(memory.ENV_VAR, text)
        with pytest.raises(ConfigError, match=memory.ENV_VAR):
            memory.memory_budget()


def test_2_colony_estimate_bounds_the_measured_peak() -> None:
    from pybullet_swarm.planning.aco import ACOParams, solve_tsp

    rng = np.random.default_rng(0)
    warm = rng.random((20, 2))
    solve_tsp(np.linalg.norm(warm[:, None] - warm[None], axis=2), ACOParams(iterations=1, local_search="none"), seed=0)
    n = 600  # after the compiled kernels are loaded: the colony's own arrays only
    pts = rng.random((n, 2))
    dist = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    tracemalloc.start()
    solve_tsp(dist, ACOParams(iterations=2, local_search="none"), seed=0)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    estimate = memory.colony_bytes(n, ants=10, iterations=2, candidates=15)
    assert peak + dist.nbytes <= estimate <= 1.2 * (peak + dist.nbytes)


def test_2_grid_estimate_is_its_arrays() -> None:
    from pybullet_swarm.planning.pheromone_grid import LayerSpec, PheromoneGrid

    grid = PheromoneGrid([3.0, 1.0], [LayerSpec("task")], cell=0.05, height=1.0)
    arrays = sum(a.nbytes for a in (*grid.values.values(), *grid.sources.values()))
    assert memory.grid_bytes(np.prod(grid.shape), 0, 1, 0) == 2 * arrays


def test_2_budget_names_the_field_and_the_size(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(memory.ENV_VAR, raising=False)
    err = bad(
        with_(
            CONSTRUCTION,
            arena__size=[30.0, 10.0],
            planner={"name": "layered_stigmergy", "params": {"cell_size": 0.01, "grid_height": 2.0}},
        )
    )
    assert err.field == "planner.params.cell_size"
    # 2 layers x (3000 x 1000 x 200 cells x 16 B + 501 snapshots x 3000 x 1000 columns x 4 B) = 29.1 GiB
    assert (
        "a pheromone grid of 3000 x 1000 x 200 cells (2 layer(s), with its snapshots) would need about 29.1 GiB, "
        "above the memory budget of 4 GiB" in err.detail
    )
    err = bad(with_(HOVER, agents__count=2, task__time_limit_s=1e5, sim__record_hz=240))
    assert err.field == "sim.record_hz" and "recording 24000002 samples of 2 agents" in err.detail


# ----------------------------------------------------------- 3. vehicles
def test_3_vehicle_errors_name_the_vehicle_file_and_field(tmp_path: Path) -> None:
    from pybullet_swarm.resources import urdf_dir

    shutil.copy(urdf_dir() / "quad150.urdf", tmp_path / "quad150.urdf")
    params = yaml.safe_load((urdf_dir() / "quad150.yaml").read_text())
    cases = [
        ("mass", float("inf"), "mass: must be a finite number"),
        ("inertia", [1e-4, 1e-4, 5e-4], "inertia: principal moments of a rigid body"),
        ("max_rotor_speed", 0, "max_rotor_speed: must be > 0"),
        ("collision_size", [0.1, 0.1], "collision_size[2]: is required"),
    ]
    for k, (key, value, expected) in enumerate(cases):
        path = tmp_path / f"v{k}.yaml"
        path.write_text(yaml.safe_dump({**params, key: value}))
        err = bad(with_(HOVER, agents__vehicle=str(path)))
        assert err.field == "agents.vehicle" and err.detail.startswith(f"v{k}.yaml: {expected}"), err.detail


@pytest.mark.parametrize(
    ("urdf", "why"),
    [
        ("<robot name='r'><link name='a'/><joint name='j' type='revolute'/></robot>", "joint 'j' is 'revolute'"),
        (
            "<robot name='r'><link name='a'><visual><geometry><mesh filename='gone.stl'/></geometry></visual></link></robot>",
            "mesh file 'gone.stl' not found",
        ),
        ("<!DOCTYPE r [<!ENTITY a 'aaaa'>]><robot name='r'><link name='&a;'/></robot>", "XML entities"),
        ("\x00\x01", "not well-formed XML"),
    ],
)
def test_3_urdf_must_be_one_rigid_body(tmp_path: Path, urdf: str, why: str) -> None:
    from pybullet_swarm.resources import urdf_dir
    from pybullet_swarm.vehicle import load_vehicle

    (tmp_path / "r.urdf").write_text(urdf)
    params = yaml.safe_load((urdf_dir() / "quad150.yaml").read_text())
    (tmp_path / "r.yaml").write_text(yaml.safe_dump({**params, "urdf": "r.urdf"}))
    with pytest.raises(ConfigError) as info:
        load_vehicle(tmp_path / "r.yaml")
    assert info.value.source == "r.yaml" and info.value.field == "urdf" and why in info.value.detail


# ------------------------------------------------------ 4. run directories
@pytest.mark.parametrize(
    ("name", "safe"),
    [
        ("../../../x", "x"),
        ("/some/abs/path", "some_abs_path"),
        ("..", "scenario"),
        ("", "scenario"),
        (".hidden", "hidden"),
        ("-rf", "rf"),
        ("hover_swarm", "hover_swarm"),
        ("a b\nc", "a_b_c"),
    ],
)
def test_4_safe_names(name: str, safe: str) -> None:
    assert safe_name(name) == safe


def test_4_output_check_leaves_nothing_behind(tmp_path: Path) -> None:
    target = tmp_path / "a" / "b" / "c"
    assert check_output_dir(target) == target
    assert list(tmp_path.iterdir()) == []


def test_4_previous_run_is_cleared_foreign_files_kept(tmp_path: Path) -> None:
    run = tmp_path / "run"
    (run / "plots").mkdir(parents=True)
    for name in ("metrics.json", "scenario.yaml", "video.mp4", ".metrics.json.abc.tmp"):
        (run / name).write_text("old")
    (run / "plots" / "position.png").write_text("old")
    check_run_dir(run)
    clear_run_dir(run, keep=frozenset({"video.mp4"}))
    assert sorted(p.name for p in run.iterdir()) == ["video.mp4"]
    (run / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="is not empty and not a run directory"):
        check_run_dir(run)


# ----------------------------------------------------- 6. saved results
def test_6_saved_results_are_checked(tmp_path: Path) -> None:
    from pybullet_swarm.experiment.results import read_metrics, read_pheromones, read_timeseries

    (tmp_path / "metrics.json").write_text(json.dumps({"completion_time_s": "soon"}))
    with pytest.raises(ConfigError) as info:
        read_metrics(tmp_path)
    assert info.value.field == "completion_time_s"
    (tmp_path / "metrics.json").write_text("[" * 100_000)
    with pytest.raises(ConfigError, match="unreadable: not JSON"):
        read_metrics(tmp_path)
    m = 5
    arrays = {
        "t": np.arange(m, dtype=np.float32),
        "positions": np.zeros((m, 2, 3)),
        "quaternions": np.zeros((m, 2, 4)),
        "velocities": np.zeros((m, 2, 3)),
        "rotor_speeds": np.zeros((m, 2, 4)),
        "ref_positions": np.zeros((m, 2, 3)),
        "ref_velocities": np.zeros((m, 2, 3)),
    }
    np.savez(tmp_path / "ts.npz", **arrays)
    assert read_timeseries(tmp_path / "ts.npz").positions.shape == (m, 2, 3)
    np.savez(tmp_path / "ts.npz", **{**arrays, "velocities": np.full((m, 2, 3), np.nan)})
    with pytest.raises(ConfigError, match="must hold finite numbers"):
        read_timeseries(tmp_path / "ts.npz")
    np.savez(tmp_path / "ts.npz", **{**arrays, "t": np.array(["a"] * m)})
    with pytest.raises(ConfigError, match="must hold numbers"):
        read_timeseries(tmp_path / "ts.npz")
    np.savez(
        tmp_path / "ph.npz",
        cell=np.array(0.1),
        extent=np.array([3.0, 1.0, 1.0]),
        layers=np.array(["task"]),
        snapshot_t=np.zeros(2),
        task=np.zeros((30, 10, 10)),
        task_history=np.zeros((2, 30, 9)),
        task_marked=np.zeros(2),
    )
    with pytest.raises(ConfigError) as info:
        read_pheromones(tmp_path / "ph.npz")
    assert info.value.field == "task_history"


def test_6_zip_bomb_is_refused_unread(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from pybullet_swarm.experiment.results import read_timeseries

    np.savez_compressed(tmp_path / "ts.npz", t=np.zeros(20_000_000, dtype=np.float32))  # 80 MB of zeros, tiny file
    monkeypatch.setenv(memory.ENV_VAR, "16M")
    with pytest.raises(ConfigError, match="above the memory budget"):
        read_timeseries(tmp_path / "ts.npz")
