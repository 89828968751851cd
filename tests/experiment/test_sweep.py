"""Sweeps: rows and summary of a tiny sweep, resume, statistics against scipy, failures, Ray."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import stats

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.results import RunsTable, flatten_metrics, parse_cell
from pybullet_swarm.experiment.summary import CIMethod, describe, summarize
from pybullet_swarm.experiment.sweep import RunSpec, Sweep, execute_run, make_row, plan_sweep, run_sweep

#: hover, shortened to ~1 s simulated: climb to an absolute point 0.3 m above the start layout's
#: centre and hold it 0.2 s. The start is jittered per seed, so seeds give different paths.
HOVER: dict[str, Any] = {
    "task.time_limit_s": 3.0,
    "task.relative": False,
    "task.waypoints": [{"t_s": 0.0, "position": [1.5, 1.5, 0.3]}],
    "task.hold_s": 0.2,
    "task.tolerance_m": 0.1,
    "agents.start_jitter": 0.05,
}
#: construction_single with one box and one slot: ~30-50 s simulated, ~1 s of wall time.
ONE_BOX: dict[str, Any] = {
    "task.boxes": [[0.4, 0.5, 0.05]],
    "task.structure": [[2.7, 0.4, 0.05]],
    "task.time_limit_s": 80.0,
}


def hover_sweep(seeds: int = 2, **kw: Any) -> Sweep:
    """Two configurations (grid over the velocity limit) of the short hover."""
    return Sweep("hover", grid={"limits.velocity": [0.5, 1.0]}, seeds=seeds, overrides=HOVER, **kw)


def _csv_rows(path: Path) -> list[dict[str, Any]]:
    import csv

    with open(path, newline="") as fh:
        return [{k: parse_cell(v) for k, v in r.items()} for r in csv.DictReader(fh)]


# ----------------------------------------------------------------- tiny sweep
def test_tiny_sweep_two_planners_rows_and_summary(tmp_path: Path) -> None:
    from pybullet_swarm.planning.registry import planners

    if "stigmergy" not in planners():
        pytest.skip("the stigmergy planner is not registered")
    sweep = Sweep("construction_single", planners=("shortest_path", "stigmergy"), seeds=2, overrides=ONE_BOX)
    res = run_sweep(sweep, tmp_path / "sw", workers=2, figures=False)

    assert (res.n_planned, res.n_run, res.n_skipped, res.n_failed) == (4, 4, 0, 0)
    rows = _csv_rows(tmp_path / "sw" / "runs.csv")
    assert len(rows) == 4 and len({r["run_id"] for r in rows}) == 4
    assert sorted((r["planner"], r["seed"]) for r in rows) == [
        ("shortest_path", 0),
        ("shortest_path", 1),
        ("stigmergy", 0),
        ("stigmergy", 1),
    ]
    for r in rows:
        assert r["avoidance"] == "none" and r["error"] is None
        metrics = json.loads((tmp_path / "sw" / r["run_dir"] / "metrics.json").read_text())
        assert r["exit_status"] == metrics["exit_status"]
        assert r["collisions.agent_agent"] == metrics["collisions"]["agent_agent"]
        assert r["path_length_m.total"] == metrics["path_length_m"]["total"]
        assert r["worker_time_s"] > 0
    summary = _csv_rows(tmp_path / "sw" / "summary.csv")
    for planner in ("shortest_path", "stigmergy"):
        values = [r["sim_time_s"] for r in rows if r["planner"] == planner]
        (s,) = [s for s in summary if s["planner"] == planner and s["metric"] == "sim_time_s"]
        assert s["n"] == 2 and s["ci_method"] == "t"
        assert s["mean"] == pytest.approx(np.mean(values))
        assert s["median"] == pytest.approx(np.median(values))


def test_sweep_rows_match_run_directories_and_summary_matches_rows(tmp_path: Path) -> None:
    res = run_sweep(hover_sweep(), tmp_path / "sw", workers=1, figures=True)

    out = tmp_path / "sw"
    rows = _csv_rows(out / "runs.csv")
    assert res.n_run == 4 and len(rows) == 4
    header = list(rows[0])
    assert header[:5] == ["run_id", "planner", "avoidance", "seed", "limits.velocity"]
    assert header[5:9] == ["exit_status", "error", "worker_time_s", "run_dir"]
    assert {(r["limits.velocity"], r["seed"]) for r in rows} == {(0.5, 0), (0.5, 1), (1.0, 0), (1.0, 1)}
    for r in rows:
        run_dir = out / r["run_dir"]
        assert run_dir.name == r["run_id"]
        flat = flatten_metrics(json.loads((run_dir / "metrics.json").read_text()))
        for key in ("sim_time_s", "energy_j", "tracking_rmse_m", "path_length_m.total", "collisions.agent_ground"):
            assert r[key] == flat[key]
        assert (run_dir / "timeseries.npz").is_file() and not (run_dir / "plots").exists()
        assert r["completed"] == 1 and r["exit_status"] == "completed"
    # seeds move the start: the two runs of a configuration differ
    v05 = [r["path_length_m.total"] for r in rows if r["limits.velocity"] == 0.5]
    assert v05[0] != v05[1]

    summary = _csv_rows(out / "summary.csv")
    (s,) = [s for s in summary if s["limits.velocity"] == 0.5 and s["metric"] == "path_length_m.total"]
    low, high = stats.t.interval(0.95, 1, loc=np.mean(v05), scale=stats.sem(v05))
    assert (s["n"], s["n_runs"], s["n_error"]) == (2, 2, 0)
    assert s["mean"] == pytest.approx(np.mean(v05))
    assert s["std"] == pytest.approx(np.std(v05, ddof=1))
    assert (s["ci95_low"], s["ci95_high"]) == (pytest.approx(low), pytest.approx(high))
    assert s["config"] == "limits.velocity=0.5"
    assert {p.name for p in res.files} >= {"box_path_length_m.total.png", "time_vs_collisions.png"}
    try:
        import pyarrow.parquet as pq
    except ImportError:
        assert not (out / "runs.parquet").exists()
    else:
        table = pq.read_table(out / "runs.parquet")
        assert table.num_rows == 4 and table.schema.field("path_length_m.total").type == "double"


def test_run_ids_are_stable_and_name_what_determines_a_run(tmp_path: Path) -> None:
    a = plan_sweep(hover_sweep(), tmp_path)
    b = plan_sweep(
        Sweep("hover", planners=("waypoints",), grid={"limits.velocity": [0.5, 1.0]}, seeds=2, overrides=HOVER),
        tmp_path,
    )
    assert [r.run_id for r in a.runs] == [r.run_id for r in b.runs]  # default planner == named planner
    assert len({r.run_id for r in a.runs}) == 4
    assert [r.seed for r in a.runs] == [0, 0, 1, 1]  # seeds outermost
    c = plan_sweep(hover_sweep(seeds=3), tmp_path)
    assert {r.run_id for r in a.runs} < {r.run_id for r in c.runs}


def test_bad_sweeps_are_refused_before_anything_runs(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"agents\.count.*grid point agents\.count=0"):
        plan_sweep(Sweep("hover", grid={"agents.count": [1, 0]}, seeds=1), tmp_path)
    with pytest.raises(ConfigError, match="unknown planner"):
        plan_sweep(Sweep("hover", planners=("nope",), seeds=1), tmp_path)
    with pytest.raises(ConfigError, match="does not solve"):
        plan_sweep(Sweep("hover", planners=("shortest_path",), seeds=1), tmp_path)
    with pytest.raises(ConfigError, match="seed"):
        Sweep("hover", seeds=[0, 0])
    with pytest.raises(ConfigError, match="at least one"):
        Sweep("hover", grid={"limits.velocity": []})
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="not a sweep directory"):
        run_sweep(hover_sweep(), tmp_path / "other")
    assert not (tmp_path / "other" / "runs.csv").exists()


# --------------------------------------------------------------------- resume
def test_resume_runs_only_what_is_missing_and_duplicates_nothing(tmp_path: Path) -> None:
    out = tmp_path / "sw"
    first = run_sweep(hover_sweep(seeds=1), out, workers=1, figures=False)
    assert (first.n_run, first.n_skipped) == (2, 0)
    before = {r["run_id"]: r for r in _csv_rows(out / "runs.csv")}

    wider = run_sweep(hover_sweep(seeds=2), out, workers=1, figures=False)
    assert (wider.n_planned, wider.n_run, wider.n_skipped) == (4, 2, 2)
    rows = _csv_rows(out / "runs.csv")
    assert len(rows) == 4 and len({r["run_id"] for r in rows}) == 4
    for r in rows:  # the earlier rows are untouched
        if r["run_id"] in before:
            assert r == before[r["run_id"]]

    # killed between a run's metrics.json and its row: the last row never written, the one
    # before torn half-way. Both are recovered from their run directories, not run again.
    lines = (out / "runs.csv").read_text().splitlines(keepends=True)
    lost_id, torn_id = lines[-1].split(",")[0], lines[-2].split(",")[0]
    (out / "runs.csv").write_text("".join(lines[:-2]) + lines[-2][: len(lines[-2]) // 2])
    stamp = (out / "runs" / lost_id / "metrics.json").stat().st_mtime_ns

    again = run_sweep(hover_sweep(seeds=2), out, workers=1, figures=False)
    assert (again.n_run, again.n_recovered, again.n_skipped) == (0, 2, 4)
    after = {r["run_id"]: r for r in _csv_rows(out / "runs.csv")}
    assert len(after) == 4 and len(_csv_rows(out / "runs.csv")) == 4 and {lost_id, torn_id} <= set(after)
    assert (out / "runs" / lost_id / "metrics.json").stat().st_mtime_ns == stamp
    for run_id in (lost_id, torn_id):  # the recovered rows hold the same numbers
        assert after[run_id]["energy_j"] == {r["run_id"]: r for r in rows}[run_id]["energy_j"]


def test_runs_table_appends_whole_lines_and_widens_its_header(tmp_path: Path) -> None:
    t = RunsTable(tmp_path / "runs.csv")
    t.append({"run_id": "a", "seed": 0, "x": 1.5})
    t.append({"run_id": "b", "seed": 1, "x": 2.5})
    t.append({"run_id": "c", "seed": 2, "x": None, "y": "text, with comma"})  # new column: rewrite
    text = (tmp_path / "runs.csv").read_text()
    assert text.splitlines()[0] == "run_id,seed,x,y" and text.endswith("\n")
    back = RunsTable(tmp_path / "runs.csv")
    assert [r["run_id"] for r in back.rows] == ["a", "b", "c"]
    assert back.get("a") == {"run_id": "a", "seed": 0, "x": 1.5, "y": None}
    assert back.get("c")["y"] == "text, with comma"
    with open(tmp_path / "runs.csv", "a") as fh:  # a torn line is dropped on reading
        fh.write("d,3,4.")
    assert RunsTable(tmp_path / "runs.csv").ids() == {"a", "b", "c"}


def test_run_ids_that_look_like_numbers_read_back_as_written(tmp_path: Path) -> None:
    # hex run ids: "7600923850e0" parses as a float and "012345678901" as an int without its zero; a resumed
    # sweep that read them so would not recognise its finished runs and append them again
    ids = ["7600923850e0", "012345678901", "515030448e97"]
    t = RunsTable(tmp_path / "runs.csv")
    for k, run_id in enumerate(ids):
        t.append({"run_id": run_id, "seed": k, "run_dir": f"runs/{run_id}"})
    back = RunsTable(tmp_path / "runs.csv")
    assert back.ids() == set(ids)
    assert [r["run_id"] for r in back.rows] == ids and [r["run_dir"] for r in back.rows] == [f"runs/{i}" for i in ids]
    assert all(back.get(i) is not None for i in ids)


# ----------------------------------------------------------------- statistics
def test_statistics_against_known_numbers_and_scipy() -> None:
    x = [1.0, 2.0, 3.0, 4.0, 5.0]
    s = describe(x)
    # mean 3, s = sqrt(2.5), sem = s / sqrt(5), t_{0.975, 4} = 2.7764451
    assert (s.n, s.mean, s.median) == (5, 3.0, 3.0)
    assert s.std == pytest.approx(math.sqrt(2.5))
    assert s.ci95_low == pytest.approx(3.0 - 2.7764451 * math.sqrt(0.5), rel=1e-7)
    assert s.ci95_high == pytest.approx(3.0 + 2.7764451 * math.sqrt(0.5), rel=1e-7)
    assert (s.ci95_low, s.ci95_high) == pytest.approx(stats.t.interval(0.95, 4, loc=3.0, scale=stats.sem(x)))

    y = [0.3, 1.9, 2.2, 2.4, 3.8, 4.1, 7.5, 9.0]
    b = describe(y, ci=CIMethod.BOOTSTRAP, seed=0)
    ref = stats.bootstrap(
        (np.asarray(y),),
        np.mean,
        confidence_level=0.95,
        method="BCa",
        n_resamples=9999,
        vectorized=True,
        rng=np.random.default_rng(0),
    ).confidence_interval
    assert (b.ci95_low, b.ci95_high) == pytest.approx((ref.low, ref.high))
    assert b.ci95_low < np.mean(y) < b.ci95_high

    one = describe([4.0])
    assert one.n == 1 and one.mean == 4.0 and math.isnan(one.std) and math.isnan(one.ci95_low)
    same = describe([2.0, 2.0, 2.0])
    assert (same.std, same.ci95_low, same.ci95_high) == (0.0, 2.0, 2.0)
    assert describe([1.0, float("nan"), 3.0]).n == 2
    assert describe([]).n == 0


def test_summary_groups_configurations_and_leaves_errors_out() -> None:
    rows = [
        {"run_id": "1", "planner": "a", "avoidance": "none", "seed": 0, "exit_status": "completed", "t": 1.0},
        {"run_id": "2", "planner": "a", "avoidance": "none", "seed": 1, "exit_status": "timeout", "t": 3.0},
        {"run_id": "3", "planner": "a", "avoidance": "none", "seed": 2, "exit_status": "error", "t": None},
        {"run_id": "4", "planner": "b", "avoidance": "none", "seed": 0, "exit_status": "completed", "t": 10.0},
    ]
    out = {(s.config.label, s.metric): s for s in summarize(rows, ("planner", "avoidance"))}
    a = out[("a", "t")]
    assert (a.n_runs, a.n_error, a.stats.n, a.stats.mean) == (3, 1, 2, 2.0)
    assert out[("b", "t")].stats.n == 1 and math.isnan(out[("b", "t")].stats.std)
    assert a.config.values == (("planner", "a"), ("avoidance", "none"))


# ------------------------------------------------------------------- failures
def flaky_worker(spec: RunSpec) -> dict[str, Any]:
    """The real worker; seed 1 gives its planner a parameter it does not take, so its run is refused."""
    if spec.seed == 1:
        data = {**spec.scenario_data, "planner": {"name": None, "params": {"bogus": 1}}}
        spec = dataclasses.replace(spec, scenario_data=data)
    return execute_run(spec)


def dying_worker(spec: RunSpec) -> dict[str, Any]:
    """The real worker; seed 1 kills its worker process."""
    if spec.seed == 1:
        os._exit(3)
    return execute_run(spec)


def test_a_failing_run_is_recorded_and_the_sweep_continues(tmp_path: Path) -> None:
    out = tmp_path / "sw"
    res = run_sweep(hover_sweep(seeds=3), out, workers=1, worker=flaky_worker, figures=False)
    assert (res.n_run, res.n_failed) == (6, 2)
    rows = _csv_rows(out / "runs.csv")
    bad = [r for r in rows if r["exit_status"] == "error"]
    assert sorted(r["seed"] for r in bad) == [1, 1]
    assert all("hover.yaml: planner.params.bogus: unknown field" in r["error"] for r in bad)
    assert all(r["completion_time_s"] is None for r in bad)
    assert all((out / r["run_dir"] / "error.txt").is_file() for r in bad)
    assert sorted(r["seed"] for r in rows if r["exit_status"] == "completed") == [0, 0, 2, 2]
    s = [s for s in res.summary if s.metric == "sim_time_s"]
    assert [(x.n_runs, x.n_error, x.stats.n) for x in s] == [(3, 1, 2), (3, 1, 2)]

    # failed runs are skipped on resume unless asked, then run again with the real worker
    assert run_sweep(hover_sweep(seeds=3), out, figures=False, workers=1).n_run == 0
    retry = run_sweep(hover_sweep(seeds=3), out, figures=False, workers=1, retry_failed=True)
    assert (retry.n_run, retry.n_failed) == (2, 0)
    rows = _csv_rows(out / "runs.csv")
    assert len(rows) == 6 and all(r["exit_status"] == "completed" for r in rows)


def test_a_dead_worker_process_is_retried_then_recorded(tmp_path: Path) -> None:
    out = tmp_path / "sw"
    sweep = Sweep("hover", seeds=3, overrides=HOVER)
    res = run_sweep(sweep, out, workers=1, worker=dying_worker, retries=1, figures=False)
    rows = {r["seed"]: r for r in _csv_rows(out / "runs.csv")}
    assert (res.n_run, res.n_failed, len(rows)) == (3, 1, 3)
    assert rows[1]["exit_status"] == "error" and "worker lost 2 times" in rows[1]["error"]
    assert rows[0]["exit_status"] == rows[2]["exit_status"] == "completed"


def _design_label(key: tuple[Any, ...]) -> str:
    """A design's inputs as text (vehicle, rates, reference step, gravity), the same in every process."""
    return f"{key[0].name} {key[1]} {key[2]} {key[4]!r} {key[5]}"


def warm_state_worker(spec: RunSpec) -> dict[str, Any]:
    """What a worker process holds before it runs anything: designs handed over, kernels loaded."""
    import sys

    from pybullet_swarm.control import kernels
    from pybullet_swarm.control.design import known_designs
    from pybullet_swarm.planning.orca import kernel as orca_kernel

    return {
        **make_row(spec, {"exit_status": "completed"}),
        "designs": ";".join(sorted(_design_label(k) for k in known_designs())),
        "physics_kernel_loaded": bool(kernels.physics_tick.signatures),
        "orca_kernel_loaded": bool(orca_kernel.orca_batch.signatures),
        "warm": "pybullet_swarm.experiment.warm" in sys.modules,
    }


def test_local_workers_start_warm_with_the_sweeps_controller_designs(tmp_path: Path) -> None:
    from pybullet_swarm.control.design import known_designs

    # another gravity than the warm-up's: a controller no process designed before this sweep
    sweep = Sweep("hover", seeds=2, overrides={**HOVER, "sim.gravity": 9.75})
    res = run_sweep(sweep, tmp_path / "sw", workers=2, worker=warm_state_worker)
    planned = {_design_label(k) for k in known_designs()}  # planning designed the sweep's controller here
    assert planned and res.n_run == 2
    for r in res.rows:  # forked from the warmed forkserver: every kernel loaded, every design known
        assert planned <= set(r["designs"].split(";"))
        assert r["physics_kernel_loaded"] and r["orca_kernel_loaded"] and r["warm"]
    t = res.timings
    assert set(t) == {"plan_s", "runs_s", "busy_s", "finish_s", "total_s"}
    assert 0.0 < t["plan_s"] < t["total_s"] and t["runs_s"] < t["total_s"]


# ------------------------------------------------------------------------ Ray
@pytest.mark.ray
def test_ray_executor_runs_the_tiny_sweep(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    out = tmp_path / "sw"
    res = run_sweep(hover_sweep(), out, executor="ray", workers=2, figures=False)
    assert (res.n_run, res.n_failed) == (4, 0)
    rows = _csv_rows(out / "runs.csv")
    assert len({r["run_id"] for r in rows}) == 4 and all(r["exit_status"] == "completed" for r in rows)
    for r in rows:  # each row holds its own run's metrics
        metrics = json.loads((out / r["run_dir"] / "metrics.json").read_text())
        assert r["path_length_m.total"] == metrics["path_length_m"]["total"]
    assert [s.stats.n for s in res.summary if s.metric == "sim_time_s"] == [2, 2]
