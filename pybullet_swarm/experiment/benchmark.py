"""Benchmarks: every layout x planner x avoidance layer x seed of a suite's split, run and summarised as JSON.

``run_benchmark(suite, "holdout", out)`` plans the runs of a split (``experiment.suites``), runs
those not recorded yet on the sweep machinery (``sweep.execute_runs``: a local process pool or
Ray; rows appended to ``OUT/runs.csv`` as runs finish, so a killed benchmark resumes where it
stopped), and writes, from the rows of every run the directory holds (this call's and those of earlier
calls into it, such as one study per planner; the rows of nothing else in ``runs.csv``):

* ``OUT/benchmark.json``: commit, suite name, version and file digest, split, and per
  configuration (planner + avoidance): runs, completed, crashed, stalled, timed out, failed to
  run, the median completion time with a bootstrap 95 % interval, runs with a contact per class,
  incidents (null where the runs' ``metrics.json`` do not report them), per layout the same
  counts, and every run's outcome (``runs``: what ``compare`` pairs);
* ``OUT/benchmark.md``: ``markdown_table`` of that JSON;
* ``OUT/benchmark.png``: ``plotting.benchmark_plots.benchmark_figure`` of that JSON.

``compare(a, b)`` pairs the runs of two such JSON files by layout, planner, avoidance and seed
and gives, per configuration, B - A of the completion rate, of the runs with a contact (per
class and any), of the stalls and of the median completion time, each with a paired bootstrap
95 % interval (pairs resampled together).

The acceptance rule (``docs/guides/benchmark.md``): a rule, switch or default lands only if on
``holdout`` it improves a primary metric with an interval that excludes zero and worsens none
beyond its interval.
"""

from __future__ import annotations

import copy
import dataclasses
import datetime
import json
import math
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.jobs import RunSpec
from pybullet_swarm.experiment.results import RUNS_CSV, Row, RunsTable, config_hash
from pybullet_swarm.experiment.suites import Split, Suite, load_suite

FORMAT = 1
PLAN = "benchmark-plan.json"
RESULT = "benchmark.json"
TABLE = "benchmark.md"
FIGURE = "benchmark.png"
BOOTSTRAP = 2000
"""Resamples of every bootstrap interval."""
BOOTSTRAP_SEED = 20240229
"""Seed of the bootstrap's generator: the same rows give the same intervals."""
CRASHED = ("crashed", "diverged")
CONTACT_PREFIX = "collisions."
PRIMARY_CONTACTS = ("agent_agent", "agent_structure")
"""Contact classes the table always shows (the acceptance rule's)."""
#: short column names of contact classes in the Markdown table
SHORT = {
    "agent_agent": "a-a",
    "agent_structure": "a-s",
    "agent_box": "a-b",
    "agent_ground": "a-g",
    "agent_obstacle": "a-o",
    "load_load": "load-load",
    "load_box": "load-box",
    "load_structure": "load-s",
    "load_ground": "load-g",
    "load_wall": "load-w",
    "load_obstacle": "load-o",
}


# ------------------------------------------------------------------ planning
@dataclasses.dataclass(frozen=True)
class Variant:
    """A study on a split that is not the split itself: a subset of its planners, more or fewer of its seeds,
    scenario overrides on top of the suite's (an ablation: ``avoidance_params.wake_column=false``).

    Attributes:
        planners: run only these of the split's planners (empty: all).
        seeds: run this many seeds from the split's first seed on (None: the split's seeds).
        overrides: ``key.path -> value`` applied after the suite's ``set``.
    """

    planners: tuple[str, ...] = ()
    seeds: int | None = None
    overrides: tuple[tuple[str, Any], ...] = ()

    @property
    def empty(self) -> bool:
        """The split as the suite defines it."""
        return not self.planners and self.seeds is None and not self.overrides

    def record(self) -> dict[str, Any]:
        """The variant as the manifest and the JSON record it (``{}`` for the split itself)."""
        if self.empty:
            return {}
        return {"planners": list(self.planners), "seeds": self.seeds, "set": dict(self.overrides)}


@dataclasses.dataclass(frozen=True)
class BenchmarkPlan:
    """A split resolved into runs.

    Attributes:
        suite: the suite.
        split: the split (with a variant's planners and seeds).
        out: the benchmark directory (absolute).
        runs: every run, seeds outermost (a partial benchmark has every configuration at similar n).
        variant: what the study changes of the split (empty: nothing).
    """

    suite: Suite
    split: Split
    out: Path
    runs: tuple[RunSpec, ...]
    variant: Variant = Variant()

    def lines(self) -> list[str]:
        """One tab-separated line per run: layout, planner, avoidance, seed."""
        return [f"{layout_of(s)}\t{s.planner}\t{s.avoidance}\t{s.seed}" for s in self.runs]


def layout_of(spec: RunSpec) -> str:
    """The layout name of a benchmark run (its one grid cell)."""
    return str(dict(spec.grid).get("layout", ""))


def default_out(suite: Suite, split: str, root: Path = Path("runs")) -> Path:
    """``runs/benchmark-<suite>-v<version>-<split>``."""
    return root / f"benchmark-{suite.name}-v{suite.version}-{split}"


def plan_benchmark(
    suite: Suite | str | Path,
    split: str,
    out: str | Path | None = None,
    *,
    build: bool = True,
    variant: Variant = Variant(),
) -> BenchmarkPlan:
    """Resolve every configuration of a split and list its runs.

    Each layout x planner x avoidance layer is the layout's scenario with the choices and the
    suite's overrides applied (then the variant's), validated (``build_scenario``; with ``build``,
    also built once without stepping, as a run starts). What a run would refuse is refused here,
    in one line naming the suite file and the layout.
    """
    from pybullet_swarm.experiment.runner import build_run
    from pybullet_swarm.experiment.scenario import apply_choices, apply_overrides, build_scenario
    from pybullet_swarm.planning.registry import avoidance_layers, planners

    suite = suite if isinstance(suite, Suite) else load_suite(suite)
    sp = _varied(suite.split(split), variant)
    out = Path(out if out is not None else default_out(suite, split)).resolve()
    known, layers = planners(), avoidance_layers()
    for p in sp.planners:
        if p not in known:
            raise ConfigError(
                f"unknown planner {p!r}; available: {', '.join(known)}", source=suite.path.name, field="planners"
            )
    for a in sp.avoidance:
        if a not in layers:
            raise ConfigError(
                f"unknown avoidance {a!r}; available: {', '.join(layers)}", source=suite.path.name, field="avoidance"
            )
    configs: list[tuple[str, str, str, dict[str, Any]]] = []
    for layout in sp.layouts:
        raw = suite.layout_data(layout, sp)
        source = f"{suite.path.name} ({sp.name} layout {layout.name})"
        for planner in sp.planners:
            for avoidance in sp.avoidance:
                data = apply_choices(copy.deepcopy(raw), planner=planner, avoidance=avoidance, source=source)
                data = apply_overrides(data, dict(suite.overrides), source=source)
                data = apply_overrides(data, dict(variant.overrides), source=f"{source} --set")
                scenario = build_scenario(data, source=source)
                if build:
                    build_run(scenario)
                configs.append((layout.name, str(scenario.planner.name), scenario.avoidance, dict(scenario.data)))
    runs = []
    for seed in sp.seeds:
        for name, planner, avoidance, data in configs:
            shared = {k: v for k, v in data.items() if k != "seed"}
            run_id = config_hash({"scenario": shared, "planner": planner, "avoidance": avoidance, "seed": seed})
            runs.append(
                RunSpec(
                    run_id=run_id,
                    planner=planner,
                    avoidance=avoidance,
                    seed=seed,
                    grid=(("layout", name),),
                    scenario_data={**data, "seed": seed},
                    source=f"{suite.path.name}:{name}",
                    run_dir=str(out / "runs" / run_id),
                )
            )
    return BenchmarkPlan(suite=suite, split=sp, out=out, runs=tuple(runs), variant=variant)


def _varied(sp: Split, variant: Variant) -> Split:
    """The split with a variant's planners and seed count."""
    planners_ = sp.planners
    if variant.planners:
        unknown = [p for p in variant.planners if p not in sp.planners]
        if unknown:
            raise ConfigError(
                f"not in the {sp.name} split: {', '.join(unknown)}; it has {', '.join(sp.planners)}",
                source="--planners",
            )
        planners_ = tuple(variant.planners)
    seeds = sp.seeds
    if variant.seeds is not None:
        if variant.seeds < 1:
            raise ConfigError(f"must be >= 1, got {variant.seeds}", source="--seeds")
        seeds = tuple(range(sp.seeds[0], sp.seeds[0] + variant.seeds))
    return dataclasses.replace(sp, planners=planners_, seeds=seeds)


# ------------------------------------------------------------------- running
@dataclasses.dataclass(frozen=True)
class BenchmarkResult:
    """What ``run_benchmark`` did.

    Attributes:
        out: the benchmark directory.
        data: the benchmark JSON (as written to ``OUT/benchmark.json``).
        files: the JSON, the Markdown table and the figure.
        n_planned: runs of the split.
        n_skipped: runs recorded before this call.
        n_run: runs executed by this call.
        interrupted: stopped early (Ctrl-C); running again resumes.
        wall_time_s: seconds this call took.
    """

    out: Path
    data: dict[str, Any]
    files: tuple[Path, ...]
    n_planned: int
    n_skipped: int
    n_run: int
    interrupted: bool
    wall_time_s: float


def _manifest(plan: BenchmarkPlan, old: Mapping[str, Any] | None) -> dict[str, Any]:
    """The directory's manifest: the suite, version and split it holds (refused when it holds another)."""
    mine = {"suite": plan.suite.name, "version": plan.suite.version, "split": plan.split.name}
    if old is not None and {k: old.get(k) for k in mine} != mine:
        held = f"{old.get('suite')} v{old.get('version')} {old.get('split')}"
        raise ConfigError(
            f"holds a benchmark of another suite, version or split ({held}); use another --out", source=str(plan.out)
        )
    if old is not None and old.get("variant", {}).get("set", {}) != plan.variant.record().get("set", {}):
        raise ConfigError(
            f"holds a benchmark with other overrides ({old.get('variant', {}).get('set', {})}); use another --out",
            source=str(plan.out),
        )
    now = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    return {
        "format": FORMAT,
        **mine,
        "suite_file": str(plan.suite.path),
        "suite_digest": plan.suite.digest,
        "variant": plan.variant.record(),
        "created": (old or {}).get("created", now),
        "updated": now,
        # every run the directory holds: a study that narrows planners or seeds adds to what earlier calls planned
        "runs": {**(old or {}).get("runs", {}), **_held(plan.runs)},
    }


def _held(runs: Iterable[RunSpec]) -> dict[str, dict[str, Any]]:
    """Run id -> layout, planner, avoidance and seed: how the manifest lists a run."""
    return {
        s.run_id: {"layout": layout_of(s), "planner": s.planner, "avoidance": s.avoidance, "seed": s.seed} for s in runs
    }


def run_benchmark(
    suite: Suite | str | Path,
    split: str,
    out: str | Path | None = None,
    *,
    executor: str = "local",
    workers: int | None = None,
    address: str | None = None,
    quiet: bool = True,
    figure: bool = True,
    retry_failed: bool = False,
    command: str | None = None,
    worker: Any = None,
    variant: Variant = Variant(),
) -> BenchmarkResult:
    """Run the runs of a split not recorded yet in ``out``, then write the benchmark JSON, table and figure.

    Args:
        suite: a suite (or its file, or a bundled suite's name).
        split: ``dev`` or ``holdout``.
        out: the benchmark directory (default ``runs/benchmark-<suite>-v<version>-<split>``).
        executor: ``local`` (a process pool) or ``ray``.
        workers: parallel runs (default: the cores; with Ray and an ``address``, the cluster's).
        address: Ray cluster address.
        quiet: no progress bar.
        figure: draw ``benchmark.png``.
        retry_failed: run again the runs recorded with ``exit_status = error`` (they failed to run).
        command: the command line recorded in the JSON (default: this process's).
        worker: the function that runs one spec (tests; default ``jobs.execute_run``).
        variant: planners, seeds and overrides that differ from the split (an ablation).

    Raises:
        ConfigError: a bad suite, a directory that holds another benchmark, an executor that cannot start.
    """
    from pybullet_swarm.experiment.executors import ExecutorKind, check_executor, prestart
    from pybullet_swarm.experiment.rundir import check_output_dir, exclusive_directory, write_json
    from pybullet_swarm.experiment.sweep import Execution, execute_runs, recover_runs

    t0 = time.perf_counter()
    if check_executor(executor, workers=workers, address=address) is ExecutorKind.LOCAL:
        prestart()
    plan = plan_benchmark(suite, split, out, variant=variant)
    check_output_dir(plan.out)
    manifest_path = plan.out / PLAN
    old = json.loads(manifest_path.read_text(encoding="utf-8")) if manifest_path.is_file() else None
    if old is None and plan.out.is_dir() and any(p.name != ".lock" for p in plan.out.iterdir()):
        raise ConfigError(
            f"exists and is not a benchmark directory (no {PLAN}); use another --out", source=str(plan.out)
        )
    ran = Execution()
    with exclusive_directory(plan.out, "benchmark"):
        manifest = _manifest(plan, old)
        write_json(manifest_path, manifest)
        table = RunsTable(plan.out / RUNS_CSV)
        if retry_failed and table.drop(
            [s.run_id for s in plan.runs if (table.get(s.run_id) or {}).get("exit_status") == "error"]
        ):
            table.save()
        recover_runs(plan.runs, table)
        todo = [s for s in plan.runs if table.get(s.run_id) is None]
        if not quiet and len(todo) < len(plan.runs):
            print(
                f"benchmark: {len(plan.runs) - len(todo)} of {len(plan.runs)} runs already finished, skipped",
                file=sys.stderr,
            )
        execute_runs(todo, table, ran, executor=executor, workers=workers, address=address, worker=worker, quiet=quiet)
        held = manifest["runs"]
        rows = [table.get(rid) for rid in held]
        data = summarize(plan, [r for r in rows if r is not None], command=command, held=held)
        files = write_outputs(data, plan.out, figure=figure and not ran.interrupted)
    return BenchmarkResult(
        out=plan.out,
        data=data,
        files=tuple(files),
        n_planned=len(plan.runs),
        n_skipped=len(plan.runs) - len(todo),
        n_run=ran.n_run,
        interrupted=ran.interrupted,
        wall_time_s=time.perf_counter() - t0,
    )


def write_outputs(data: Mapping[str, Any], out: Path, *, figure: bool = True) -> list[Path]:
    """Write ``benchmark.json``, ``benchmark.md`` (and ``benchmark.png``) of benchmark data into ``out``."""
    from pybullet_swarm.experiment.rundir import atomic_write, write_json

    write_json(out / RESULT, data)
    atomic_write(out / TABLE, lambda fh: fh.write(markdown_table(dict(data)) + "\n"))
    files = [out / RESULT, out / TABLE]
    if figure:
        from pybullet_swarm.plotting.benchmark_plots import benchmark_figure

        files.append(benchmark_figure(data, out / FIGURE))
    return files


# --------------------------------------------------------------- statistics
def _number(v: Any) -> float | None:
    if isinstance(v, bool) or v is None or v == "":
        return None
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def run_incidents(row: Mapping[str, Any]) -> float | None:
    """Incidents of one run (``incidents`` of its ``metrics.json``: a count, or a mapping whose ``total``
    or whose numbers' sum is the count); None when the run does not report them."""
    whole = _number(row.get("incidents"))
    if whole is not None:
        return whole
    total = _number(row.get("incidents.total"))
    if total is not None:
        return total
    parts = [_number(v) for k, v in row.items() if str(k).startswith("incidents.")]
    known = [p for p in parts if p is not None]
    return float(sum(known)) if known else None


def contact_classes(rows: Iterable[Mapping[str, Any]]) -> list[str]:
    """The contact classes the rows report (``collisions.<class>`` columns, without the total)."""
    seen: dict[str, None] = {}
    for r in rows:
        for k in r:
            if str(k).startswith(CONTACT_PREFIX) and k != "collisions.total":
                seen.setdefault(str(k)[len(CONTACT_PREFIX) :])
    return list(seen)


def run_record(row: Mapping[str, Any], classes: Sequence[str]) -> dict[str, Any]:
    """One run's outcome as the benchmark JSON holds it."""
    contacts = {c: _number(row.get(CONTACT_PREFIX + c)) for c in classes}
    return {
        "layout": str(row.get("layout")),
        "planner": str(row.get("planner")),
        "avoidance": str(row.get("avoidance")),
        "seed": int(row["seed"]),
        "exit_status": str(row.get("exit_status")),
        "completion_time_s": _number(row.get("completion_time_s")) if row.get("exit_status") == "completed" else None,
        "contacts": {c: (None if v is None else int(v)) for c, v in contacts.items()},
        "incidents": run_incidents(row),
        "wall_time_s": _number(row.get("worker_time_s")),
        "cpu_time_s": _number(row.get("worker_cpu_s")),
    }


def bootstrap_ci(
    values: Sequence[float] | np.ndarray, stat: Any = np.median, *, n: int = BOOTSTRAP, seed: int = BOOTSTRAP_SEED
) -> list[float] | None:
    """Percentile bootstrap 95 % interval of ``stat`` of ``values`` (None for fewer than two values)."""
    x = np.asarray(values, dtype=float)
    if x.size < 2:
        return None
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, x.size, size=(n, x.size))
    stats = np.apply_along_axis(stat, 1, x[idx])
    lo, hi = np.percentile(stats, [2.5, 97.5])
    return [round(float(lo), 4), round(float(hi), 4)]


def _counts(records: Sequence[Mapping[str, Any]], classes: Sequence[str]) -> dict[str, Any]:
    status = [r["exit_status"] for r in records]
    times = [r["completion_time_s"] for r in records if r["completion_time_s"] is not None]
    incidents = [r["incidents"] for r in records if r["incidents"] is not None]
    out: dict[str, Any] = {
        "runs": len(records),
        "completed": status.count("completed"),
        "completion_rate": round(status.count("completed") / len(records), 4) if records else None,
        "crashed": sum(status.count(s) for s in CRASHED),
        "stalled": status.count("stalled"),
        "timeout": status.count("timeout"),
        "error": status.count("error"),
        "median_time_s": round(statistics.median(times), 3) if times else None,
        "median_time_ci": bootstrap_ci(times),
        "contact_runs": {c: sum(1 for r in records if (r["contacts"].get(c) or 0) > 0) for c in classes},
        "contact_runs_any": sum(1 for r in records if any((v or 0) > 0 for v in r["contacts"].values())),
        "incidents": None
        if not incidents
        else {
            "runs_reporting": len(incidents),
            "runs_with": sum(1 for v in incidents if v > 0),
            "total": sum(incidents),
        },
    }
    return out


def git_commit(where: Path | None = None) -> str:
    """Short hash of the checkout the package runs from (``+dirty`` with uncommitted changes), or ``unknown``."""
    root = where or Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short=10", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return f"{head}+dirty" if dirty else head


def summarize(
    plan: BenchmarkPlan,
    rows: Sequence[Row],
    *,
    command: str | None = None,
    held: Mapping[str, Mapping[str, Any]] | None = None,
) -> dict[str, Any]:
    """The benchmark JSON of the recorded rows of the runs a directory holds.

    Args:
        plan: this call's plan (suite, split, overrides).
        rows: the recorded rows of the held runs.
        command: the command line recorded (default: this process's).
        held: run id -> layout, planner, avoidance, seed of every run the directory holds, this call's and
            earlier calls' (a study that ran one planner, then another, into one directory); default: the plan's.
    """
    held = _held(plan.runs) if held is None else held
    classes = contact_classes(rows)
    records = [run_record(r, classes) for r in rows]
    order = {p: i for i, p in enumerate(plan.suite.split(plan.split.name).planners)}
    configs = sorted(
        dict.fromkeys((h["planner"], h["avoidance"]) for h in held.values()), key=lambda c: order.get(c[0], len(order))
    )
    layouts = [lay.name for lay in plan.split.layouts]
    seeds = sorted({int(h["seed"]) for h in held.values()})
    out_configs = []
    for planner, avoidance in configs:
        mine = [r for r in records if (r["planner"], r["avoidance"]) == (planner, avoidance)]
        per_layout = []
        for name in layouts:
            here = [r for r in mine if r["layout"] == name]
            if here:
                per_layout.append({"layout": name, **_counts(here, classes)})
        out_configs.append(
            {
                "planner": planner,
                "avoidance": avoidance,
                "planned": sum(1 for h in held.values() if (h["planner"], h["avoidance"]) == (planner, avoidance)),
                **_counts(mine, classes),
                "layouts": per_layout,
            }
        )
    return {
        "format": FORMAT,
        "kind": "pybullet_swarm.benchmark",
        "suite": plan.suite.name,
        "suite_version": plan.suite.version,
        "suite_digest": plan.suite.digest,
        "split": plan.split.name,
        "variant": _held_variant(plan, configs, seeds),
        "commit": git_commit(),
        "date": datetime.date.today().isoformat(),
        "command": command if command is not None else " ".join(["pybullet-swarm", *sys.argv[1:]]),
        "planned_runs": len(held),
        "recorded_runs": len(records),
        # s, summed over the runs: what the runs cost (CPU) and took in their workers (wall, load included)
        "cpu_time_s": round(sum(r["cpu_time_s"] or 0.0 for r in records), 1),
        "wall_time_s": round(sum(r["wall_time_s"] or 0.0 for r in records), 1),
        "seeds": seeds,
        "layouts": layouts,
        "contact_classes": classes,
        "configurations": out_configs,
        "runs": records,
    }


def _held_variant(plan: BenchmarkPlan, configs: Sequence[tuple[str, str]], seeds: Sequence[int]) -> dict[str, Any]:
    """The variant record of what a directory holds: its planners and seed count where they differ from the
    split's (the union of the calls that ran into it), and the overrides (one set per directory)."""
    full = plan.suite.split(plan.split.name)
    planners = tuple(dict.fromkeys(p for p, _ in configs))
    return Variant(
        planners=planners if planners != full.planners else (),
        seeds=len(seeds) if list(seeds) != list(full.seeds) else None,
        overrides=plan.variant.overrides,
    ).record()


# ------------------------------------------------------------------ reading
REQUIRED = ("suite", "suite_version", "split", "commit", "configurations", "runs")


def read_benchmark(path: str | Path) -> dict[str, Any]:
    """A benchmark JSON file, checked for the keys ``compare`` and the table need.

    Raises:
        ConfigError: unreadable, or not a benchmark JSON (naming the missing key).
    """
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(f"unreadable benchmark JSON ({' '.join(str(exc).split())[:120]})", source=str(p)) from None
    if not isinstance(data, dict):
        raise ConfigError("must be a benchmark JSON object", source=str(p))
    for key in REQUIRED:
        if key not in data:
            raise ConfigError("is required (a file written by pybullet-swarm benchmark)", source=str(p), field=key)
    if not isinstance(data["runs"], list) or not isinstance(data["configurations"], list):
        raise ConfigError("must be lists", source=str(p), field="runs")
    return data


# ----------------------------------------------------------------- the table
def _fmt(v: Any, digits: str = ".1f") -> str:
    return "-" if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) else format(v, digits)


def _median_cell(c: Mapping[str, Any]) -> str:
    ci = c.get("median_time_ci")
    text = _fmt(c.get("median_time_s"))
    return f"{text} [{_fmt(ci[0])}, {_fmt(ci[1])}]" if ci else text


def _incident_cell(c: Mapping[str, Any]) -> str:
    inc = c.get("incidents")
    if not inc:
        return "-"
    return f"{inc['runs_with']} ({_fmt(inc['total'], '.0f')})"


def markdown_table(data: dict) -> str:  # type: ignore[type-arg]
    """The configurations of a benchmark JSON as a Markdown table (what the docs render for a
    ``<!-- benchmark-table: PATH -->`` marker): one row per planner + avoidance layer, with runs,
    completed, crashed, stalled, timed out, the median completion time [95 % CI], runs with a contact
    per class (agent-agent and agent-structure always, the other classes where a run has one), and runs
    with an incident (incidents) where the runs report them."""
    configs = data.get("configurations", [])
    classes = [
        c
        for c in data.get("contact_classes") or []
        if c in PRIMARY_CONTACTS or any(cfg["contact_runs"].get(c) for cfg in configs)
    ]  # the primary classes, and the others where a run touched
    head = (
        ["configuration", "completed", "crashed", "stalled", "timeout", "median time [s] (95 % CI)"]
        + [f"runs with {SHORT.get(c, c)} contact" for c in classes]
        + ["runs with an incident (incidents)"]
    )
    lines = [
        f"Suite `{data.get('suite')}` v{data.get('suite_version')}, split `{data.get('split')}`, "
        f"commit `{data.get('commit')}`, {data.get('date')}: {data.get('recorded_runs')} of "
        f"{data.get('planned_runs')} runs.",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for c in configs:
        name = c["planner"] if c["avoidance"] == "none" else f"{c['planner']} + {c['avoidance']}"
        cells = [
            name,
            f"{c['completed']}/{c['runs']}",
            str(c["crashed"]),
            str(c["stalled"]),
            str(c["timeout"]),
            _median_cell(c),
            *(str(c["contact_runs"].get(k, "-")) for k in classes),
            _incident_cell(c),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


# ------------------------------------------------------------------ compare
PAIR_KEYS = ("layout", "planner", "avoidance", "seed")


def _paired_diff(a: np.ndarray, b: np.ndarray, stat: Any) -> dict[str, Any]:
    """B - A of ``stat`` over paired samples, with a paired bootstrap 95 % interval (pairs resampled together)."""
    if a.size == 0:
        return {"a": None, "b": None, "diff": None, "ci": None, "pairs": 0}
    diff = float(stat(b) - stat(a))
    ci = None
    if a.size >= 2:
        rng = np.random.default_rng(BOOTSTRAP_SEED)
        idx = rng.integers(0, a.size, size=(BOOTSTRAP, a.size))
        boot = np.array([stat(b[i]) - stat(a[i]) for i in idx])
        lo, hi = np.percentile(boot, [2.5, 97.5])
        ci = [round(float(lo), 4), round(float(hi), 4)]
    return {
        "a": round(float(stat(a)), 4),
        "b": round(float(stat(b)), 4),
        "diff": round(diff, 4),
        "ci": ci,
        "pairs": int(a.size),
    }


def compare(a: Mapping[str, Any], b: Mapping[str, Any]) -> dict[str, Any]:
    """Paired differences B - A of two benchmark JSON (runs paired by layout, planner, avoidance, seed).

    Per configuration present in both: the completion rate, the rate of runs with a contact of each
    class and of any class, the rate of stalled runs (each over every pair), and the median
    completion time (over the pairs completed in both), each with a paired bootstrap 95 % interval.
    A difference whose interval excludes zero is marked ``significant``.
    """

    def key(r: Mapping[str, Any]) -> tuple[Any, ...]:
        return tuple(r[k] for k in PAIR_KEYS)

    ra = {key(r): r for r in a["runs"]}
    rb = {key(r): r for r in b["runs"]}
    common = [k for k in ra if k in rb]
    classes = [c for c in a.get("contact_classes", []) if c in set(b.get("contact_classes", []))]
    configs = list(dict.fromkeys((k[1], k[2]) for k in common))
    out = []
    for planner, avoidance in configs:
        pairs = [(ra[k], rb[k]) for k in common if (k[1], k[2]) == (planner, avoidance)]

        def col(f: Any) -> tuple[np.ndarray, np.ndarray]:
            return np.array([f(x) for x, _ in pairs], dtype=float), np.array([f(y) for _, y in pairs], dtype=float)

        metrics: dict[str, Any] = {
            "completion_rate": _paired_diff(*col(lambda r: r["exit_status"] == "completed"), np.mean),
            "stall_rate": _paired_diff(*col(lambda r: r["exit_status"] == "stalled"), np.mean),
            "contact_rate_any": _paired_diff(
                *col(lambda r: any((v or 0) > 0 for v in r["contacts"].values())), np.mean
            ),
        }
        for c in classes:
            metrics[f"contact_rate_{c}"] = _paired_diff(*col(lambda r, c=c: (r["contacts"].get(c) or 0) > 0), np.mean)
        both = [(x, y) for x, y in pairs if x["completion_time_s"] is not None and y["completion_time_s"] is not None]
        ta = np.array([x["completion_time_s"] for x, _ in both], dtype=float)
        tb = np.array([y["completion_time_s"] for _, y in both], dtype=float)
        metrics["median_time_s"] = _paired_diff(ta, tb, np.median)
        for m in metrics.values():
            m["significant"] = bool(m["ci"] is not None and (m["ci"][0] > 0 or m["ci"][1] < 0))
        out.append({"planner": planner, "avoidance": avoidance, "pairs": len(pairs), "metrics": metrics})
    notes = []
    for name, d in (("A", a), ("B", b)):
        if d.get("suite_version") != a.get("suite_version") or d.get("split") != a.get("split"):
            notes.append(f"{name} is another suite version or split: only runs with the same layout names pair")
    return {
        "kind": "pybullet_swarm.benchmark_compare",
        "a": {k: a.get(k) for k in ("suite", "suite_version", "split", "commit", "date", "variant")},
        "b": {k: b.get(k) for k in ("suite", "suite_version", "split", "commit", "date", "variant")},
        "paired_runs": len(common),
        "unpaired_a": len(ra) - len(common),
        "unpaired_b": len(rb) - len(common),
        "configurations": out,
        "notes": notes,
    }


def _side(d: Mapping[str, Any]) -> str:
    """One side of a comparison: its commit and the overrides its runs were made with."""
    overrides = ((d.get("variant") or {}).get("set") or {}).items()
    return ", ".join([str(d["commit"]), *(f"{k}={v}" for k, v in overrides)])


def compare_table(result: Mapping[str, Any]) -> str:
    """The paired differences as a Markdown table (``*``: the interval excludes zero)."""
    lines = [
        f"B ({_side(result['b'])}) - A ({_side(result['a'])}), {result['paired_runs']} paired runs "
        f"({result['unpaired_a']} of A and {result['unpaired_b']} of B unpaired).",
        "",
        "| configuration | pairs | metric | A | B | B - A | 95 % CI |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in result["configurations"]:
        name = c["planner"] if c["avoidance"] == "none" else f"{c['planner']} + {c['avoidance']}"
        for metric, m in c["metrics"].items():
            ci = m["ci"]
            ci_text = "-" if ci is None else f"[{ci[0]:+.3g}, {ci[1]:+.3g}]" + (" *" if m["significant"] else "")
            diff = "-" if m["diff"] is None else f"{m['diff']:+.3g}"
            lines.append(
                f"| {name} | {m['pairs']} | {metric} | {_fmt(m['a'], '.3g')} | {_fmt(m['b'], '.3g')} | {diff} | {ci_text} |"
            )
    return "\n".join(lines)
