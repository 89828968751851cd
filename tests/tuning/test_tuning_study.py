"""Studies: a stand-in quadratic objective, Pareto fronts, resume after a kill, refusals, best.yaml."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import optuna
import pytest
import yaml
from pydantic import Field

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.results import RunsTable
from pybullet_swarm.experiment.sweep import RunSpec, make_row
from pybullet_swarm.tuning import TuneSpec, run_tuning
from pybullet_swarm.tuning.outputs import read_overrides_file
from pybullet_swarm.planning.params import Params as PlannerParams
from pybullet_swarm.planning.registry import register_planner
from pybullet_swarm.planning.waypoints import WaypointFollower
from pybullet_swarm.tuning.study import default_storage, open_storage

XY = ["planner.params.x=-1:1", "planner.params.y=-1:1"]
OPTIMUM = (0.3, -0.2)
QUADRATIC = "test_tuning_quadratic"
"""A stand-in planner whose parameters are x and y in [-1, 1] (it flies the task's set-points; the
stand-in worker below scores x and y without simulating)."""


class _QuadraticParams(PlannerParams):
    x: float = Field(0.0, ge=-1.0, le=1.0, description="stand-in parameter")
    y: float = Field(0.0, ge=-1.0, le=1.0, description="stand-in parameter")


register_planner(
    QUADRATIC,
    WaypointFollower,
    "test only: the waypoint follower with two stand-in parameters",
    ("waypoints",),
    params=_QuadraticParams,
)


def quadratic_worker(spec: RunSpec) -> dict[str, Any]:
    """Stand-in for a simulation: metrics of a quadratic bowl in the planner's (x, y), minimum 0 at OPTIMUM.

    ``loss`` grows by 0.001 per seed, so a trial's mean depends on the seeds it ran.
    """
    p = spec.scenario_data["planner"]["params"]
    x, y = float(p["x"]), float(p["y"])
    loss = (x - OPTIMUM[0]) ** 2 + (y - OPTIMUM[1]) ** 2 + 0.001 * spec.seed
    return make_row(
        spec, {"exit_status": "completed", "sim_time_s": 1.0, "completion_time_s": 1.0, "x": x, "y": y, "loss": loss}
    )


def _trials_csv(out: Path) -> list[dict[str, str]]:
    with open(out / "trials.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _tune(out: Path, **kw: Any) -> Any:
    spec_kw = {
        "params": XY,
        "objectives": ["loss"],
        "trials": 6,
        "seeds_per_trial": 2,
        "sampler": "tpe",
        "planner": QUADRATIC,
    }
    spec_kw.update({k: v for k, v in kw.items() if k not in ("figures",)})
    spec = TuneSpec("hover", **spec_kw)
    return run_tuning(spec, out, workers=1, worker=quadratic_worker, figures=kw.get("figures", False))


@pytest.mark.slow
def test_a_tiny_study_on_a_quadratic_finds_the_optimum_region(tmp_path: Path) -> None:
    out = tmp_path / "quad"
    res = _tune(out, trials=30, figures=True)
    best = res.best[0]
    assert abs(best["planner.params.x"] - OPTIMUM[0]) < 0.15
    assert abs(best["planner.params.y"] - OPTIMUM[1]) < 0.15
    # the trial's value is the mean over its two seeds of the closed-form loss
    dx, dy = best["planner.params.x"] - OPTIMUM[0], best["planner.params.y"] - OPTIMUM[1]
    assert best["value"] == pytest.approx(dx * dx + dy * dy + 0.0005)
    rows = _trials_csv(out)
    assert len(rows) == 30 and all(r["state"] == "complete" for r in rows)
    assert {r["seeds"] for r in rows} == {"[0,1]"}  # every trial ran the same seeds: paired
    values = [float(r["value"]) for r in rows]
    assert min(values[20:]) < sorted(values[:10])[2]  # the sampler's later trials beat most start-up ones
    assert len(RunsTable(out / "runs.csv")) == 60
    over = dict(read_overrides_file(out / "best.yaml"))
    assert over["planner.params.x"] == pytest.approx(best["planner.params.x"])
    assert over["planner.name"] == QUADRATIC and over["avoidance"] == "none"
    for name in ("history.png", "importance.png"):
        assert (out / "plots" / name).stat().st_size > 5000
    summary = json.loads((out / "study.json").read_text())
    assert set(summary["importances"]["loss"]) == {"planner.params.x", "planner.params.y"}


def test_multi_objective_study_returns_the_non_dominated_trials(tmp_path: Path) -> None:
    out = tmp_path / "mo"
    res = _tune(out, objectives="(x - 0.3)**2 + y**2,(x + 0.3)**2 + y**2", sampler="nsga2", trials=16, figures=True)
    rows = [r for r in _trials_csv(out) if r["state"] == "complete"]
    pts = {int(r["trial"]): (float(r["value_0"]), float(r["value_1"])) for r in rows}
    dominated = {
        n for n, (a, b) in pts.items() if any(a2 <= a and b2 <= b and (a2, b2) != (a, b) for a2, b2 in pts.values())
    }
    front = {int(r["trial"]) for r in rows if r["pareto"] == "true"}
    assert front and front == set(pts) - dominated
    assert [r["trial"] for r in res.best] == sorted(front, key=lambda n: pts[n][0])
    for n in front:
        assert (out / "pareto" / f"trial-{n}.yaml").is_file()
    assert (out / "plots" / "pareto.png").stat().st_size > 5000


def test_cmaes_runs_single_objective_studies_only(tmp_path: Path) -> None:
    res = _tune(tmp_path / "cma", sampler="cmaes", trials=5)
    assert sum(t["state"] == "complete" for t in res.trials) == 5
    with pytest.raises(ConfigError, match="--sampler: CMA-ES optimises one objective"):
        TuneSpec("hover", params=XY, objectives="x,y", sampler="cmaes")


def test_resume_adds_trials_to_the_same_study_and_reruns_nothing(tmp_path: Path) -> None:
    out = tmp_path / "resume"
    first = _tune(out, trials=4)
    again = _tune(out, trials=4)
    assert again.n_run == 0 and len(again.trials) == 4
    more = _tune(out, trials=7)
    assert more.n_run == 3
    assert [(t["trial"], t["value"], t["planner.params.x"]) for t in more.trials[:4]] == [
        (t["trial"], t["value"], t["planner.params.x"]) for t in first.trials
    ]
    assert len(RunsTable(out / "runs.csv")) == 7 * 2  # one row per run: nothing ran twice


def test_a_trial_left_running_by_a_killed_tuner_is_queued_again(tmp_path: Path) -> None:
    out = tmp_path / "killed"
    _tune(out, trials=2)
    # a tuner killed mid-trial leaves a RUNNING trial in the storage
    study = optuna.load_study(study_name=f"hover-{QUADRATIC}-none", storage=open_storage(default_storage(out)))
    dists = {
        "planner.params.x": optuna.distributions.FloatDistribution(-1, 1),
        "planner.params.y": optuna.distributions.FloatDistribution(-1, 1),
    }
    orphan = study.ask(dists)
    res = _tune(out, trials=4)
    by_number = {t["trial"]: t for t in res.trials}
    assert by_number[orphan.number]["state"] == "fail"
    retry = [t for t in res.trials if t["retry_of"] == orphan.number]
    assert len(retry) == 1 and retry[0]["state"] == "complete"
    assert retry[0]["planner.params.x"] == orphan.params["planner.params.x"]
    assert sum(t["state"] == "complete" for t in res.trials) == 4


def test_a_study_resumed_with_other_settings_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "other"
    _tune(out, trials=1)
    with pytest.raises(ConfigError, match=rf"--study: study 'hover-{QUADRATIC}-none' .* \(penalty differ\)"):
        _tune(out, trials=2, penalty=10.0)
    _tune(out, trials=2, penalty=10.0, study_name="second")  # another study in the same storage is fine


def test_bad_input_is_refused_before_anything_runs(tmp_path: Path) -> None:
    out = tmp_path / "bad"
    with pytest.raises(ConfigError) as err:
        _tune(out, objectives=["lossy + 1"])
    assert str(err.value) == "--objective: unknown metric 'lossy' in 'lossy + 1'; did you mean loss?"
    assert not (out / "study.db").exists()
    with pytest.raises(
        ConfigError,
        match=r"^--param: limits\.velocity: the range -1:1 leaves the parameter's range "
        r"\[0\.001, 1e\+06\]$",
    ):
        run_tuning(TuneSpec("hover", params=["limits.velocity=-1:1"], objectives=["sim_time_s"]), out)
    with pytest.raises(ConfigError, match="--storage: cannot open 'nosuchdb://x'"):
        run_tuning(
            TuneSpec("hover", params=XY, objectives=["loss"], planner=QUADRATIC),
            out,
            storage="nosuchdb://x",
            worker=quadratic_worker,
        )


def _never(spec: RunSpec) -> dict[str, Any]:
    raise AssertionError("nothing may run")


@pytest.mark.parametrize(
    "scenario, planner, avoidance, param, message",
    [
        (
            "hover",
            QUADRATIC,
            None,
            "planner.params.x=-2:1",
            "planner.params.x: the range -2:1 leaves the parameter's range [-1, 1]",
        ),
        (
            "construction",
            "stigmergy",
            None,
            "planner.params.fatigue=-1:1",
            "planner.params.fatigue: the range -1:1 leaves the parameter's range [0, 1000]",
        ),
        (
            "construction",
            "stigmergy",
            None,
            "planner.params.cell_size=0.001:0.1:log",
            "planner.params.cell_size: the range 0.001:0.1 leaves the parameter's range [0.01, 1]",
        ),
        (
            "construction",
            "stigmergy",
            None,
            "planner.params.ties=0:1",
            "planner.params.ties: is not a number (random | nearest | first) and cannot be tuned",
        ),
        ("construction", "stigmergy", None, "planner.params.nosuch=0:1", "planner.params.nosuch: names no field"),
        (
            "hover",
            None,
            "orca",
            "avoidance_params.max_neighbours=2:8",
            "avoidance_params.max_neighbours: is an integer: give its range with :int",
        ),
        (
            "hover",
            None,
            "orca",
            "avoidance_params.max_neighbours=0:8:int",
            "the range 0:8 leaves the parameter's range [1, 100]",
        ),
        (
            "hover",
            None,
            None,
            "sim.planner_hz=1:20000:int",
            "sim.planner_hz: the range 1:20000 leaves the parameter's range [1, 10000]",
        ),
        # within the model's ranges, but a rule between fields refuses one end (formation: on_threshold 0.55)
        (
            "formation",
            None,
            None,
            "avoidance_params.off_threshold=0.1:0.9",
            "the high end of the ranges is refused (avoidance_params.off_threshold=0.9): formation.yaml: "
            "avoidance_params.off_threshold: must be <= on_threshold (0.55), got 0.9",
        ),
    ],
)
def test_ranges_are_read_from_the_models_and_refused_before_anything_runs(
    tmp_path: Path, scenario: str, planner: str | None, avoidance: str | None, param: str, message: str
) -> None:
    spec = TuneSpec(scenario, params=[param], objectives=["sim_time_s"], planner=planner, avoidance=avoidance)
    with pytest.raises(ConfigError) as err:
        run_tuning(spec, tmp_path / "t", worker=_never, probe=_never)
    assert str(err.value).startswith("--param: ") and message in str(err.value) and "\n" not in str(err.value)
    assert not (tmp_path / "t" / "study.db").exists()


def test_field_info_gives_the_models_types_and_ranges() -> None:
    from pybullet_swarm.experiment.scenario import field_info, load_scenario

    sc = load_scenario("construction", planner="stigmergy", avoidance="orca")
    cell = field_info(sc, "planner.params.cell_size")
    assert (cell.type, cell.default, cell.low, cell.low_open, cell.high, cell.integer) == (
        "float",
        0.1,
        0.01,
        False,
        1.0,
        False,
    )
    k = field_info(sc, "avoidance_params.max_neighbours")
    assert (k.integer, k.low, k.high, k.default) == (True, 1.0, 100.0, 10)
    v = field_info(sc, "limits.velocity")
    assert v.numeric and (v.low, v.low_open, v.high) == (1e-3, False, 1e6)
    assert field_info(sc, "task.time_limit_s").range_text() == "(0, 100000]"
    assert not field_info(sc, "planner.params.ties").numeric
    assert field_info(sc, "sim") is None and field_info(sc, "planner.params.nosuch") is None


#: hover shortened to ~1 s simulated (as in the sweep tests).
HOVER = [
    "task.time_limit_s=3.0",
    "task.relative=false",
    "task.waypoints=[{t_s: 0.0, position: [1.5, 1.5, 0.3]}]",
    "task.hold_s=0.2",
    "task.tolerance_m=0.1",
    "agents.start_jitter=0.05",
]


@pytest.mark.slow
def test_best_yaml_applied_to_run_reproduces_the_trials_metrics(tmp_path: Path) -> None:
    from pybullet_swarm.cli.main import main

    out = tmp_path / "real"
    spec = TuneSpec(
        "hover",
        params=["limits.velocity=0.2:0.8", "limits.acceleration=0.5:1.4:log"],
        objectives=["tracking_rmse_m + 0.1 * sim_time_s"],
        trials=2,
        seeds_per_trial=1,
        seed_start=3,
        overrides=HOVER,
    )
    res = run_tuning(spec, out, workers=1)
    best = res.best[0]
    text = (out / "best.yaml").read_text()
    assert "apply: pybullet-swarm run hover -c best.yaml --seed 3" in text
    assert yaml.safe_load(text)["limits.velocity"] == pytest.approx(best["limits.velocity"])
    row = next(
        r for r in RunsTable(out / "runs.csv").rows if r["limits.velocity"] == pytest.approx(best["limits.velocity"])
    )
    run_dir = tmp_path / "again"
    assert (
        main(
            [
                "run",
                "hover",
                "-c",
                str(out / "best.yaml"),
                "--seed",
                "3",
                "--out",
                str(run_dir),
                "--no-plots",
                "--quiet",
            ]
        )
        == 0
    )
    metrics = json.loads((run_dir / "metrics.json").read_text())
    for key in ("sim_time_s", "tracking_rmse_m", "energy_j", "max_tilt_deg"):
        assert metrics[key] == row[key], key
    assert metrics["tracking_rmse_m"] + 0.1 * metrics["sim_time_s"] == pytest.approx(best["value"])


def test_a_second_study_in_the_same_directory_rescores_recorded_runs_without_running_them(tmp_path: Path) -> None:
    out = tmp_path / "shared"
    first = _tune(out, trials=4)
    seen = [{k: t[k] for k in ("planner.params.x", "planner.params.y")} for t in first.trials]
    second = run_tuning(
        TuneSpec(
            "hover",
            params=XY,
            objectives="x,y",
            trials=4,
            seeds_per_trial=2,
            sampler="nsga2",
            planner=QUADRATIC,
            study_name="xy",
            enqueue=seen,
        ),
        out,
        workers=1,
        worker=quadratic_worker,
        figures=True,
        outputs=tmp_path / "xy",
    )
    assert len(RunsTable(out / "runs.csv")) == 4 * 2  # every run came from runs.csv
    assert [(t["value_0"], t["value_1"]) for t in second.trials] == [
        (s["planner.params.x"], s["planner.params.y"]) for s in seen
    ]
    assert (tmp_path / "xy" / "trials.csv").is_file() and (tmp_path / "xy" / "plots" / "pareto.png").is_file()
    assert len(_trials_csv(out)) == 4  # the first study's table is untouched
    with pytest.raises(ConfigError, match="enqueue: needs a value for exactly the tuned keys"):
        TuneSpec("hover", params=XY, enqueue=[{"planner.params.x": 0.0}])


@pytest.mark.ray
@pytest.mark.slow
def test_trials_run_on_the_ray_executor(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    spec = TuneSpec(
        "hover",
        params=["limits.velocity=0.2:0.8"],
        objectives=["tracking_rmse_m"],
        trials=2,
        seeds_per_trial=2,
        overrides=HOVER,
    )
    res = run_tuning(spec, tmp_path / "ray", executor="ray", workers=2, figures=False)
    assert [t["state"] for t in res.trials] == ["complete", "complete"]
    rows = RunsTable(tmp_path / "ray" / "runs.csv").rows
    assert len(rows) == 4 and all(r["exit_status"] == "completed" for r in rows)
    for t in res.trials:  # a trial's value is the mean of its two runs' metric
        mine = [r["tracking_rmse_m"] for r in rows if r["limits.velocity"] == t["limits.velocity"]]
        assert t["value"] == pytest.approx(sum(mine) / 2)


def slow_quadratic_worker(spec: RunSpec) -> dict[str, Any]:
    """``quadratic_worker`` taking 0.2 s, so that a tuner can be killed in the middle of a trial."""
    import time

    time.sleep(0.2)
    return quadratic_worker(spec)


KILLED_TUNER = """
import sys
sys.path.insert(0, {here!r})
from test_tuning_study import QUADRATIC, XY, slow_quadratic_worker
from pybullet_swarm.tuning import TuneSpec, run_tuning
if __name__ == "__main__":
    run_tuning(TuneSpec("hover", params=XY, objectives=["loss"], trials=40, seeds_per_trial=2, planner=QUADRATIC),
               {out!r},
               workers=1, worker=slow_quadratic_worker, figures=False)
"""


@pytest.mark.slow
def test_a_tuner_killed_with_sigkill_resumes_without_losing_finished_trials(tmp_path: Path) -> None:
    import os
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "sigkill"
    script = tmp_path / "tuner.py"
    script.write_text(KILLED_TUNER.format(here=str(Path(__file__).parent), out=str(out)))
    stderr = tmp_path / "tuner.stderr"
    # The watcher only reads (a read-only SQLite URI): it must not take part in creating the storage.
    watch = f"sqlite:///file:{out / 'study.db'}?mode=ro&uri=true"
    with open(stderr, "w") as err:
        proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.DEVNULL, stderr=err)
    try:
        finished: list[Any] = []
        for _ in range(1200):  # poll (at most ~10 min on a loaded machine) until 3 trials are finished
            time.sleep(0.5)
            if proc.poll() is not None:
                break
            if (out / "study.db").is_file():
                try:
                    study = optuna.load_study(study_name=f"hover-{QUADRATIC}-none", storage=watch)
                    finished = [t for t in study.trials if t.state.name == "COMPLETE"]
                except Exception:  # noqa: BLE001 - the tuner has not created the study yet
                    continue
                if len(finished) >= 3:
                    break
        assert proc.poll() is None and len(finished) >= 3, f"tuner exited {proc.poll()}: {stderr.read_text()}"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    before = {t.number: t.value for t in finished}
    res = _tune(out, trials=len(before) + 3)
    after = {t["trial"]: t for t in res.trials}
    assert all(after[n]["value"] == v for n, v in before.items())  # nothing finished is lost
    assert sum(t["state"] == "complete" for t in res.trials) == len(before) + 3
    assert all(t["state"] in ("complete", "fail") for t in res.trials)  # nothing is left running
    assert all(t["error"] is None for t in res.trials)


def test_a_new_sqlite_storage_appears_with_its_schema_complete(tmp_path: Path, monkeypatch: Any) -> None:
    """study.db is published only once Optuna's tables are in it, so that a process opening it
    meanwhile (a watcher, a dashboard) never runs Optuna's table creation against the tuner's
    (the cause of "table studies already exists" in a tuner started beside a watcher)."""
    import sqlite3

    db = tmp_path / "study.db"
    real = optuna.storages.RDBStorage
    published_while_built: list[bool] = []

    def spy(url: str, *args: Any, **kw: Any) -> Any:
        storage = real(url, *args, **kw)
        published_while_built.append(db.exists())
        return storage

    monkeypatch.setattr(optuna.storages, "RDBStorage", spy)
    open_storage(default_storage(tmp_path))
    assert published_while_built[0] is False  # the schema was built before study.db existed
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as con:
        tables = {r[0] for r in con.execute("select name from sqlite_master where type = 'table'")}
    assert {"studies", "trials", "version_info", "alembic_version"} <= tables
    assert [p.name for p in tmp_path.iterdir()] == ["study.db"]  # no temporary file left behind
    open_storage(default_storage(tmp_path))  # an existing file is opened as it is
    assert published_while_built[-1] is True


def test_two_directories_share_one_study_through_a_storage_url(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'team.db'}"  # stands in for postgresql://... shared by several machines
    spec = dict(params=XY, objectives=["loss"], seeds_per_trial=2, study_name="team", planner=QUADRATIC)
    a = run_tuning(
        TuneSpec("hover", trials=3, **spec),
        tmp_path / "a",
        storage=url,
        workers=1,
        worker=quadratic_worker,
        figures=False,
    )
    b = run_tuning(
        TuneSpec("hover", trials=5, **spec),
        tmp_path / "b",
        storage=url,
        workers=1,
        worker=quadratic_worker,
        figures=False,
    )
    assert (a.n_run, b.n_run) == (3, 2) and b.storage == url
    assert [t["value"] for t in b.trials[:3]] == [t["value"] for t in a.trials]
    assert len(RunsTable(tmp_path / "b" / "runs.csv")) == 2 * 2  # machine b ran only its own trials
    assert not (tmp_path / "b" / "study.db").exists()
