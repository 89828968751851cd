"""``pybullet-swarm tune``: bad input is one line with exit code 2; a tiny real study end to end."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from pybullet_swarm.cli.main import main

BASE = ["tune", "hover", "--planner", "waypoints"]


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--param", "limits.velocity=1:0.5"], "--param: limits.velocity: needs low < high, got 1.0:0.5"),
        (
            ["--param", "limits.velocity=0.2:1", "--objective", "__import__('os')"],
            "--objective: not allowed in an objective",
        ),
        (
            ["--param", "limits.velocity=0.2:1", "--objective", "tracking_rmse", "--trials", "1"],
            "--objective: unknown metric 'tracking_rmse' in 'tracking_rmse'; did you mean tracking_rmse_m",
        ),
        (["--param", "limits.velocity=0.2:1", "--objective", "a", "--objectives", "b,c"], "not allowed with argument"),
        (
            ["--param", "limits.velocity=0.2:1", "--objectives", "a,b", "--sampler", "cmaes"],
            "--sampler: CMA-ES optimises one objective",
        ),
        (["--param", "limits.velocity=0.2:1", "--trials", "0"], "--trials: must be an integer >= 1, got 0"),
        (["--param", "limits.velocity=0.2:1", "--address", "auto"], "--address: needs --executor ray"),
        ([], "--param: needs at least one --param key.path=low:high"),
    ],
)
def test_bad_tune_input_is_one_line_with_exit_code_2(
    argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*BASE, *argv, "--out", str(tmp_path / "t")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("pybullet-swarm: error: ") and message in err


def test_run_refuses_a_missing_override_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "hover", "-c", str(tmp_path / "best.yaml"), "--quiet"]) == 2
    assert "best.yaml: file not found" in capsys.readouterr().err


@pytest.mark.slow
def test_a_tiny_real_study_from_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "study"
    argv = [
        *BASE,
        "--param",
        "limits.velocity=0.3:0.9",
        "--objective",
        "sim_time_s + 10 * tracking_rmse_m",
        "--trials",
        "2",
        "--seeds-per-trial",
        "1",
        "--workers",
        "1",
        "--out",
        str(out),
        "--set",
        "task.time_limit_s=3",
        "--set",
        "task.relative=false",
        "--set",
        "task.hold_s=0.2",
        "--set",
        "task.waypoints=[{t_s: 0.0, position: [1.5, 1.5, 0.3]}]",
        "--set",
        "task.tolerance_m=0.1",
    ]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "best trial (minimize sim_time_s + 10 * tracking_rmse_m):" in text
    with open(out / "trials.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["state"] for r in rows] == ["complete", "complete"]
    assert (out / "best.yaml").is_file() and (out / "plots" / "history.png").is_file()
    assert main([*argv, "--trials", "3"]) == 0  # resumes: one more trial
    with open(out / "trials.csv", newline="") as fh:
        assert len(list(csv.DictReader(fh))) == 3
