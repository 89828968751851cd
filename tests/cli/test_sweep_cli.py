"""``pybullet-swarm sweep``, ``compare`` and ``plot SWEEP_DIR``: results, figures, errors, SIGKILL and resume."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pybullet_swarm.cli.main import main

PREFIX = "pybullet-swarm: error: "
#: hover shortened to ~1 s simulated, jittered start (see tests/experiment/test_sweep.py)
HOVER_ARGS = [
    "--set",
    "task.time_limit_s=3",
    "--set",
    "task.relative=false",
    "--set",
    "task.waypoints=[{t_s: 0, position: [1.5, 1.5, 0.3]}]",
    "--set",
    "task.hold_s=0.2",
    "--set",
    "task.tolerance_m=0.1",
    "--set",
    "agents.start_jitter=0.05",
]


def run_cli(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, str, str]:
    """``main(argv)`` in-process: exit code, stdout, stderr."""
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def rows(sweep_dir: Path) -> list[dict[str, str]]:
    """The rows of ``runs.csv`` as text."""
    with open(sweep_dir / "runs.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def test_sweep_then_plot_and_compare_read_the_results(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "sw"
    code, stdout, stderr = run_cli(
        capsys,
        [
            "sweep",
            "hover",
            "--seeds",
            "2",
            "--grid",
            "limits.velocity=0.5,1.0",
            *HOVER_ARGS,
            "--workers",
            "2",
            "--out",
            str(out),
            "--no-plots",
        ],
    )
    assert code == 0, stderr
    assert "95% CI of mean (t)" in stdout and "limits.velocity=1.0" in stdout
    assert f"sweep directory: {out} (4 runs: 4 run now, 0 skipped, 0 failed" in stdout
    assert "4/4" in stderr and "failed=0" in stderr  # the progress bar
    recorded = rows(out)
    assert len(recorded) == 4 and {r["exit_status"] for r in recorded} == {"completed"}
    assert (out / "summary.csv").is_file() and not (out / "plots").exists()
    assert f"report: {out / 'report.html'}" in stdout and (out / "report.html").is_file()

    # the same command again: nothing runs, it says so
    code, stdout, stderr = run_cli(
        capsys,
        [
            "sweep",
            "hover",
            "--seeds",
            "2",
            "--grid",
            "limits.velocity=0.5,1.0",
            *HOVER_ARGS,
            "--workers",
            "2",
            "--out",
            str(out),
            "--no-plots",
        ],
    )
    assert code == 0 and "sweep: 4 of 4 runs already finished, skipped" in stderr
    assert rows(out) == recorded

    # plot SWEEP_DIR: table and comparison figures from runs.csv alone
    code, stdout, _ = run_cli(capsys, ["plot", str(out), "--ci", "bootstrap", "--metrics", "path_length_m.total"])
    assert code == 0 and "95% CI of mean (bootstrap)" in stdout
    assert sorted(p.name for p in (out / "plots").iterdir()) == [
        "box_path_length_m.total.png",
        "time_vs_collisions.png",
    ]

    # plot RUN_DIR: every figure of one run, from its files
    run_dir = out / recorded[0]["run_dir"]
    code, stdout, _ = run_cli(capsys, ["plot", str(run_dir)])
    assert code == 0
    assert {Path(line).name for line in stdout.split()} >= {
        "position.png",
        "attitude.png",
        "rotor_speeds.png",
        "collision_timeline.png",
    }

    # compare RUN_DIR ...: runs grouped by configuration (the velocity limit differs)
    dirs = [str(out / r["run_dir"]) for r in recorded]
    code, stdout, _ = run_cli(capsys, ["compare", *dirs, "--out", str(tmp_path / "cmp"), "--metrics", "energy_j"])
    assert code == 0
    table = [line for line in stdout.splitlines() if line.startswith("energy_j")]
    assert len(table) == 2 and all("  2  " in line for line in table)
    assert (tmp_path / "cmp" / "box_energy_j.png").is_file()
    assert (tmp_path / "cmp" / "summary.csv").is_file() and (tmp_path / "cmp" / "time_vs_collisions.png").is_file()


def test_a_rule_only_the_task_layout_shows_is_refused_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "sw"
    # flying altitudes that do not rise from floor to depot to structure: only the task's layout shows it;
    # the planner's parameters are checked against the layout at load, before the sweep starts
    code, stdout, stderr = run_cli(
        capsys,
        [
            "sweep",
            "construction_single",
            "--planners",
            "stigmergy",
            "--seeds",
            "2",
            "--set",
            "planner.params.cruise_altitude=0.2",
            "--set",
            "task.time_limit_s=1",
            "--out",
            str(out),
            "--quiet",
            "--no-plots",
        ],
    )
    assert code == 2 and stdout == "" and stderr.count("\n") == 1
    assert stderr.startswith(PREFIX + "construction_single.yaml: planner.params.cruise_altitude: altitudes must rise")
    assert not (out / "runs.csv").exists()


def test_failed_runs_are_recorded_and_the_exit_code_says_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from pybullet_swarm.experiment.results import RunsTable

    out = tmp_path / "sw"
    argv = [
        "sweep",
        "construction_single",
        "--seeds",
        "2",
        "--set",
        "task.time_limit_s=0.5",
        "--out",
        str(out),
        "--quiet",
        "--no-plots",
    ]
    assert run_cli(capsys, argv)[0] == 0
    table = RunsTable(out / "runs.csv")  # as if both runs had raised (a bug): rows recorded as errors
    for r in table.rows:
        r.update(exit_status="error", error="RuntimeError: boom")
    table.save()
    code, stdout, stderr = run_cli(capsys, argv)  # resumed: nothing to run, the failures are reported
    assert code == 1 and stdout == ""
    assert stderr.strip().splitlines()[-1].startswith(PREFIX + "2 of 2 runs failed")
    assert [r["exit_status"] for r in rows(out)] == ["error", "error"]


def test_bad_planner_parameters_are_refused_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "sw"
    for extra, message in (
        (["--set", "planner.params.bogus=1"], "hover.yaml: planner.params.bogus: unknown field"),
        (
            ["--planners", "stigmergy", "--set", "planner.params.fatigue=-1"],
            "construction.yaml: planner.params.fatigue: must be >= 0",
        ),
        (
            ["--avoidance", "orca", "--set", "avoidance_params.time_horizon=abc"],
            "hover.yaml: avoidance_params.time_horizon: must be a valid number",
        ),
    ):
        scenario = "construction" if "stigmergy" in extra else "hover"
        code, stdout, stderr = run_cli(
            capsys, ["sweep", scenario, "--seeds", "1", *extra, "--out", str(out), "--quiet"]
        )
        assert code == 2 and stdout == "" and stderr.count("\n") == 1, stderr
        assert stderr.startswith(PREFIX + message), stderr
        assert not out.exists()


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["--seeds", "0"], "--seeds: must be >= 1"),
        (["--seeds", "2", "--grid", "limits.velocity"], "--grid: limits.velocity: expected key.path=v1,v2"),
        (["--seeds", "2", "--grid", "=1,2"], "--grid: expected key.path=value"),
        (
            ["--seeds", "2", "--grid", "agents.count=1,0"],
            "agents.count: must be >= 1, got 0 (grid point agents.count=0)",
        ),
        (["--seeds", "2", "--grid", "limits.velocity=0.5,0.5"], "--grid: limits.velocity: must not repeat a value"),
        (["--seeds", "2", "--planners", "waypoints,"], "expected comma-separated names"),
        (["--seeds", "2", "--planners", "nope"], "--planners: unknown planner 'nope'"),
        (["--seeds", "2", "--avoidance", "nope"], "--avoidance: unknown avoidance 'nope'"),
        (["--seeds", "2", "--address", "auto"], "--address: needs --executor ray"),
        (["--seeds", "2", "--executor", "dask"], "invalid choice: 'dask'"),
        (["--seeds", "2", "--workers", "0"], "--workers: must be >= 1"),
        (["--seeds", "2", "--set", "agents.count=-1"], "agents.count: must be >= 1"),
        (["--seeds", "two"], "invalid int value"),
    ],
)
def test_bad_sweep_input_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], expected: str
) -> None:
    code, stdout, stderr = run_cli(capsys, ["sweep", "hover", *argv, "--out", str(tmp_path / "sw")])
    assert code == 2 and stdout == ""
    assert stderr.startswith(PREFIX) and stderr.count("\n") == 1 and expected in stderr
    assert not (tmp_path / "sw" / "runs.csv").exists()


def test_plot_and_compare_refuse_what_is_not_a_result(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "empty").mkdir()
    for argv in (
        ["plot", str(tmp_path / "empty")],
        ["compare", str(tmp_path / "empty")],
        ["compare", str(tmp_path / "missing")],
    ):
        code, _, stderr = run_cli(capsys, argv)
        assert code == 2 and stderr.startswith(PREFIX) and stderr.count("\n") == 1


def test_a_sweep_killed_with_sigkill_resumes_without_losing_or_duplicating_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "sw"
    argv = [
        "sweep",
        "hover",
        "--seeds",
        "10",
        *HOVER_ARGS,
        "--set",
        "task.hold_s=1.5",
        "--workers",
        "1",
        "--out",
        str(out),
        "--no-plots",
    ]
    proc = subprocess.Popen(
        [sys.executable, "-m", "pybullet_swarm.cli.main", *argv, "--quiet"],
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            if (out / "runs.csv").is_file() and (out / "runs.csv").read_bytes().count(b"\n") >= 3:
                break  # header and two rows
            time.sleep(0.01)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the sweep, its forkserver and its worker: one session
        proc.wait()
    assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode() if proc.stderr else ""
    before = {r["run_id"]: r for r in rows(out)}
    assert 2 <= len(before) < 10

    code, _, stderr = run_cli(capsys, argv)
    assert code == 0, stderr
    skipped = int(stderr.split("sweep: ")[1].split(" of 10 runs already finished")[0])
    assert skipped >= len(before)  # recorded rows, plus any run finished but not yet recorded
    after = rows(out)
    assert len(after) == 10 and len({r["run_id"] for r in after}) == 10
    for r in after:
        if r["run_id"] in before:
            assert r == before[r["run_id"]]
