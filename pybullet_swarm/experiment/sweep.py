"""Sweeps: planners x avoidance x grid values x seeds, run in parallel, resumable, summarised.

Layout of a sweep directory::

    DIR/sweep.json      manifest: the sweep, the base scenario's hash, every planned run
    DIR/runs.csv        one row per finished run (appended as runs finish)
    DIR/runs.parquet    the same rows, typed (only when pyarrow is installed)
    DIR/summary.csv     per configuration and metric: n, mean, std, median, 95 % CI
    DIR/plots/          comparison figures
    DIR/runs/<id>/      each run's own run directory (scenario.yaml, timeseries.npz, ...)

A run's id is a hash of what determines it (the resolved scenario without its seed, the
planner, the avoidance layer and the seed), so the same run planned twice, from the same
command or from a wider one, is recognised and not run again.

Scripted use (the ``__main__`` guard is needed: workers are fresh processes that import the script)::

    from pybullet_swarm.experiment.sweep import Sweep, run_sweep

    if __name__ == "__main__":
        sweep = Sweep("construction", planners=("shortest_path", "stigmergy"), seeds=10)
        result = run_sweep(sweep, "runs/thesis", workers=2, quiet=False)
        print(result.table())
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import functools
import itertools
import sys
import time
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Sequence, cast

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.results import (
    MANIFEST,
    RUNS_CSV,
    RUNS_PARQUET,
    SUMMARY_CSV,
    Row,
    RunStatus,
    RunsTable,
    config_hash,
    one_line,
    plain_cell,
    read_metrics,
    write_parquet,
)
from pybullet_swarm.experiment.jobs import RunSpec, cpu_count, execute_run, failure_row, make_row
from pybullet_swarm.experiment.summary import CIMethod, SummaryRow, format_table, summarize, write_summary

__all__ = [
    "Execution",
    "RunSpec",
    "Sweep",
    "SweepResult",
    "cpu_count",
    "execute_run",
    "execute_runs",
    "failure_row",
    "make_row",
    "recover_runs",
    "run_sweep",
]

Worker = Callable[["RunSpec"], Row]


# ------------------------------------------------------------------ the spec
@dataclasses.dataclass(frozen=True)
class Sweep:
    """What to run: the product of planners x avoidance layers x grid values x seeds.

    Args:
        scenario: a scenario YAML file or bundled name.
        planners: planner names (None: the scenario's own planner).
        avoidance: avoidance layer names (None: the scenario's own).
        grid: ``{'key.path': [v1, v2, ...]}``: every combination of values is a configuration.
        seeds: the seeds (an int N means seeds 0 .. N-1).
        overrides: ``{'key.path': value}`` or ``['key.path=value', ...]`` applied to every run.

    Raises:
        ConfigError: empty axes, repeated values, negative seeds or malformed keys.
    """

    scenario: str | Path
    planners: Sequence[str | None] = (None,)
    avoidance: Sequence[str | None] = (None,)
    grid: Mapping[str, Sequence[Any]] | Sequence[tuple[str, Sequence[Any]]] = ()
    seeds: int | Sequence[int] = 10
    overrides: Mapping[str, Any] | Sequence[str] = ()

    def __post_init__(self) -> None:
        from pybullet_swarm.experiment.scenario import parse_override

        set_ = functools.partial(object.__setattr__, self)  # frozen: the fields are normalised once, here
        set_("planners", _axis(self.planners, "--planners"))
        set_("avoidance", _axis(self.avoidance, "--avoidance"))
        seeds = tuple(range(self.seeds)) if isinstance(self.seeds, int) else tuple(self.seeds)
        if not seeds:
            raise ConfigError("must hold at least one seed", source="--seeds")
        for s in seeds:
            if isinstance(s, bool) or not isinstance(s, int) or s < 0:
                raise ConfigError(f"must be integers >= 0, got {s!r}", source="--seeds")
        if len(set(seeds)) != len(seeds):
            raise ConfigError("must not repeat a seed", source="--seeds")
        set_("seeds", seeds)
        items = self.grid.items() if isinstance(self.grid, Mapping) else self.grid
        grid: list[tuple[str, tuple[Any, ...]]] = []
        for key, values in items:
            _check_key(key, "--grid")
            values = tuple(values)
            if not values:
                raise ConfigError("needs at least one value", source="--grid", field=key)
            if len({plain_cell(v) for v in values}) != len(values):
                raise ConfigError("must not repeat a value", source="--grid", field=key)
            if key in (k for k, _ in grid):
                raise ConfigError("appears twice", source="--grid", field=key)
            grid.append((key, values))
        set_("grid", tuple(grid))
        pairs = (
            self.overrides.items()
            if isinstance(self.overrides, Mapping)
            else (parse_override(o) if isinstance(o, str) else tuple(o) for o in self.overrides)
        )
        overrides = []
        for key, value in pairs:
            _check_key(key, "--set")
            overrides.append((key, value))
        set_("overrides", tuple(overrides))

    @property
    def grid_items(self) -> tuple[tuple[str, tuple[Any, ...]], ...]:
        """The grid as ``__post_init__`` normalised it: ``((key, values), ...)``."""
        return cast("tuple[tuple[str, tuple[Any, ...]], ...]", self.grid)

    @property
    def seed_list(self) -> tuple[int, ...]:
        """The seeds as ``__post_init__`` normalised them."""
        return cast("tuple[int, ...]", self.seeds)

    @property
    def override_items(self) -> tuple[tuple[str, Any], ...]:
        """The overrides as ``__post_init__`` normalised them: ``((key, value), ...)``."""
        return cast("tuple[tuple[str, Any], ...]", self.overrides)

    @property
    def grid_keys(self) -> tuple[str, ...]:
        """The grid's key paths, in order."""
        return tuple(k for k, _ in self.grid_items)

    def grid_points(self) -> list[tuple[tuple[str, Any], ...]]:
        """Every combination of grid values: ``((key, value), ...)`` (one empty point without a grid)."""
        keys = self.grid_keys
        values = [v for _, v in self.grid_items]
        return [tuple(zip(keys, combo)) for combo in itertools.product(*values)]

    def to_json(self) -> dict[str, Any]:
        """The sweep as plain data (for the manifest)."""
        return {
            "scenario": str(self.scenario),
            "planners": list(self.planners),
            "avoidance": list(self.avoidance),
            "grid": {k: list(v) for k, v in self.grid_items},
            "seeds": list(self.seed_list),
            "overrides": dict(self.override_items),
        }


def _axis(values: Sequence[str | None] | str | None, name: str) -> tuple[str | None, ...]:
    if values is None or isinstance(values, str):
        values = (values,)
    out = tuple(values)
    if not out:
        raise ConfigError("needs at least one value", source=name)
    if len(set(out)) != len(out):
        raise ConfigError(f"must not repeat a value, got {', '.join(map(str, out))}", source=name)
    for v in out:
        if v is not None and (not isinstance(v, str) or not v.strip()):
            raise ConfigError(f"must be names, got {v!r}", source=name)
    return out


def _check_key(key: Any, source: str) -> None:
    if not isinstance(key, str) or not key or any(not p for p in key.split(".")):
        raise ConfigError(f"expected a key.path, got {key!r}", source=source)


# ------------------------------------------------------------------ planning
@dataclasses.dataclass(frozen=True)
class Plan:
    """A sweep resolved against its scenario: every run, validated.

    Attributes:
        sweep: the sweep.
        out: the sweep directory (absolute).
        source: the scenario file's name.
        scenario_name: the scenario's ``name``.
        base_hash: hash of the resolved scenario with the sweep's overrides (no grid values).
        runs: every run, seeds outermost (a partial sweep has every configuration at similar n).
    """

    sweep: Sweep
    out: Path
    source: str
    scenario_name: str
    base_hash: str
    runs: tuple[RunSpec, ...]

    @property
    def group_by(self) -> tuple[str, ...]:
        """The columns that define a configuration."""
        return ("planner", "avoidance", *self.sweep.grid_keys)


def _file_data(sweep: Sweep) -> tuple[dict[str, Any], str]:
    """The sweep's scenario file as plain data (not validated yet) and its name."""
    from pybullet_swarm.experiment.scenario import resolve_scenario_path
    from pybullet_swarm.validation import read_yaml

    path = resolve_scenario_path(sweep.scenario)
    data = read_yaml(path)
    if not isinstance(data, dict):
        raise ConfigError(f"must be a mapping of scenario sections, got {type(data).__name__}", source=path.name)
    return data, path.name


def _configuration(
    raw: Mapping[str, Any],
    source: str,
    sweep: Sweep,
    planner: str | None,
    avoidance: str | None,
    point: tuple[tuple[str, Any], ...] = (),
) -> Any:
    """One configuration's scenario: the planner and avoidance choices, the sweep's overrides and the
    grid point applied to the file's data, then validated (``Scenario``)."""
    from pybullet_swarm.experiment.scenario import apply_choices, apply_overrides, build_scenario

    data = apply_choices(copy.deepcopy(dict(raw)), planner=planner, avoidance=avoidance, source=source)
    data = apply_overrides(data, dict(sweep.override_items), source=source)
    if point:
        data = apply_overrides(data, dict(point), source=source)
    return build_scenario(data, source=source)


_CHOSEN = ("planner", "avoidance", "avoidance_params")  # scenario keys the planner/avoidance choices decide


def base_scenario(sweep: Sweep) -> tuple[dict[str, Any], str]:
    """The sweep's scenario with its overrides applied (first planner and avoidance layer), validated:
    ``(resolved data, source)``."""
    raw, source = _file_data(sweep)
    scenario = _configuration(raw, source, sweep, sweep.planners[0], sweep.avoidance[0])
    return dict(scenario.data), source


def _base_hash(data: Mapping[str, Any], sweep: Sweep) -> str:
    """Hash of what every run of a sweep shares: the resolved scenario without its seed and without
    what the planner and avoidance choices decide, plus the ``--set`` overrides of those."""
    shared = {k: v for k, v in data.items() if k != "seed" and k not in _CHOSEN}
    chosen = {k: v for k, v in sweep.override_items if k.split(".")[0] in _CHOSEN}
    if chosen:
        shared["overrides"] = chosen
    return config_hash(shared)


def default_out(sweep: Sweep, root: Path = Path("runs")) -> Path:
    """``runs/sweep-<scenario>-<hash of the base scenario>``: the same command finds the same directory."""
    data, _ = base_scenario(sweep)
    from pybullet_swarm.experiment.rundir import safe_name

    return root / f"sweep-{safe_name(str(data.get('name', 'scenario')))}-{_base_hash(data, sweep)[:8]}"


def _without_seed(data: Mapping[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in data.items() if k != "seed"}


def plan_sweep(sweep: Sweep, out: str | Path, *, plots: bool = False) -> Plan:
    """Resolve and validate every configuration of a sweep; list its runs.

    Each configuration (planner x avoidance x grid point) is the scenario file with the planner and
    avoidance choices applied (``scenario.apply_choices``), then the sweep's overrides, then the
    grid values, validated: its planner and avoidance parameters are checked against their models,
    and its run is built once without stepping (``runner.build_run``).

    Raises:
        ConfigError: a grid value, planner or avoidance layer that cannot be used (one line
            naming the configuration), before anything runs.
    """
    from pybullet_swarm.experiment.runner import build_run
    from pybullet_swarm.planning.registry import avoidance_layers, planners

    out = Path(out).resolve()
    raw, source = _file_data(sweep)
    registry, layers = planners(), avoidance_layers()
    for p in sweep.planners:
        if p is not None and p not in registry:
            raise ConfigError(f"unknown planner {p!r}; available: {', '.join(registry)}", source="--planners")
    for a in sweep.avoidance:
        if a is not None and a not in layers:
            raise ConfigError(f"unknown avoidance {a!r}; available: {', '.join(layers)}", source="--avoidance")
    runs: list[RunSpec] = []
    configs: list[tuple[tuple[tuple[str, Any], ...], str, str, dict[str, Any]]] = []
    base: dict[str, Any] | None = None
    for point in sweep.grid_points():
        for p, a in itertools.product(sweep.planners, sweep.avoidance):
            try:
                scenario = _configuration(raw, source, sweep, p, a, point)
                build_run(scenario)  # what a run refuses when it starts is refused before the sweep
            except ConfigError as exc:
                where = ", ".join(f"{k}={plain_cell(v)}" for k, v in point)
                if exc.field == "planner.name" and p is not None:
                    raise ConfigError(exc.detail, source="--planners") from None
                raise ConfigError(
                    f"{exc.detail} (grid point {where})" if point else exc.detail,
                    source=exc.source or source,
                    field=exc.field,
                ) from None
            if base is None and not point:
                base = dict(scenario.data)
            configs.append((point, str(scenario.planner.name), scenario.avoidance, dict(scenario.data)))
    if base is None:
        base, _ = base_scenario(sweep)
    seen: set[str] = set()
    for seed in sweep.seed_list:
        for point, planner, avoidance, data in configs:
            run_data = {**data, "seed": seed}  # what the run's scenario.yaml holds
            run_id = config_hash(
                {"scenario": _without_seed(data), "planner": planner, "avoidance": avoidance, "seed": seed}
            )
            if run_id in seen:  # two grid points that resolve to the same scenario
                continue
            seen.add(run_id)
            runs.append(
                RunSpec(
                    run_id=run_id,
                    planner=planner,
                    avoidance=avoidance,
                    seed=seed,
                    grid=point,
                    scenario_data=run_data,
                    source=source,
                    run_dir=str(out / "runs" / run_id),
                    plots=plots,
                )
            )
    return Plan(
        sweep=sweep,
        out=out,
        source=source,
        scenario_name=str(base.get("name", "scenario")),
        base_hash=_base_hash(base, sweep),
        runs=tuple(runs),
    )


# ------------------------------------------------------------------ manifest
def read_manifest(out: Path) -> dict[str, Any] | None:
    """``sweep.json`` of a sweep directory (None when there is none)."""
    import json

    path = Path(out) / MANIFEST
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as exc:  # UnicodeDecodeError is a ValueError
        raise ConfigError(f"unreadable manifest ({' '.join(str(exc).split())[:120]})", source=str(path)) from None
    if not isinstance(data, dict) or not isinstance(data.get("runs"), dict):
        raise ConfigError("not a sweep manifest (no mapping of runs)", source=str(path))
    keys = data.get("grid_keys", [])
    if not isinstance(keys, list) or not all(isinstance(k, str) for k in keys):
        raise ConfigError("corrupt sweep manifest: grid_keys must be a list of names", source=str(path))
    return data


def _merge_manifest(plan: Plan, old: dict[str, Any] | None) -> dict[str, Any]:
    """The new manifest: the old runs and grid keys, then this plan's (a wider sweep extends a directory)."""
    if old is not None and old.get("base_hash") != plan.base_hash:
        was = one_line(f"{old.get('scenario')} with --set {(old.get('sweep') or {}).get('overrides')}", 160)
        raise ConfigError(
            f"holds a sweep of another scenario or other --set overrides ({was}); use another --out",
            source=str(plan.out),
        )
    runs: dict[str, Any] = dict(old["runs"]) if old else {}
    for spec in plan.runs:
        runs.setdefault(
            spec.run_id,
            {
                "planner": spec.planner,
                "avoidance": spec.avoidance,
                "seed": spec.seed,
                "grid": {k: v for k, v in spec.grid},
            },
        )
    grid_keys = list(dict.fromkeys([*(old or {}).get("grid_keys", []), *plan.sweep.grid_keys]))
    now = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    return {
        "format": 1,
        "scenario": str(plan.sweep.scenario),
        "source": plan.source,
        "scenario_name": plan.scenario_name,
        "base_hash": plan.base_hash,
        "sweep": plan.sweep.to_json(),
        "grid_keys": grid_keys,
        "created": (old or {}).get("created", now),
        "updated": now,
        "runs": runs,
    }


# ---------------------------------------------------------------- the sweep
@dataclasses.dataclass(frozen=True)
class SweepResult:
    """What a sweep directory holds after ``run_sweep``.

    Attributes:
        out: the sweep directory.
        rows: every recorded run (``runs.csv``), earlier invocations included.
        summary: statistics per configuration and metric (``summary.csv``).
        n_planned: runs of this sweep.
        n_skipped: runs already recorded before this call (``n_recovered`` of them read back
            from run directories whose row was missing).
        n_run: runs executed by this call.
        n_failed: runs of this sweep recorded with ``exit_status = error``.
        wall_time_s: seconds spent by this call.
        files: the figures drawn.
        interrupted: stopped early (Ctrl-C); re-running resumes.
        timings: where this call's wall time went, s: ``plan_s`` (validating and building every
            configuration), ``runs_s`` (from the first run submitted to the last row received, worker
            start-up included), ``busy_s`` (the runs' own time in their workers, summed), ``finish_s``
            (summary, tables and figures) and ``total_s``.
    """

    out: Path
    rows: tuple[Row, ...]
    summary: tuple[SummaryRow, ...]
    n_planned: int
    n_skipped: int
    n_recovered: int
    n_run: int
    n_failed: int
    wall_time_s: float
    files: tuple[Path, ...] = ()
    interrupted: bool = False
    timings: Mapping[str, float] = dataclasses.field(default_factory=dict)

    def table(self, metrics: Sequence[str] | None = None) -> str:
        """The comparison table (see ``summary.format_table``)."""
        return format_table(self.summary, metrics)


def run_sweep(
    sweep: Sweep,
    out: str | Path | None = None,
    *,
    executor: str = "local",
    workers: int | None = None,
    address: str | None = None,
    plots: bool = False,
    figures: bool = True,
    retry_failed: bool = False,
    ci: CIMethod | str = CIMethod.T,
    quiet: bool = True,
    worker: Worker | None = None,
    retries: int = 2,
) -> SweepResult:
    """Run every run of a sweep that is not recorded yet, in parallel, then summarise.

    Rows are appended to ``runs.csv`` as runs finish; calling again with the same sweep and
    directory skips recorded runs (a directory killed at any point loses no finished run and
    duplicates none). A run that raises is recorded with ``exit_status = error``; the sweep goes on.

    Args:
        sweep: what to run.
        out: the sweep directory (default: ``runs/sweep-<scenario>-<hash>``).
        executor: ``local`` (a process pool on this machine) or ``ray``.
        workers: parallel runs (default: the number of cores; with ``ray`` and an ``address``: the cluster's).
        address: Ray cluster address (``auto`` or ``host:port``); None starts a local Ray.
        plots: draw each run's own figures (they can be drawn later with ``pybullet-swarm plot RUN_DIR``).
        figures: draw the comparison figures into ``out/plots``.
        retry_failed: run again the runs recorded with ``exit_status = error``.
        ci: confidence interval of the summary: ``t`` or ``bootstrap``.
        quiet: no messages and no progress bar.
        worker: the function that runs one spec (default ``execute_run``; must be importable by workers).
        retries: how often a run whose worker was lost (or, with Ray, that raised) is tried again.

    Raises:
        ConfigError: bad sweep, a directory that holds another sweep, or an executor that cannot start.
    """
    from pybullet_swarm.experiment.executors import ExecutorKind, check_executor, prestart

    t0 = time.perf_counter()
    if check_executor(executor, workers=workers, address=address) is ExecutorKind.LOCAL:
        prestart()  # the workers' imports overlap with the planning below
    out = Path(out) if out is not None else default_out(sweep)
    t_plan = time.perf_counter()
    plan = plan_sweep(sweep, out, plots=plots)
    t_plan = time.perf_counter() - t_plan
    out = plan.out
    from pybullet_swarm.experiment.rundir import check_output_dir

    check_output_dir(out)  # before any run: a directory that cannot be written is refused now
    old = read_manifest(out) if out.is_dir() else None
    if old is None and out.is_dir() and any(p.name != ".lock" for p in out.iterdir()):
        raise ConfigError("exists and is not a sweep directory (no sweep.json); use another --out", source=str(out))
    say = (lambda msg: None) if quiet else (lambda msg: print(msg, file=sys.stderr, flush=True))
    from pybullet_swarm.experiment.rundir import exclusive_directory, write_json

    with exclusive_directory(out, "sweep"):
        manifest = _merge_manifest(plan, old)
        write_json(out / MANIFEST, manifest)
        table = RunsTable(out / RUNS_CSV)
        ids = {s.run_id for s in plan.runs}
        if retry_failed:
            failed = [
                r["run_id"] for r in table.rows if r.get("exit_status") == RunStatus.ERROR.value and r["run_id"] in ids
            ]
            if table.drop(failed):
                table.save()
        n_recovered = recover_runs(plan.runs, table)
        _fill_grid_cells(plan, table)
        todo = [s for s in plan.runs if table.get(s.run_id) is None]
        n_skipped = len(plan.runs) - len(todo)
        if n_skipped:
            n_bad = sum(1 for s in plan.runs if (table.get(s.run_id) or {}).get("exit_status") == RunStatus.ERROR.value)
            say(
                f"sweep: {n_skipped} of {len(plan.runs)} runs already finished, skipped"
                + (f" ({n_bad} failed; --retry-failed runs them again)" if n_bad else "")
                + (f"; {n_recovered} recovered from their run directories" if n_recovered else "")
            )
        ran = Execution()
        try:
            execute_runs(
                todo, table, ran, executor=executor, workers=workers, address=address, worker=worker,
                retries=retries, quiet=quiet,
            )  # fmt: skip
        finally:
            rows = _ordered(table.rows, manifest)
            summary = summarize(rows, _group_by(manifest), ci=ci)
            write_summary(out / SUMMARY_CSV, summary)
            write_parquet(out / RUNS_PARQUET, rows, table.columns)
        interrupted, n_run, busy, t_runs, t_last = ran.interrupted, ran.n_run, ran.busy_s, ran.t_start, ran.t_last
        files: list[Path] = []
        if figures and not interrupted and rows:
            files = draw_comparison(rows, _group_by(manifest), out / "plots")
    t_done = time.perf_counter()
    timings = {
        "plan_s": t_plan,
        "runs_s": t_last - t_runs,
        "busy_s": busy,
        "finish_s": t_done - t_last,
        "total_s": t_done - t0,
    }
    n_failed = sum(1 for s in plan.runs if (table.get(s.run_id) or {}).get("exit_status") == RunStatus.ERROR.value)
    return SweepResult(
        out=out,
        rows=tuple(rows),
        summary=tuple(summary),
        n_planned=len(plan.runs),
        n_skipped=n_skipped,
        n_recovered=n_recovered,
        n_run=n_run,
        n_failed=n_failed,
        wall_time_s=time.perf_counter() - t0,
        files=tuple(files),
        interrupted=interrupted,
        timings={k: round(v, 3) for k, v in timings.items()},
    )


@dataclasses.dataclass
class Execution:
    """What ``execute_runs`` did (filled as it goes, so an interrupted call still tells).

    Attributes:
        n_run: runs executed (rows appended).
        busy_s: the runs' own time in their workers, summed, s.
        t_start: ``time.perf_counter()`` when the first run was submitted.
        t_last: ``time.perf_counter()`` when the last row was received.
        interrupted: stopped by Ctrl-C (the rows received are kept).
    """

    n_run: int = 0
    busy_s: float = 0.0
    t_start: float = dataclasses.field(default_factory=time.perf_counter)
    t_last: float = dataclasses.field(default_factory=time.perf_counter)
    interrupted: bool = False


def execute_runs(
    todo: Sequence[RunSpec],
    table: RunsTable,
    ran: Execution,
    *,
    executor: str = "local",
    workers: int | None = None,
    address: str | None = None,
    worker: Worker | None = None,
    retries: int = 2,
    quiet: bool = True,
) -> None:
    """Run ``todo`` on an executor, appending each row to ``table`` as its run finishes (the sweep
    machinery shared by sweeps and benchmarks). A Ctrl-C stops it with ``ran.interrupted`` set."""
    from pybullet_swarm.experiment.executors import make_executor

    ran.t_start = ran.t_last = time.perf_counter()
    if not todo:
        return
    try:
        with (
            make_executor(
                executor, workers=workers, address=address, worker=worker, retries=retries, quiet=quiet
            ) as ex,
            _progress(len(todo), quiet) as bar,
        ):
            for row in ex.imap_unordered(todo):
                table.append(row)
                ran.n_run += 1
                ran.busy_s += float(row.get("worker_time_s") or 0.0)
                ran.t_last = time.perf_counter()
                bar.record(row.get("exit_status") == RunStatus.ERROR.value)
    except KeyboardInterrupt:
        ran.interrupted = True


def recover_runs(runs: Sequence[RunSpec], table: RunsTable) -> int:
    """Record runs that finished (``metrics.json`` written) but whose row never reached ``runs.csv``."""
    n = 0
    for spec in runs:
        if table.get(spec.run_id) is None and (Path(spec.run_dir) / "metrics.json").is_file():
            try:
                metrics = read_metrics(Path(spec.run_dir))
            except ConfigError:
                continue  # unreadable: run it again
            table.append(make_row(spec, metrics))
            n += 1
    return n


def _fill_grid_cells(plan: Plan, table: RunsTable) -> None:
    """Give rows recorded before a grid key was added the value this plan gives them."""
    changed = False
    for spec in plan.runs:
        if spec.grid and table.get(spec.run_id) is not None:
            changed |= table.update(spec.run_id, {k: plain_cell(v) for k, v in spec.grid})
    if changed:
        table.save()


def _group_by(manifest: Mapping[str, Any]) -> tuple[str, ...]:
    return ("planner", "avoidance", *manifest.get("grid_keys", []))


def _ordered(rows: Sequence[Row], manifest: Mapping[str, Any] | None) -> list[Row]:
    """Rows in the manifest's order (configurations as planned), rows it does not list last."""
    if not manifest:
        return list(rows)
    rank = {run_id: i for i, run_id in enumerate(manifest.get("runs", {}))}
    return sorted(rows, key=lambda r: rank.get(str(r.get("run_id")), len(rank)))


def load_sweep(out: str | Path) -> tuple[list[Row], tuple[str, ...]]:
    """The rows of a sweep directory (in planned order) and the columns that define a configuration."""
    out = Path(out)
    if not (out / RUNS_CSV).is_file():
        if (out / MANIFEST).is_file():
            return [], _group_by(read_manifest(out) or {})
        raise ConfigError("not a sweep directory (no runs.csv)", source=str(out))
    manifest = read_manifest(out)
    rows = RunsTable(out / RUNS_CSV).rows
    if manifest is None:  # a runs.csv alone: the columns between seed and exit_status are grid keys
        cols = list(rows[0]) if rows else []
        grid = cols[cols.index("seed") + 1 : cols.index("exit_status")] if {"seed", "exit_status"} <= set(cols) else []
        return rows, ("planner", "avoidance", *grid)
    return _ordered(rows, manifest), _group_by(manifest)


def draw_comparison(
    rows: Sequence[Row], group_by: Sequence[str], out_dir: Path, metrics: Sequence[str] | None = None
) -> list[Path]:
    """Draw the comparison figures of result rows: box plots per metric, completion time vs collisions.

    Args:
        rows: result rows (rows of runs that raised are left out).
        group_by: the columns that define a configuration.
        out_dir: figure directory.
        metrics: the metrics to draw box plots of (default: every numeric outcome that varies).
    """
    from pybullet_swarm.experiment.results import metric_columns
    from pybullet_swarm.experiment.summary import group_rows
    from pybullet_swarm.plotting.sweep_plots import plot_comparison

    ok = [r for r in rows if r.get("exit_status") != RunStatus.ERROR.value]
    groups = [(config.label, members) for config, members in group_rows(ok, group_by)]
    available = metric_columns(ok, exclude=group_by)
    chosen = [m for m in available if m in metrics] if metrics is not None else available
    return plot_comparison(groups, chosen, out_dir)


@contextlib.contextmanager
def _progress(total: int, quiet: bool) -> Iterator[Any]:
    """One progress bar (stderr) with ETA and the counts of finished and failed runs."""
    from tqdm import tqdm

    bar = tqdm(total=total, unit="run", desc="sweep", disable=quiet, file=sys.stderr, dynamic_ncols=True, smoothing=0.1)
    counts = {"ok": 0, "failed": 0}

    class _Bar:
        def record(self, failed: bool) -> None:
            counts["failed" if failed else "ok"] += 1
            bar.set_postfix(counts, refresh=False)
            bar.update(1)

    try:
        yield _Bar()
    finally:
        bar.close()
