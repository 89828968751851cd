"""Hostile and malformed input at the command line (issue 23): one test per defect of the issue.

Every case exits 2 with exactly one ``pybullet-swarm: error:`` line naming the file (or option)
and the field, before any simulation starts, or is handled as the README documents.
"""

from __future__ import annotations

import json
import os
import shutil
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from pybullet_swarm.cli.main import main
from pybullet_swarm.resources import scenarios_dir, urdf_dir

PREFIX = "pybullet-swarm: error: "

# one agent, half a second: the smallest complete run
TINY: dict[str, Any] = {
    "name": "tiny",
    "seed": 0,
    "arena": {"size": [2.0, 2.0]},
    "agents": {"count": 1},
    "task": {"kind": "waypoints", "time_limit_s": 0.5, "waypoints": [{"t_s": 0, "position": [0.0, 0.0, 0.3]}]},
}


def cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def one_line(result: tuple[int, str, str], *parts: str) -> str:
    """Exit 2 and one error line holding every part; returns the line."""
    code, out, err = result
    assert code == 2, (code, out, err)
    assert err.count("\n") == 1 and err.startswith(PREFIX), err
    for part in parts:
        assert part in err, (part, err)
    return err.strip()


def write(path: Path, data: Any) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


@pytest.fixture
def no_simulation(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if a simulation is started."""

    def refuse(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("a simulation started")

    monkeypatch.setattr("pybullet_swarm.experiment.runner.Simulation", refuse)
    monkeypatch.setattr("pybullet_swarm.experiment.sweep.run_sweep", refuse)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished run directory of the tiny scenario (with its figures)."""
    base = tmp_path_factory.mktemp("run")
    scenario = write(base / "tiny.yaml", TINY)
    assert main(["run", str(scenario), "--out", str(base / "run"), "--quiet"]) == 0
    return base / "run"


# ----------------------------------------------------------- 1. alias bombs
BOMB = """name: bomb
task: {kind: waypoints, time_limit_s: 1, waypoints: [{t_s: 0, position: [0, 0, 1]}]}
planner:
  params:
    a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]
""" + "".join(f"    {c}: &{c} [{', '.join(['*' + p] * 9)}]\n" for p, c in zip("abcdefghi", "bcdefghij"))

MERGE_BOMB = """name: merge
task: {kind: waypoints, time_limit_s: 1, waypoints: [{t_s: 0, position: [0, 0, 1]}]}
planner:
  params:
    a: &a {k0: 0, k1: 1, k2: 2, k3: 3, k4: 4, k5: 5, k6: 6, k7: 7}
""" + "".join(f"    {c}: &{c} {{<<: [{', '.join(['*' + p] * 8)}]}}\n" for p, c in zip("abcdefghi", "bcdefghij"))


@pytest.mark.parametrize("text", [BOMB, MERGE_BOMB], ids=["nested_anchors", "merge_keys"])
def test_1_alias_bomb_is_refused_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str) -> None:
    path = tmp_path / "bomb.yaml"
    path.write_text(text, encoding="utf-8")
    assert len(text) < 1000
    one_line(cli(capsys, "check", path), "bomb.yaml: too large: the document expands to more than")


def test_1_document_size_is_bounded(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "huge.yaml"
    path.write_text("name: x\ndescription: '" + "x" * (2 << 20) + "'\n", encoding="utf-8")
    one_line(cli(capsys, "check", path), "huge.yaml: too large: more than 1048576 bytes")


def test_1_set_value_is_bounded_too(capsys: pytest.CaptureFixture[str]) -> None:
    bomb = "[" + ",".join(["&a [1,2,3,4,5,6,7,8,9]"] + ["*a"] * 8) + "]"
    nested = "&b " + bomb
    for _ in range(6):
        nested = f"&{'x'}{_} [" + ",".join([nested] + [f"*{'x'}{_ - 1}" if _ else "*b"] * 8) + "]"
    one_line(cli(capsys, "check", "hover", "--set", f"planner.params.x={nested}"), "planner.params.x")


# ------------------------------------------------ 3. --out that cannot be used
def test_3_replay_out_must_be_a_file_in_a_writable_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], run_dir: Path
) -> None:
    existing = tmp_path / "EXISTING_FILE"
    existing.write_text("not a directory\n")
    one_line(
        cli(capsys, "replay", run_dir, "--out", existing / "video.mp4"),
        f"--out {existing}: exists and is not a directory",
    )
    one_line(cli(capsys, "replay", run_dir, "--out", tmp_path), f"--out {tmp_path}: is a directory; give a file name")


@pytest.mark.parametrize("command", ["run", "sweep", "plot", "compare", "design", "tune"])
def test_3_out_that_is_a_file_is_refused_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], no_simulation: None, run_dir: Path, command: str
) -> None:
    existing = tmp_path / "EXISTING_FILE"
    existing.write_text("not a directory\n")
    argv = {
        "run": ["run", "hover", "--out", existing],
        "sweep": ["sweep", "hover", "--seeds", "1", "--out", existing],
        "plot": ["plot", run_dir, "--out", existing],
        "compare": ["compare", run_dir, "--out", existing],
        "design": ["design", "--plot", existing],
        "tune": ["tune", "hover", "--planner", "waypoints", "--param", "task.tolerance_m=0.01:0.1", "--out", existing],
    }[command]
    option = "--plot" if command == "design" else "--out"
    one_line(cli(capsys, *argv), f"{option} {existing}: exists and is not a directory")
    assert not (run_dir / "plots" / "x").exists()


@pytest.mark.parametrize("command", ["run", "sweep", "plot", "compare", "design"])
def test_3_unwritable_out_is_refused_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], no_simulation: None, run_dir: Path, command: str
) -> None:
    if os.geteuid() == 0:  # root writes anywhere: a directory under /proc cannot be created by anyone
        target = Path("/proc/pybullet-swarm-test/out")
    else:
        locked = tmp_path / "locked"
        locked.mkdir()
        locked.chmod(0o500)
        target = locked / "out"
    argv = {
        "run": ["run", "hover", "--out", target],
        "sweep": ["sweep", "hover", "--seeds", "1", "--out", target],
        "plot": ["plot", run_dir, "--out", target],
        "compare": ["compare", run_dir, "--out", target],
        "design": ["design", "--plot", target],
    }[command]
    option = "--plot" if command == "design" else "--out"
    one_line(cli(capsys, *argv), f"{option} {target}: cannot write there")


# ------------------------------------------- 4. scenario names and run directories
@pytest.mark.parametrize("name", ["/some/abs/path", "../../../x", "..", "a/../../b", "", "ok name"])
def test_4_run_directory_stays_inside_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    work = tmp_path / "deep" / "er" / "work"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    write(work / "named.yaml", {**TINY, "name": name})
    code, out, err = cli(capsys, "run", "named.yaml", "--quiet", "--no-plots")
    assert (code, err) == (0, ""), err
    runs = list((work / "runs").iterdir())
    assert len(runs) == 1 and runs[0].parent == work / "runs"
    assert not runs[0].name.startswith(".") and "/" not in runs[0].name
    assert (runs[0] / "metrics.json").is_file()
    outside = [p for p in tmp_path.rglob("*") if work not in p.parents and p != work and p not in work.parents]
    assert outside == [], outside


def test_4_a_control_character_in_the_name_is_refused_before_anything_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    write(tmp_path / "named.yaml", {**TINY, "name": "\x00"})
    one_line(cli(capsys, "run", "named.yaml", "--quiet", "--no-plots"), "named.yaml: name: ", "U+0000")
    assert not (tmp_path / "runs").exists()


def test_4_sweep_directory_name_is_sanitised(tmp_path: Path) -> None:
    from pybullet_swarm.experiment.sweep import Sweep, default_out

    path = write(tmp_path / "named.yaml", {**TINY, "name": "../../../etc/x"})
    out = default_out(Sweep(str(path), seeds=1), root=tmp_path / "runs")
    assert out.parent == tmp_path / "runs" and out.name.startswith("sweep-etc_x-")


def test_4_run_into_a_previous_run_directory_replaces_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], run_dir: Path
) -> None:
    again = tmp_path / "again"
    shutil.copytree(run_dir, again)
    (again / "plots" / "stale.png").write_bytes(b"old figure")
    (again / "video.gif").write_bytes(b"old video")
    code, _, err = cli(capsys, "run", write(tmp_path / "tiny.yaml", TINY), "--out", again, "--quiet", "--no-plots")
    assert (code, err) == (0, "")
    assert sorted(p.name for p in again.iterdir()) == [
        "events.csv",
        "metrics.json",
        "report.html",
        "scenario.yaml",
        "timeseries.npz",
    ]


def test_4_run_into_a_foreign_non_empty_directory_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], no_simulation: None
) -> None:
    folder = tmp_path / "notes"
    folder.mkdir()
    (folder / "thesis.tex").write_text("precious")
    one_line(
        cli(capsys, "run", "hover", "--out", folder),
        f"--out {folder}: is not empty and not a run directory",
        "thesis.tex",
    )
    assert (folder / "thesis.tex").read_text() == "precious"


# ------------------------------------------ 5. values that ended in exit 1
def _vehicle(tmp_path: Path, **changes: Any) -> Path:
    """A copy of quad150 (parameters and URDF) with ``changes`` to its parameter file."""
    shutil.copy(urdf_dir() / "quad150.urdf", tmp_path / "quad150.urdf")
    data = yaml.safe_load((urdf_dir() / "quad150.yaml").read_text())
    data.update(changes)
    return write(tmp_path / "veh.yaml", data)


@pytest.mark.parametrize(
    ("overrides", "parts"),
    [
        (
            ["task.boxes=[[0.25, 0.25, .nan]]"],
            ["construction.yaml: task.boxes[0][2]: must be a finite number, got nan"],
        ),
        (["task.structure=[[2.5, 0.5, .nan]]"], ["construction.yaml: task.structure[0][2]: must be a finite number"]),
        (["task.box_size=.inf"], ["construction.yaml: task.box_size: must be a finite number, got inf"]),
        (["sim.gravity=0"], ["construction.yaml: sim.gravity: must be >= 0.1 m/s^2 (the hover controller"]),
        (
            ["planner.name=stigmergy", "planner.params.cell_size=0.001"],
            ["construction.yaml: planner.params.cell_size: must be >= 0.01, got 0.001"],
        ),
        (
            ["planner.name=stigmergy", "planner.params.grid_height=1e6"],
            ["construction.yaml: planner.params.grid_height: must be <= 20.0, got 1000000.0"],
        ),
        (
            [
                "planner.name=layered_stigmergy",
                "arena.size=[100.0, 100.0]",
                "planner.params.cell_size=0.01",
                "planner.params.grid_height=20",
            ],
            [
                "construction.yaml: planner.params.cell_size: a pheromone grid of 10000 x 10000 x 2000 cells (2 layer(s), with "
                "its snapshots) would need about",
                "TiB, above the memory budget of 4 GiB (set PYBULLET_SWARM_MEMORY_BUDGET",
            ],
        ),
    ],
    ids=[
        "nan_box",
        "nan_slot",
        "inf_box_size",
        "zero_gravity",
        "stigmergy_cells",
        "stigmergy_height",
        "stigmergy_memory",
    ],
)
def test_5_construction_values_are_refused_at_check(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, overrides: list[str], parts: list[str]
) -> None:
    monkeypatch.delenv("PYBULLET_SWARM_MEMORY_BUDGET", raising=False)
    argv = ["check", "construction"] + [x for o in overrides for x in ("--set", o)]
    one_line(cli(capsys, *argv), *parts)


def test_5_run_with_planner_option_checks_its_budget(
    capsys: pytest.CaptureFixture[str], no_simulation: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("PYBULLET_SWARM_MEMORY_BUDGET", raising=False)
    one_line(
        cli(
            capsys,
            "run",
            "construction",
            "--planner",
            "stigmergy",
            "--set",
            "arena.size=[100.0, 100.0]",
            "--set",
            "planner.params.cell_size=0.01",
        ),
        "construction.yaml: planner.params.cell_size: a pheromone grid",
    )


def test_5_memory_budget_is_configurable(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PYBULLET_SWARM_MEMORY_BUDGET", "64M")
    # 300 x 100 x 100 cells (1 cm) need about 96 MiB: refused under 64 MiB, accepted under the default
    one_line(
        cli(
            capsys, "check", "construction", "--set", "planner.name=stigmergy", "--set", "planner.params.cell_size=0.01"
        ),
        "above the memory budget of 64 MiB",
    )
    monkeypatch.delenv("PYBULLET_SWARM_MEMORY_BUDGET")
    assert (
        cli(
            capsys,
            "check",
            "construction",
            "--quiet",
            "--set",
            "planner.name=stigmergy",
            "--set",
            "planner.params.cell_size=0.01",
        )[0]
        == 0
    )
    monkeypatch.setenv("PYBULLET_SWARM_MEMORY_BUDGET", "lots")
    one_line(cli(capsys, "check", "construction"), "PYBULLET_SWARM_MEMORY_BUDGET: must be a size such as 8192")


def test_5_aco_tour_iterations_and_tour_size(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("PYBULLET_SWARM_MEMORY_BUDGET", raising=False)
    one_line(
        cli(capsys, "check", "tour", "--set", "planner.params.iterations=1000000000"),
        "tour.yaml: planner.params.iterations: must be <= 100000, got 1000000000",
    )
    tour = yaml.safe_load((scenarios_dir() / "tour.yaml").read_text())
    g = np.arange(100) * 0.5 + 0.5
    tour["arena"]["size"] = [51.0, 51.0]
    tour["task"]["points"] = [[float(x), float(y), 1.0] for x in g for y in g]  # 10,000 points
    one_line(
        cli(capsys, "check", write(tmp_path / "big_tour.yaml", tour)),
        "big_tour.yaml: task.points: an ant colony on 10000 points",
        "GiB, above the memory budget",
    )


def test_5_vehicle_files_are_validated(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    one_line(
        cli(capsys, "check", "hover", "--set", f"agents.vehicle={_vehicle(tmp_path, mass=float('inf'))}"),
        "hover.yaml: agents.vehicle: veh.yaml: mass: must be a finite number, got inf",
    )
    one_line(
        cli(capsys, "check", "hover", "--set", f"agents.vehicle={_vehicle(tmp_path, kf=-1e-7)}"),
        "hover.yaml: agents.vehicle: veh.yaml: kf: must be > 0",
    )
    one_line(
        cli(capsys, "check", "hover", "--set", f"agents.vehicle={_vehicle(tmp_path, motor_time_constant=5.0)}"),
        "hover.yaml: agents.vehicle: veh.yaml: roll/pitch: no gains: not even w_n = ",
    )
    one_line(
        cli(capsys, "design", "--vehicle", _vehicle(tmp_path, motor_time_constant=5.0)),
        "veh.yaml: roll/pitch: no gains: not even w_n = ",
    )
    (tmp_path / "notes.txt").write_text("not a robot")
    one_line(
        cli(capsys, "check", "hover", "--set", f"agents.vehicle={_vehicle(tmp_path, urdf='notes.txt')}"),
        "hover.yaml: agents.vehicle: veh.yaml: urdf: notes.txt is not a usable URDF: not well-formed XML",
    )
    (tmp_path / "other.urdf").write_text("<model><link name='a'/></model>")
    one_line(
        cli(capsys, "check", "hover", "--set", f"agents.vehicle={_vehicle(tmp_path, urdf='other.urdf')}"),
        "veh.yaml: urdf: other.urdf is not a usable URDF: its root element must be <robot>, got <model>",
    )
    (tmp_path / "empty.urdf").write_text("<robot name='r'/>")
    one_line(
        cli(capsys, "check", "hover", "--set", f"agents.vehicle={_vehicle(tmp_path, urdf='empty.urdf')}"),
        "veh.yaml: urdf: empty.urdf is not a usable URDF: it has no <link>",
    )


def test_5_tsp_seed_and_size(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("PYBULLET_SWARM_MEMORY_BUDGET", raising=False)
    one_line(cli(capsys, "tsp", "eil51", "--seed", "-1"), "--seed: expected an integer in [0,")
    rng = np.random.default_rng(0)
    n = 30_000
    nodes = "\n".join(f"{i + 1} {x:.1f} {y:.1f}" for i, (x, y) in enumerate(rng.uniform(0, 1e5, (n, 2))))
    big = tmp_path / "big.tsp"
    big.write_text(
        f"NAME: big\nTYPE: TSP\nDIMENSION: {n}\nEDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n{nodes}\nEOF\n"
    )
    one_line(
        cli(capsys, "tsp", big, "--runs", "1"),
        "big: DIMENSION: an ant colony on 30000 nodes",
        "GiB, above the memory budget",
    )


def test_5_tune_objective_size_is_bounded(capsys: pytest.CaptureFixture[str], no_simulation: None) -> None:
    huge = " + ".join(["sim_time_s"] * 6000)
    one_line(
        cli(
            capsys,
            "tune",
            "hover",
            "--planner",
            "waypoints",
            "--param",
            "task.tolerance_m=0.01:0.1",
            "--objective",
            huge,
        ),
        "--objective: expression too long",
    )
    deep = " + ".join(["sim_time_s"] * 100)
    one_line(
        cli(
            capsys,
            "tune",
            "hover",
            "--planner",
            "waypoints",
            "--param",
            "task.tolerance_m=0.01:0.1",
            "--objective",
            deep,
        ),
        "--objective: expression too large",
    )


# ------------------------------------------------ 6. corrupt saved results
def _corrupt(path: Path, how: str) -> None:
    if how == "empty":
        path.write_bytes(b"")
    elif how == "truncated":  # a quarter is left: a scenario.yaml without its task, a zip without its directory
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 4])
    elif how == "garbage":
        path.write_text("hello: [world\n")
    else:
        path.write_bytes(bytes(range(256)) * 8)


@pytest.mark.parametrize("how", ["empty", "truncated", "garbage", "binary"])
@pytest.mark.parametrize("name", ["metrics.json", "timeseries.npz", "scenario.yaml", "events.csv"])
@pytest.mark.parametrize("command", ["plot", "replay", "report"])
def test_6_a_corrupt_run_file_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], run_dir: Path, command: str, name: str, how: str
) -> None:
    if name == "events.csv" and how != "binary" and command != "plot":
        pytest.skip("an event log with unreadable rows is drawn (its rows are skipped): tested with plot")
    broken = tmp_path / "broken"
    shutil.copytree(run_dir, broken)
    _corrupt(broken / name, how)
    argv = {
        "plot": ["plot", broken, "--out", tmp_path / "figs"],
        "replay": ["replay", broken, "--frame", "0.1", "--out", tmp_path / "frame.png", "--quiet"],
        "report": ["report", broken, "--quiet"],
    }[command]
    code, out, err = cli(capsys, *argv)
    if name == "events.csv" and how != "binary":
        assert (code, err) == (0, "")  # unreadable rows of the event log are skipped (documented)
        return
    one_line((code, out, err), f"{broken / name}: ")


def test_6_timeseries_with_inconsistent_arrays(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], run_dir: Path
) -> None:
    broken = tmp_path / "broken"
    shutil.copytree(run_dir, broken)
    with np.load(broken / "timeseries.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["positions"] = arrays["positions"][:, :, :2]
    np.savez(broken / "timeseries.npz", **arrays)
    one_line(cli(capsys, "plot", broken), "timeseries.npz: positions: corrupt: must have shape")


def _sweep_dir(tmp_path: Path, run_dir: Path) -> Path:
    """A sweep directory holding one row (from the run directory's metrics)."""
    from pybullet_swarm.experiment.results import RunsTable, metrics_row

    sweep = tmp_path / "sweep"
    sweep.mkdir()
    metrics = json.loads((run_dir / "metrics.json").read_text())
    RunsTable(sweep / "runs.csv").append(
        {
            "run_id": "r0",
            "planner": "waypoints",
            "avoidance": "none",
            "seed": 0,
            "exit_status": metrics["exit_status"],
            **metrics_row(metrics),
        }
    )
    return sweep


@pytest.mark.parametrize("command", ["plot", "compare", "report"])
def test_6_binary_runs_csv_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], run_dir: Path, command: str
) -> None:
    sweep = _sweep_dir(tmp_path, run_dir)
    out = [] if command == "report" else ["--out", tmp_path / "figs"]
    assert cli(capsys, command, sweep, *out)[0] == 0
    _corrupt(sweep / "runs.csv", "binary")
    one_line(cli(capsys, command, sweep, *out), f"{sweep / 'runs.csv'}: unreadable runs table")


@pytest.mark.parametrize("how", ["garbage", "binary"])
def test_6_report_refuses_a_corrupt_summary(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], run_dir: Path, how: str
) -> None:
    sweep = _sweep_dir(tmp_path, run_dir)
    _corrupt(sweep / "summary.csv", how)
    one_line(cli(capsys, "report", sweep, "--quiet"), f"{sweep / 'summary.csv'}: ")


def test_6_compare_refuses_a_corrupt_run(tmp_path: Path, capsys: pytest.CaptureFixture[str], run_dir: Path) -> None:
    broken = tmp_path / "broken"
    shutil.copytree(run_dir, broken)
    _corrupt(broken / "scenario.yaml", "binary")
    one_line(cli(capsys, "compare", run_dir, broken, "--out", tmp_path / "cmp"), f"{broken / 'scenario.yaml'}: ")


# -------------------------------------------------- 7. obstacles and ceiling
FLOCKING = yaml.safe_load((scenarios_dir() / "flocking.yaml").read_text())


def test_7_agent_inside_a_raised_obstacle_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = json.loads(json.dumps(FLOCKING))
    data["agents"]["count"] = 1
    data["agents"]["start"] = [[1.0, 1.0, 1.0]]
    data["agents"].pop("start_jitter", None)
    data["arena"]["obstacles"] = [{"shape": "box", "size": [0.4, 0.4, 0.4], "position": [1.0, 1.0, 1.0]}]
    one_line(
        cli(capsys, "check", write(tmp_path / "inside.yaml", data)),
        "inside.yaml: arena.obstacles[0]: agent 0 starts inside this obstacle",
    )
    data["agents"]["start"] = [[1.0, 1.0, 0.011]]  # under the raised box: allowed
    code, _, err = cli(capsys, "check", write(tmp_path / "under.yaml", data), "--quiet")
    assert (code, err) == (0, "")


def test_7_waypoint_above_the_ceiling_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    one_line(
        cli(capsys, "check", "hover", "--set", "arena.height=0.5"),
        "hover.yaml: task.waypoints[0].position: set-point above the ceiling (arena.height 0.5 m",
    )
    data = {**TINY, "arena": {"size": [2.0, 2.0], "height": 0.5}}
    data["task"] = {**TINY["task"], "relative": False, "waypoints": [{"t_s": 0, "position": [1.0, 1.0, 1.52]}]}
    one_line(
        cli(capsys, "check", write(tmp_path / "low.yaml", data)),
        "low.yaml: task.waypoints[0].position: set-point above the ceiling",
    )


# --------------------------------------------------------------- 8. smaller
def test_8_set_reads_numbers_as_a_person_writes_them(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = cli(capsys, "check", "hover", "--set", "limits.velocity=1e6", "--set", "limits.acceleration=5E-1")
    assert (code, err) == (0, "")
    limits = yaml.safe_load(out)["limits"]
    assert limits == {"velocity": 1e6, "acceleration": 0.5}


def test_8_no_warning_text_on_an_infinite_coordinate(capsys: pytest.CaptureFixture[str]) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for value in ("[.inf, 1.0]", "[1.0e+308, 1.0e+308]", "[-1e308, 0]"):
            one_line(cli(capsys, "check", "hover", "--set", f"agents.origin={value}"), "hover.yaml: agents.origin")
        one_line(cli(capsys, "check", "flocking", "--set", "arena.obstacles[0]=1"), "flocking.yaml: ")
    assert [str(w.message) for w in caught] == []


def test_8_gui_without_a_display(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, no_simulation: None
) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    one_line(cli(capsys, "run", "hover", "--gui"), "--gui: needs a display")


def test_8_errors_name_the_right_field(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    one_line(
        cli(capsys, "check", "hover", "--set", "agents.origin=[100.0, 1.0]"),
        "hover.yaml: agents.origin: layout centre (100, 1) is outside the arena",
    )
    one_line(cli(capsys, "design", "--physics-hz", "inf"), "--physics-hz: must be a rate in (0, 100000] Hz, got inf")
    one_line(cli(capsys, "design", "--control-hz", "nan"), "--control-hz: must be a rate")
    path = tmp_path / "tagged.yaml"
    path.write_text((scenarios_dir() / "hover.yaml").read_text().replace("count: 1", "count: !!int abc"))
    one_line(cli(capsys, "check", path), "tagged.yaml: agents.count: cannot read !!int 'abc'")


def test_8_compare_refuses_an_unknown_metric(tmp_path: Path, capsys: pytest.CaptureFixture[str], run_dir: Path) -> None:
    one_line(
        cli(capsys, "compare", run_dir, "--metrics", "foo", "--out", tmp_path / "c"), "--metrics: unknown metric 'foo'"
    )
    one_line(
        cli(capsys, "compare", run_dir, "--metrics", "sim_time", "--out", tmp_path / "c"),
        "--metrics: unknown metric 'sim_time'; did you mean sim_time_s",
    )
    assert cli(capsys, "compare", run_dir, "--metrics", "sim_time_s", "--out", tmp_path / "c")[0] == 0
