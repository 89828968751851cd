"""Benchmarks: dry-run lines, JSON keys, table and figure of a tiny suite, resume after a kill, paired compare, ablation."""

from __future__ import annotations

import copy
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from pybullet_swarm.cli.main import main
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment import ablation, benchmark
from pybullet_swarm.experiment.jobs import RunSpec, make_row
from pybullet_swarm.experiment.results import RUNS_CSV, RunsTable

ROOT = Path(__file__).resolve().parents[2]

#: one agent, one box, a tower of one slot; 3 s simulated: each run times out in about a second of wall time
TINY: dict[str, Any] = {
    "suite": "tiny",
    "version": 1,
    "planners": ["shortest_path"],
    "avoidance": ["none"],
    "set": {"task.time_limit_s": 3.0},
    "splits": {
        "dev": {
            "seeds": {"start": 0, "count": 2},
            "layouts": [{"name": "t1", "structure": {"shape": "tower", "origin": [1.6, 0.5], "height": 1},
                         "agents": 1, "arena": [2.0, 1.0]}],
        },
        "holdout": {
            "seeds": [1000, 1001],
            "layouts": [{"name": "g1", "generator_seed": 1000, "shape": "tower", "agents": 1},
                        {"name": "g2", "generator_seed": 1001, "shape": "wall", "agents": 2, "depots": 2}],
        },
    },
}  # fmt: skip


def tiny_suite(tmp_path: Path, **changes: Any) -> Path:
    data = copy.deepcopy(TINY)
    data.update(changes)
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_dry_run_prints_one_tab_separated_line_per_run(tmp_path, capsys):
    suite = tiny_suite(tmp_path, planners=["shortest_path", "stigmergy"], avoidance=["none", "orca"])
    assert main(["benchmark", str(suite), "--split", "holdout", "--dry-run", "--quiet"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2 * 2 * 2 * 2  # layouts x planners x avoidance x seeds
    cells = [line.split("\t") for line in lines]
    assert all(len(c) == 4 for c in cells)
    assert {c[0] for c in cells} == {"g1", "g2"} and {c[1] for c in cells} == {"shortest_path", "stigmergy"}
    assert {c[2] for c in cells} == {"none", "orca"} and {int(c[3]) for c in cells} == {1000, 1001}
    assert not (tmp_path / "runs").exists()  # nothing written


def test_the_bundled_suite_plans_both_splits(capsys):
    assert main(["benchmark", "construction", "--split", "holdout", "--dry-run", "--quiet"]) == 0
    holdout = [line.split("\t") for line in capsys.readouterr().out.splitlines()]
    assert len({c[0] for c in holdout}) >= 20 and min(int(c[3]) for c in holdout) >= 1000
    assert main(["benchmark", "construction", "--split", "dev", "--dry-run", "--quiet"]) == 0
    dev = [line.split("\t") for line in capsys.readouterr().out.splitlines()]
    assert {int(c[3]) for c in dev} == set(range(50)) and "thesis" in {c[0] for c in dev}


def test_a_study_narrows_planners_widens_seeds_and_sets_overrides(tmp_path, capsys):
    suite = tiny_suite(tmp_path, planners=["shortest_path", "stigmergy"])
    argv = ["benchmark", str(suite), "--split", "holdout", "--dry-run", "--quiet", "--planners", "stigmergy"]
    assert main([*argv, "--seeds", "3"]) == 0
    cells = [line.split("\t") for line in capsys.readouterr().out.splitlines()]
    assert {c[1] for c in cells} == {"stigmergy"} and sorted({int(c[3]) for c in cells}) == [1000, 1001, 1002]
    variant = benchmark.Variant(planners=("stigmergy",), overrides=(("task.time_limit_s", 2.0),))
    plan = benchmark.plan_benchmark(suite, "holdout", tmp_path / "b", build=False, variant=variant)
    assert {s.scenario_data["task"]["time_limit_s"] for s in plan.runs} == {2.0}
    plain = benchmark.plan_benchmark(suite, "holdout", tmp_path / "b", build=False)
    assert not {s.run_id for s in plan.runs} & {s.run_id for s in plain.runs}  # other scenarios, other runs
    assert main([*argv, "--planners", "reynolds"]) == 2
    assert "--planners: not in the holdout split: reynolds" in capsys.readouterr().err


def test_a_directory_holds_one_set_of_overrides(tmp_path):
    out, suite = tmp_path / "bench", tiny_suite(tmp_path)
    benchmark.run_benchmark(suite, "dev", out, workers=1, figure=False)
    other = benchmark.Variant(overrides=(("task.time_limit_s", 2.0),))
    with pytest.raises(ConfigError, match="other overrides"):
        benchmark.run_benchmark(suite, "dev", out, workers=1, figure=False, variant=other)
    data = benchmark.run_benchmark(suite, "dev", tmp_path / "b2", workers=1, figure=False, variant=other).data
    assert data["variant"]["set"] == {"task.time_limit_s": 2.0}


def test_studies_of_one_planner_each_add_up_in_one_directory(tmp_path):
    suite, out = tiny_suite(tmp_path, planners=["shortest_path", "stigmergy"]), tmp_path / "bench"
    for planner in ("stigmergy", "shortest_path"):
        variant = benchmark.Variant(planners=(planner,))
        res = benchmark.run_benchmark(
            suite, "dev", out, workers=1, figure=False, worker=failing_worker, variant=variant
        )
    data = json.loads((out / benchmark.RESULT).read_text())
    assert res.n_planned == 2 and data["planned_runs"] == data["recorded_runs"] == 4
    assert [c["planner"] for c in data["configurations"]] == ["shortest_path", "stigmergy"]  # the suite's order
    assert all(c["planned"] == c["error"] == 2 for c in data["configurations"])
    assert data["variant"] == {} and data["seeds"] == [0, 1]  # the two calls together are the split
    assert len(json.loads((out / benchmark.PLAN).read_text())["runs"]) == 4
    wider = benchmark.Variant(planners=("stigmergy",), seeds=3)
    data = benchmark.run_benchmark(
        suite, "dev", out, workers=1, figure=False, worker=failing_worker, variant=wider
    ).data
    assert [c["planned"] for c in data["configurations"]] == [2, 3] and data["seeds"] == [0, 1, 2]
    assert data["variant"] == {"planners": [], "seeds": 3, "set": {}}


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["benchmark", "construction"], "--split: is required"),
        (["benchmark", "construction", "--split", "test"], "invalid choice"),
        (["benchmark", "compare", "a.json"], "two benchmark JSON files"),
        (["benchmark", "no_such_suite", "--split", "dev", "--dry-run"], "no suite file"),
    ],
)
def test_bad_benchmark_commands_fail_in_one_line(capsys, argv, words):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0]


def test_a_tiny_benchmark_writes_json_table_and_figure_and_resumes(tmp_path):
    out = tmp_path / "bench"
    res = benchmark.run_benchmark(tiny_suite(tmp_path), "dev", out, workers=1, command="test")
    assert res.n_planned == 2 and res.n_run == 2 and not res.interrupted
    data = json.loads((out / "benchmark.json").read_text())
    for key in ("commit", "suite", "suite_version", "split", "configurations", "runs", "contact_classes"):
        assert key in data
    assert data["suite"] == "tiny" and data["suite_version"] == 1 and data["split"] == "dev"
    (config,) = data["configurations"]
    for key in (
        "runs",
        "completed",
        "crashed",
        "stalled",
        "median_time_s",
        "median_time_ci",
        "contact_runs",
        "incidents",
    ):
        assert key in config
    assert config["runs"] == 2 and config["timeout"] == 2 and config["completed"] == 0
    assert "agent_agent" in config["contact_runs"]
    assert {(r["layout"], r["seed"]) for r in data["runs"]} == {("t1", 0), ("t1", 1)}
    assert all(r["cpu_time_s"] > 0 and r["wall_time_s"] > 0 for r in data["runs"])
    assert data["cpu_time_s"] == pytest.approx(sum(r["cpu_time_s"] for r in data["runs"]), abs=0.1)
    table = (out / "benchmark.md").read_text()
    assert "| shortest_path | 0/2 | 0 | 0 | 2 | - |" in table
    assert (out / "benchmark.png").stat().st_size > 1000
    again = benchmark.run_benchmark(tiny_suite(tmp_path), "dev", out, workers=1, figure=False)
    assert again.n_run == 0 and again.n_skipped == 2


def failing_worker(spec: RunSpec) -> dict[str, Any]:
    """A worker whose every run fails to run (recorded with exit_status = error)."""
    return make_row(spec, None, error="ConfigError: no such vehicle field")


def test_failed_runs_are_kept_on_resume_and_run_again_when_asked(tmp_path, capsys):
    suite, out = tiny_suite(tmp_path), tmp_path / "bench"
    first = benchmark.run_benchmark(suite, "dev", out, workers=1, worker=failing_worker, figure=False)
    assert first.data["configurations"][0]["error"] == 2
    assert benchmark.run_benchmark(suite, "dev", out, workers=1, figure=False).n_run == 0
    argv = ["benchmark", str(suite), "--split", "dev", "--workers", "1", "--out", str(out), "--no-figure"]
    assert main([*argv, "--quiet"]) == 1  # failed runs make the command fail, saying how to retry them
    assert "--retry-failed" in capsys.readouterr().err
    assert main([*argv, "--quiet", "--retry-failed"]) == 0
    data = json.loads((out / benchmark.RESULT).read_text())
    assert data["configurations"][0]["error"] == 0 and data["configurations"][0]["timeout"] == 2


def test_a_layout_whose_scenario_is_missing_is_refused_naming_the_suite_and_layout(tmp_path):
    dev = {"seeds": [0], "layouts": [{"name": "mine", "scenario": "no_such.yaml"}]}
    suite = tiny_suite(tmp_path, splits={**TINY["splits"], "dev": dev})
    with pytest.raises(ConfigError) as err:
        benchmark.plan_benchmark(suite, "dev", build=False)
    assert str(err.value).startswith("tiny.yaml: layout mine.scenario: ") and "\n" not in str(err.value)


def test_a_directory_of_another_split_is_refused(tmp_path):
    out = tmp_path / "bench"
    out.mkdir()
    (out / benchmark.PLAN).write_text(json.dumps({"suite": "tiny", "version": 1, "split": "holdout", "runs": {}}))
    with pytest.raises(ConfigError, match="another suite, version or split"):
        benchmark.run_benchmark(tiny_suite(tmp_path), "dev", out, workers=1)


def test_a_killed_benchmark_resumes_without_losing_or_repeating_runs(tmp_path):
    suite = tiny_suite(tmp_path, splits={**TINY["splits"], "dev": {**TINY["splits"]["dev"], "seeds": {"count": 4}}})
    out = tmp_path / "bench"
    cmd = [sys.executable, "-m", "pybullet_swarm.cli.main", "benchmark", str(suite), "--split", "dev",
           "--workers", "1", "--out", str(out), "--quiet", "--no-figure"]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.Popen(cmd, env=env, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 600
        while time.monotonic() < deadline and proc.poll() is None:
            if (out / RUNS_CSV).is_file() and len(RunsTable(out / RUNS_CSV).rows) >= 1:
                break
            time.sleep(0.2)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    before = {r["run_id"] for r in RunsTable(out / RUNS_CSV).rows}
    assert before and not (out / benchmark.RESULT).exists() or proc.returncode == 0
    res = benchmark.run_benchmark(suite, "dev", out, workers=1, figure=False)
    rows = RunsTable(out / RUNS_CSV).rows
    ids = [r["run_id"] for r in rows]
    assert len(ids) == len(set(ids)) == res.n_planned == 4  # nothing lost, nothing twice
    assert res.n_skipped >= len(before) and res.n_run == res.n_planned - res.n_skipped
    assert res.data["recorded_runs"] == 4


# ------------------------------------------------------------------ compare
def _run(layout: str, seed: int, status: str, t: float | None, aa: int = 0) -> dict[str, Any]:
    return {"layout": layout, "planner": "stigmergy", "avoidance": "orca", "seed": seed, "exit_status": status,
            "completion_time_s": t, "contacts": {"agent_agent": aa, "agent_structure": 0}, "incidents": None,
            "wall_time_s": 1.0}  # fmt: skip


def _bench(runs: list[dict[str, Any]], commit: str) -> dict[str, Any]:
    return {"suite": "s", "suite_version": 1, "split": "holdout", "commit": commit, "date": "2026-01-01",
            "contact_classes": ["agent_agent", "agent_structure"], "configurations": [], "runs": runs}  # fmt: skip


def test_compare_finds_a_known_paired_difference():
    a = _bench([_run(f"L{i % 5}", i, "completed", 100.0 + i % 7) for i in range(60)], "aaa")
    # B: every third run stalls, and the completed ones are 20 s slower, with one contact in every other run
    b = _bench(
        [_run(f"L{i % 5}", i, "stalled" if i % 3 == 0 else "completed", None if i % 3 == 0 else 120.0 + i % 7, aa=i % 2)
         for i in range(60)],
        "bbb",
    )  # fmt: skip
    (c,) = benchmark.compare(a, b)["configurations"]
    m = c["metrics"]
    assert c["pairs"] == 60
    assert m["completion_rate"]["diff"] == pytest.approx(-1 / 3, abs=1e-3)
    assert m["completion_rate"]["ci"][1] < 0 and m["completion_rate"]["significant"]
    assert m["stall_rate"]["ci"][0] > 0 and m["contact_rate_agent_agent"]["ci"][0] > 0
    assert m["median_time_s"]["diff"] == pytest.approx(20.0) and m["median_time_s"]["ci"][0] > 0
    assert m["contact_rate_agent_structure"]["diff"] == 0.0 and not m["contact_rate_agent_structure"]["significant"]


def test_compare_of_two_equivalent_benchmarks_includes_zero():
    runs = [_run(f"L{i % 4}", i, "completed" if i % 4 else "stalled", 100.0 + (i * 37) % 11, aa=int(i % 5 == 0))
            for i in range(40)]  # fmt: skip
    shuffled = [dict(r, completion_time_s=None if r["completion_time_s"] is None else r["completion_time_s"]
                     + (1.0 if r["seed"] % 2 else -1.0)) for r in runs]  # fmt: skip
    (c,) = benchmark.compare(_bench(runs, "a"), _bench(shuffled, "b"))["configurations"]
    for name, m in c["metrics"].items():
        assert m["ci"] is None or m["ci"][0] <= 0.0 <= m["ci"][1], name
        assert not m["significant"], name


def test_compare_cli_pairs_two_files(tmp_path, capsys):
    a = _bench([_run("L", i, "completed", 100.0) for i in range(10)], "aaa")
    b = _bench([_run("L", i, "completed", 90.0) for i in range(12)], "bbb")
    b["variant"] = {"planners": ["stigmergy"], "seeds": 12, "set": {"sim.reference_leash": 0.03}}
    (tmp_path / "a.json").write_text(json.dumps(a))
    (tmp_path / "b.json").write_text(json.dumps(b))
    out = tmp_path / "cmp.json"
    argv = ["benchmark", "compare", str(tmp_path / "a.json"), str(tmp_path / "b.json"), "--out", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "10 paired runs (0 of A and 2 of B unpaired)" in text and "| median_time_s | 100 | 90 | -10 |" in text
    assert text.startswith("B (bbb, sim.reference_leash=0.03) - A (aaa), ")  # a study's overrides are named
    assert json.loads(out.read_text())["configurations"][0]["metrics"]["median_time_s"]["diff"] == -10.0
    (tmp_path / "bad.json").write_text(json.dumps({"suite": "s"}))
    assert main(["benchmark", "compare", str(tmp_path / "a.json"), str(tmp_path / "bad.json")]) == 2
    assert "bad.json: suite_version: is required" in capsys.readouterr().err


# ------------------------------------------------------------------ the table
def _config(**kw: Any) -> dict[str, Any]:
    base = {"planner": "stigmergy", "avoidance": "orca", "runs": 10, "completed": 9, "crashed": 0, "stalled": 1,
            "timeout": 0, "median_time_s": 101.25, "median_time_ci": [98.0, 104.5],
            "contact_runs": {"agent_agent": 1, "agent_structure": 0, "agent_box": 0, "load_box": 2},
            "incidents": None}  # fmt: skip
    return {**base, **kw}


def test_markdown_table_renders_every_configuration():
    data = {"suite": "construction", "suite_version": 1, "split": "holdout", "commit": "abc", "date": "2026-01-01",
            "planned_runs": 20, "recorded_runs": 20,
            "contact_classes": ["agent_agent", "agent_structure", "agent_box", "load_box"],
            "configurations": [_config(), _config(planner="shortest_path", avoidance="none",
                                                  incidents={"runs_reporting": 10, "runs_with": 2, "total": 3})]}  # fmt: skip
    text = benchmark.markdown_table(data)
    assert "runs with a-a contact" in text and "runs with load-box contact" in text
    assert "a-b contact" not in text  # a class no run touched is left out
    assert "| stigmergy + orca | 9/10 | 0 | 1 | 0 | 101.2 [98.0, 104.5] | 1 | 0 | 2 | - |" in text
    assert "| shortest_path | 9/10 | 0 | 1 | 0 | 101.2 [98.0, 104.5] | 1 | 0 | 2 | 2 (3) |" in text
    assert "split `holdout`, commit `abc`" in text


@pytest.mark.parametrize(
    ("row", "expected"),
    [({}, None), ({"incidents": 3}, 3.0), ({"incidents.total": 2, "incidents.x": 9}, 2.0),
     ({"incidents.agent": 1, "incidents.load": 2}, 3.0), ({"incidents": ""}, None)],
)  # fmt: skip
def test_incidents_of_a_run_are_unknown_when_not_reported(row, expected):
    assert benchmark.run_incidents(row) == expected


def test_median_ci_is_deterministic_and_brackets_the_median():
    values = [100.0, 104.0, 98.0, 120.0, 101.0, 99.0, 103.0]
    ci = benchmark.bootstrap_ci(values)
    assert ci == benchmark.bootstrap_ci(values) and ci[0] <= 101.0 <= ci[1]
    assert benchmark.bootstrap_ci([5.0]) is None


@pytest.mark.ray
def test_ray_executor_runs_a_tiny_benchmark(tmp_path):
    pytest.importorskip("ray")
    res = benchmark.run_benchmark(
        tiny_suite(tmp_path), "dev", tmp_path / "bench", executor="ray", workers=1, figure=False
    )
    assert res.n_run == 2 and res.data["configurations"][0]["timeout"] == 2


# ------------------------------------------------------------------ ablation


def _paired(worse_completion: bool) -> dict[str, Any]:
    """A baseline that completes every run against a configuration that stalls every third one, or not at all."""
    a = _bench([_run(f"L{i % 5}", i, "completed", 100.0 + i % 7) for i in range(60)], "aaa")
    b = _bench(
        [_run(f"L{i % 5}", i, "stalled" if worse_completion and i % 3 == 0 else "completed", 100.0 + i % 7)
         for i in range(60)],
        "bbb",
    )  # fmt: skip
    return benchmark.compare(a, b)


def test_a_configuration_pays_only_when_switching_it_off_is_significantly_worse():
    worse = _paired(worse_completion=True)["configurations"][0]["metrics"]
    same = _paired(worse_completion=False)["configurations"][0]["metrics"]
    assert ablation.verdict(worse) == "pays (completion, stalls)"
    assert ablation.verdict(same) == "does not pay"
    # a significant improvement when switched off is not a reason to keep the rule: it is what the rule costs
    better = benchmark.compare(
        _bench([_run(f"L{i % 5}", i, "completed", 120.0 + i % 7) for i in range(60)], "a"),
        _bench([_run(f"L{i % 5}", i, "completed", 100.0 + i % 7) for i in range(60)], "b"),
    )["configurations"][0]["metrics"]
    assert better["median_time_s"]["significant"]
    assert ablation.verdict(better) == "does not pay; better off: median time [s]"


def test_a_configuration_also_pays_on_the_runs_with_a_contact_of_one_class():
    flat = {"diff": 0.0, "significant": False}
    metrics = {
        "completion_rate": flat,
        "contact_rate_any": {"diff": 0.1, "significant": False},
        "contact_rate_load_structure": {"diff": 0.12, "significant": True},
        "contact_rate_agent_box": {"diff": -0.1, "significant": True},  # fewer: no reason to keep
    }
    assert ablation.verdict(metrics) == "pays (load-structure contact); better off: agent-box contact"
    metrics["contact_rate_load_structure"] = {"diff": 0.12, "significant": False}
    assert ablation.verdict(metrics) == "does not pay; better off: agent-box contact"
    metrics["contact_rate_agent_box"] = flat
    assert ablation.verdict(metrics) == "does not pay"


def test_the_table_has_one_row_per_configuration_with_its_rules_and_verdict():
    cfgs = [
        ablation.switched_off("rule: claims", "stigmergy", "planner.params", ["claims"]),
        ablation.switched_off("rules: a, b", "stigmergy", "avoidance_params", ["headway", "lag_margin"]),
    ]
    results = {"rule: claims": _paired(True), "rules: a, b": _paired(False)}
    data = ablation.results_table(results, cfgs, title="T", command="cmd", notes=["n"])
    assert data["columns"][:3] == ["configuration", "rules off", "pairs"] and data["columns"][-1] == "verdict"
    (r1, r2) = data["rows"]
    assert r1[:3] == ["rule: claims", "claims", 60] and r1[-1].startswith("pays")
    assert r2[1] == "headway, lag_margin" and r2[-1] == "does not pay"
    assert r1[3].startswith("1 -> 0.667 [") and r1[3].endswith("*")
    assert data["commit"] == "bbb" and "n" in data["notes"]


def test_slugs_are_file_names_that_keep_configurations_apart():
    a = ablation.switched_off("rule: claims", "stigmergy", "planner.params", ["claims"])
    b = ablation.switched_off("rule: claims", "layered_stigmergy", "planner.params", ["claims"])
    c = ablation.switched_off("rules: wake_lanes, wake_clear (shortest_path)", "shortest_path", "planner.params", [])
    assert a.slug == "stigmergy-claims" and b.slug != a.slug
    assert c.slug == "shortest_path-wake_lanes+wake_clear"


def test_an_ablation_runs_each_configuration_and_pairs_it_with_the_given_baseline(tmp_path):
    suite = tiny_suite(tmp_path)
    base = benchmark.run_benchmark(suite, "dev", tmp_path / "base", workers=1, figure=False).data
    cfg = ablation.switched_off("rule: retry_slots", "shortest_path", "planner.params", ["retry_slots"])
    out = tmp_path / "abl"
    results = ablation.run_ablation([cfg], out, suite=str(suite), split="dev", workers=1, baseline=base)
    (conf,) = results["rule: retry_slots"]["configurations"]
    assert conf["pairs"] == 2 and conf["planner"] == "shortest_path"
    recorded = benchmark.read_benchmark(out / f"abl-{cfg.slug}" / "benchmark.json")
    assert recorded["variant"]["set"] == {"planner.params.retry_slots": False}
    # resumable: a second call runs nothing and gives the same comparison
    again = ablation.run_ablation([cfg], out, suite=str(suite), split="dev", workers=1, baseline=base)
    assert again["rule: retry_slots"]["configurations"] == results["rule: retry_slots"]["configurations"]


def test_common_overrides_reach_the_run_baseline_and_every_configuration(tmp_path):
    suite = tiny_suite(tmp_path)
    cfg = ablation.switched_off("rule: retry_slots", "shortest_path", "planner.params", ["retry_slots"])
    common = (("planner.params.arrive_tol", 0.02),)
    out = tmp_path / "abl"
    results = ablation.run_ablation(
        [cfg], out, suite=str(suite), split="dev", workers=1, baseline_seeds={"shortest_path": 1}, common=common
    )
    base = benchmark.read_benchmark(out / "base" / "benchmark.json")
    row = benchmark.read_benchmark(out / f"abl-{cfg.slug}" / "benchmark.json")
    assert base["variant"]["set"] == {"planner.params.arrive_tol": 0.02} and base["variant"]["seeds"] == 1
    assert row["variant"]["set"] == {"planner.params.arrive_tol": 0.02, "planner.params.retry_slots": False}
    assert results["rule: retry_slots"]["configurations"][0]["pairs"] == 1  # paired on the runs both have


@pytest.mark.parametrize("name", ["rule: x", "stage: a, b"])
def test_rules_column_names_the_last_key_component(name):
    cfg = ablation.Ablation(name, "stigmergy", (("avoidance_params.wake_column", False),))
    assert cfg.rules == "wake_column"


def test_report_prints_one_line_per_row_and_writes_the_table(tmp_path, capsys):
    cfg = ablation.switched_off("rule: claims", "stigmergy", "planner.params", ["claims"])
    data = ablation.results_table({"rule: claims": _paired(True)}, [cfg], title="T", command="cmd")
    path = tmp_path / "t.json"
    ablation.report(data, path)
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("rule: claims | claims | 60 |") and out[-1] == str(path)
    assert json.loads(path.read_text()) == data
