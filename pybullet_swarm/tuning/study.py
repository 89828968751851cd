"""Optuna studies over scenario fields, evaluated through the sweep executors, resumable.

A trial is one configuration (a value for every ``--param`` key) run over the study's K seeds
(the same seeds for every trial, so comparisons between trials are paired). Its objective values
are the means over those seeds of each run's score (``objective.score_run``). Runs go through the
sweep machinery: ``plan_sweep`` resolves and validates each configuration and names every run by
a hash of what determines it, the sweep executors (local forkserver pool or Ray) run them, and
each run's row is appended to ``DIR/runs.csv``, so a run already finished (by an interrupted
trial, or by an identical configuration) is never run again.

**Resuming.** ``--trials N`` is the number of finished trials the study should hold: running the
same command again after a kill finishes the study, and a larger N adds trials to it. With the
default storage (``DIR/study.db``, SQLite) the tuner holds ``DIR/.lock``, so a trial found RUNNING
at start was left by a killed tuner: it is marked failed and its parameters are queued again (its
finished runs come back from ``runs.csv``). With a shared storage (``--storage
postgresql://...``) several tuners may work on one study at once; each sends a heartbeat for its
running trials, and a trial whose heartbeat stopped for ``GRACE_PERIOD_S`` is failed and queued
again by the next tuner that starts or asks for a trial.

**Samplers** are seeded with ``sampler_seed + number of trials already in the study``, so a
resumed study does not draw its first points again. NSGA-II's population is
``clip(trials // 5, 4, 50)`` (about five generations for the budget); TPE is multivariate with
``clip(trials // 3, 1, 10)`` random start-up trials and a constant liar for parallel trials.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import sys
import threading
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.rundir import exclusive_directory
from pybullet_swarm.experiment.results import RUNS_CSV, Row, RunsTable, RunStatus, read_metrics
from pybullet_swarm.tuning.objective import MissingMetric, check_names, is_completed, score_run
from pybullet_swarm.tuning.space import ParamSpec, check_ranges
from pybullet_swarm.tuning.spec import SamplerKind, TuneSpec

if TYPE_CHECKING:  # pragma: no cover
    from pybullet_swarm.experiment.sweep import RunSpec

Worker = Callable[["RunSpec"], Row]

STUDY_DB = "study.db"
HEARTBEAT_S = 30
"""s, period of the heartbeat a tuner records for each of its running trials."""
GRACE_PERIOD_S = 120
"""s without a heartbeat after which another tuner fails a trial and queues its parameters again."""
SPEC_ATTR = "pybullet_swarm.tune"
"""Study user attribute holding what the study tunes (compared when a study is resumed)."""


@dataclasses.dataclass(frozen=True)
class TuneResult:
    """What a study directory holds after ``run_tuning``.

    Attributes:
        out: the output directory.
        study_name: the study's name in its storage.
        storage: the storage URL.
        spec: the tuning spec.
        planner: resolved planner.
        avoidance: resolved avoidance layer.
        scenario_name: the scenario's ``name``.
        trials: every trial of the study as plain records (see ``outputs.trial_records``).
        best: the best trial (single objective) or the Pareto-optimal trials, as plain records.
        n_run: trials finished by this call.
        wall_time_s: seconds spent by this call.
        files: outputs written (tables, best.yaml, figures).
        interrupted: stopped early (Ctrl-C); running the same command again resumes.
    """

    out: Path
    study_name: str
    storage: str
    spec: TuneSpec
    planner: str
    avoidance: str
    scenario_name: str
    trials: tuple[dict[str, Any], ...]
    best: tuple[dict[str, Any], ...]
    n_run: int
    wall_time_s: float
    files: tuple[Path, ...] = ()
    interrupted: bool = False


# ------------------------------------------------------------------ planning
@dataclasses.dataclass(frozen=True)
class _Context:
    """A study's scenario resolved once: planner, avoidance and how to plan a trial's runs."""

    spec: TuneSpec
    out: Path
    planner: str
    avoidance: str
    scenario_name: str
    base_hash: str

    def plan(self, values: Mapping[str, Any], *, seeds: Sequence[int] | None = None) -> tuple[RunSpec, ...]:
        """The runs of one configuration (one per seed), validated."""
        from pybullet_swarm.experiment.sweep import Sweep, plan_sweep

        sweep = Sweep(
            self.spec.scenario,
            planners=(self.planner,),
            avoidance=(self.avoidance,),
            grid={k: [v] for k, v in values.items()},
            seeds=tuple(seeds or self.spec.seeds),
            overrides=self.spec.overrides,
        )
        return plan_sweep(sweep, self.out).runs


def _resolve(spec: TuneSpec, out: Path) -> _Context:
    """Resolve the study's scenario (planner, avoidance layer, overrides) and check the search space
    against the parameter models: types and ranges from the models, then the scenario validated at
    both ends of the ranges (rules between fields); nothing is simulated."""
    from pybullet_swarm.experiment.scenario import field_info, load_scenario
    from pybullet_swarm.experiment.sweep import Sweep, plan_sweep

    scenario = load_scenario(spec.scenario, spec.overrides, planner=spec.planner, avoidance=spec.avoidance)
    check_ranges(spec.param_specs, lambda key: field_info(scenario, key))  # type: ignore[arg-type]  # normalised
    sweep = Sweep(
        spec.scenario,
        planners=(spec.planner,),
        avoidance=(spec.avoidance,),
        seeds=(spec.seed_start,),
        overrides=spec.overrides,
    )
    plan = plan_sweep(sweep, out)
    ctx = _Context(
        spec=spec,
        out=out,
        planner=plan.runs[0].planner,
        avoidance=plan.runs[0].avoidance,
        scenario_name=plan.scenario_name,
        base_hash=plan.base_hash,
    )
    for end in ("low", "high"):
        values = {p.key: _cast(p, getattr(p, end)) for p in spec.param_specs}
        try:
            ctx.plan(values, seeds=(spec.seed_start,))
        except ConfigError as exc:
            where = ", ".join(f"{k}={v:g}" for k, v in values.items())
            raise ConfigError(f"the {end} end of the ranges is refused ({where}): {exc}", source="--param") from None
    return ctx


def probe_run(spec: RunSpec) -> Row:
    """Run a spec for three planner ticks in this process (nothing written): the row's keys are the
    metric names of a run (the objectives are checked against them)."""
    import copy

    from pybullet_swarm.experiment.scenario import build_scenario
    from pybullet_swarm.experiment.simulation import Simulation
    from pybullet_swarm.experiment.sweep import make_row

    scenario = build_scenario(copy.deepcopy(dict(spec.scenario_data)), source=spec.source)
    with Simulation(scenario, seed=spec.seed, planner=spec.planner, avoidance=spec.avoidance) as sim:
        sim.step(3 * sim.planner_every)
        metrics = sim.metrics()
    return make_row(spec, metrics)


def _metric_names(ctx: _Context, probe: Worker) -> list[str]:
    """Metric names of a run, from one short run at the low end of the ranges (parameters were
    checked by ``_resolve``, against the models)."""
    values = {p.key: _cast(p, p.low) for p in ctx.spec.param_specs}
    row = probe(ctx.plan(values, seeds=(ctx.spec.seed_start,))[0])
    if row.get("exit_status") == RunStatus.ERROR.value:
        raise ConfigError(f"a run at the low end of the ranges fails: {row.get('error')}", source="--param")
    return sorted(row)


def _cast(p: ParamSpec, v: float) -> float | int:
    return int(v) if p.integer else float(v)


# ------------------------------------------------------------------- storage
def default_storage(out: Path) -> str:
    """``sqlite:///DIR/study.db``."""
    return f"sqlite:///{(Path(out) / STUDY_DB).resolve()}"


def open_storage(url: str) -> Any:
    """An Optuna RDB storage with heartbeats (any SQLAlchemy URL).

    A new SQLite file is made whole before anyone can open it (``_create_sqlite_schema``).

    Raises:
        ConfigError: a URL SQLAlchemy cannot use, a missing database driver, or a database that
            cannot be reached.
    """
    import optuna

    try:
        _create_sqlite_schema(url)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            retry = getattr(optuna.storages, "RetryHeartbeatStaleTrialCallback", None)  # Optuna >= 4.9
            callback = (
                {"heartbeat_stale_trial_callback": retry(max_retry=3)}
                if retry is not None
                else {"failed_trial_callback": optuna.storages.RetryFailedTrialCallback(max_retry=3)}
            )
            return optuna.storages.RDBStorage(
                url, heartbeat_interval=HEARTBEAT_S, grace_period=GRACE_PERIOD_S, **callback
            )
    except ImportError as exc:
        raise ConfigError(f"needs a database driver ({exc})", source="--storage") from None
    except Exception as exc:  # noqa: BLE001 - sqlalchemy's ArgumentError, OperationalError, ...
        text = " ".join(str(exc).split())[:300]
        raise ConfigError(
            f"cannot open {url!r} as an SQLAlchemy database URL ({type(exc).__name__}: {text})", source="--storage"
        ) from None


def _create_sqlite_schema(url: str) -> None:
    """Give a new SQLite storage file its Optuna schema in a temporary file, then link it into place.

    Optuna creates its tables with check-then-create steps that are not atomic across processes:
    a second process opening a database that is being created (a dashboard, a test watching the
    study, a second tuner on a shared file) creates the same tables, and one of the two fails with
    ``table studies already exists``. Building the schema under a private name and publishing it
    with ``os.link`` (which fails if the file appeared meanwhile) means ``study.db`` never exists
    half made; every later opener finds the tables and only reads them. Nothing is done for other
    databases or an existing file.
    """
    import os

    import optuna
    import sqlalchemy

    parsed = sqlalchemy.engine.make_url(url)
    if (
        not parsed.drivername.startswith("sqlite")
        or parsed.database in (None, "", ":memory:")
        or parsed.query.get("mode") is not None
        or parsed.database.startswith("file:")
    ):
        return
    path = Path(parsed.database)
    if path.exists():
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.unlink(missing_ok=True)
    try:
        storage = optuna.storages.RDBStorage(parsed.set(database=str(tmp)).render_as_string(hide_password=False))
        storage.engine.dispose()
        try:
            os.link(tmp, path)
        except FileExistsError:  # another process published its schema first: use that file
            pass
        except OSError:  # no hard links on this file system: rename (last one wins, still whole)
            if not path.exists():
                os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _study_name(ctx: _Context) -> str:
    return ctx.spec.study_name or f"{ctx.scenario_name}-{ctx.planner}-{ctx.avoidance}"


def _open_study(ctx: _Context, storage: Any, name: str) -> Any:
    import optuna

    spec = ctx.spec
    stored = {
        **spec.to_json(),
        "scenario": str(spec.scenario),
        "base_hash": ctx.base_hash,
        "planner": ctx.planner,
        "avoidance": ctx.avoidance,
    }
    directions: list[Any] = [o.direction.value for o in spec.objective_list]
    study = optuna.create_study(storage=storage, study_name=name, directions=directions, load_if_exists=True)
    old = study.user_attrs.get(SPEC_ATTR)
    if old is None:
        if study.trials:
            raise ConfigError(
                f"study {name!r} exists and was not made by pybullet-swarm tune; use another --study", source="--study"
            )
        study.set_user_attr(SPEC_ATTR, stored)
        if spec.baseline is not None:
            study.enqueue_trial(dict(spec.baseline), user_attrs={"baseline": True})
        for values in spec.enqueue:
            study.enqueue_trial(dict(values))
        return study
    diff = [k for k in stored if old.get(k) != stored[k]]
    if diff or [d.name.lower() for d in study.directions] != directions:
        what = ", ".join(diff) if diff else "directions"
        raise ConfigError(
            f"study {name!r} in the storage tunes with other settings ({what} differ); use the "
            "same settings to resume it, or another --study",
            source="--study",
        )
    return study


def _requeue_running(study: Any, *, exclusive: bool) -> int:
    """Fail trials left running by a killed tuner and queue their parameters again; returns how many."""
    import optuna
    from optuna.trial import TrialState

    if not exclusive:  # a shared storage: only trials whose heartbeat stopped (the callback requeues them)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            before = len(study.get_trials(deepcopy=False, states=(TrialState.WAITING,)))
            optuna.storages.fail_stale_trials(study)
            return len(study.get_trials(deepcopy=False, states=(TrialState.WAITING,))) - before
    n = 0
    for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        study.tell(t.number, state=TrialState.FAIL)
        if t.params:
            study.enqueue_trial(t.params, user_attrs={**_carry_attrs(t), "retry_of": t.number})
        n += 1
    return n


def _carry_attrs(t: Any) -> dict[str, Any]:
    return {k: v for k, v in t.user_attrs.items() if k == "baseline"}


def make_sampler(spec: TuneSpec, offset: int = 0) -> Any:
    """The Optuna sampler of ``spec``, seeded with ``sampler_seed + offset``."""
    import optuna

    seed = spec.sampler_seed + offset
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        if spec.sampler is SamplerKind.TPE:
            return optuna.samplers.TPESampler(
                seed=seed, multivariate=True, constant_liar=True, n_startup_trials=max(1, min(10, spec.trials // 3))
            )
        if spec.sampler is SamplerKind.NSGA2:
            return optuna.samplers.NSGAIISampler(seed=seed, population_size=max(4, min(50, spec.trials // 5)))
        if spec.sampler is SamplerKind.CMAES:
            try:
                import cmaes  # noqa: F401
            except ImportError:
                raise ConfigError("needs the cmaes package: pip install cmaes", source="--sampler cmaes") from None
            return optuna.samplers.CmaEsSampler(seed=seed, n_startup_trials=1, warn_independent_sampling=False)
        return optuna.samplers.RandomSampler(seed=seed)


def _n_done(study: Any) -> int:
    """Trials that count towards the budget: completed, and failed because their runs failed."""
    from optuna.trial import TrialState

    trials = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.FAIL))
    return sum(1 for t in trials if t.state is TrialState.COMPLETE or "error" in t.user_attrs)


class _Heartbeat:
    """A daemon thread recording a heartbeat for each running trial of this tuner."""

    def __init__(self, storage: Any) -> None:
        self.storage = storage
        self.ids: set[int] = set()
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._beat, name="tune-heartbeat", daemon=True)
        self._thread.start()

    def _beat(self) -> None:
        while not self._stop.wait(HEARTBEAT_S):
            with self._lock:
                ids = list(self.ids)
            for trial_id in ids:
                with contextlib.suppress(Exception):  # a finished trial refuses heartbeats: fine
                    self.storage.record_heartbeat(trial_id)

    def add(self, trial_id: int) -> None:
        with self._lock:
            self.ids.add(trial_id)
        with contextlib.suppress(Exception):
            self.storage.record_heartbeat(trial_id)

    def remove(self, trial_id: int) -> None:
        with self._lock:
            self.ids.discard(trial_id)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0)


# ------------------------------------------------------------------- running
def _cached_row(table: RunsTable, spec: RunSpec) -> Row | None:
    """A finished run's row: from ``runs.csv``, or recovered from its run directory."""
    from pybullet_swarm.experiment.sweep import make_row

    row = table.get(spec.run_id)
    if row is not None and row.get("exit_status") != RunStatus.ERROR.value:
        return row
    if (Path(spec.run_dir) / "metrics.json").is_file():
        try:
            row = make_row(spec, read_metrics(Path(spec.run_dir)))
        except ConfigError:
            return None
        table.append(row)
        return row
    return None


def trial_scores(spec: TuneSpec, rows: Sequence[Row]) -> tuple[tuple[float, ...], dict[str, Any]]:
    """A trial's objective values (means over its runs) and what to record with it.

    Raises:
        MissingMetric: a run failed or lacks a metric an objective reads.
    """
    objs = spec.objective_list
    per_run = [score_run(objs, r, spec.penalty) for r in rows]
    means = tuple(sum(v[i] for v in per_run) / len(per_run) for i in range(len(objs)))
    if not all(math.isfinite(m) for m in means):
        raise MissingMetric(f"an objective is not finite ({', '.join(f'{m:g}' for m in means)})")
    attrs: dict[str, Any] = {
        "seeds": [int(r["seed"]) for r in rows],  # type: ignore[arg-type]
        "run_ids": [str(r["run_id"]) for r in rows],
        "per_seed": [list(v) for v in per_run],
        "completed": sum(1 for r in rows if is_completed(r)) / len(rows),
    }
    for name in dict.fromkeys(n for o in objs for n in o.names):
        vals = [float(v) for v in (r.get(name) for r in rows) if isinstance(v, (int, float))]
        attrs[f"mean.{name}"] = sum(vals) / len(vals) if vals else None
    return means, attrs


def run_tuning(
    spec: TuneSpec,
    out: str | Path,
    *,
    storage: str | None = None,
    executor: str = "local",
    workers: int | None = None,
    address: str | None = None,
    quiet: bool = True,
    figures: bool = True,
    worker: Worker | None = None,
    probe: Worker | None = None,
    retries: int = 2,
    outputs: str | Path | None = None,
) -> TuneResult:
    """Run (or resume) a study until it holds ``spec.trials`` finished trials; write its outputs.

    Args:
        spec: what to tune.
        out: the output directory (runs, tables, figures; the SQLite study by default).
        storage: an SQLAlchemy URL (default ``sqlite:///DIR/study.db``).
        executor: ``local`` or ``ray``.
        workers: parallel runs (default: the cores).
        address: Ray cluster address (``--executor ray``).
        quiet: no progress bar and no messages.
        figures: draw the figures.
        worker: the function that runs one spec (default: the sweep's ``execute_run``).
        probe: the function that runs the probe (default: ``probe_run``; a stand-in ``worker`` for tests).
        retries: attempts of a run whose worker process died.
        outputs: where ``trials.csv``, ``best.yaml``, ``study.json`` and ``plots/`` go (default ``out``);
            two studies sharing ``out`` (and so its runs and its SQLite storage) need their own.

    Raises:
        ConfigError: bad spec, ranges a planner refuses, unknown metric names, a storage that cannot
            be opened, a study made with other settings, another tuner on ``out``.
    """
    import optuna
    from tqdm import tqdm

    from pybullet_swarm.experiment.executors import ExecutorKind, check_executor, make_executor, prestart
    from pybullet_swarm.experiment.sweep import cpu_count
    from pybullet_swarm.tuning.outputs import write_outputs

    t0 = time.perf_counter()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    # ask/tell with our own heartbeat thread (see _Heartbeat) is what the warning asks to avoid; it is intended
    warnings.filterwarnings("ignore", message="Heartbeat of storage is supposed to be used")
    kind = check_executor(executor, workers=workers, address=address)
    if kind is ExecutorKind.LOCAL and worker is None:
        prestart()
    out = Path(out).resolve()
    if out.exists() and not out.is_dir():
        raise ConfigError("exists and is not a directory", source=str(out))
    ctx = _resolve(spec, out)
    check_names(
        spec.objective_list,
        _metric_names(ctx, probe or (worker if worker is not None else probe_run)),
        source="--objectives" if spec.multi else "--objective",
    )
    exclusive = storage is None
    url = storage or default_storage(out)
    say = (lambda msg: None) if quiet else (lambda msg: print(msg, file=sys.stderr, flush=True))
    interrupted = False
    n_run = 0
    with exclusive_directory(out, "tuner") if exclusive else contextlib.nullcontext():
        store = open_storage(url)
        name = _study_name(ctx)
        study = _open_study(ctx, store, name)
        requeued = _requeue_running(study, exclusive=exclusive)
        if requeued:
            say(f"tune: {requeued} trial(s) of an interrupted tuner queued again")
        study.sampler = make_sampler(spec, offset=len(study.trials))
        done = _n_done(study)
        if done:
            say(f"tune: study {name!r} resumed with {done} of {spec.trials} trials finished")
        distributions = {p.key: p.distribution() for p in spec.param_specs}
        table = RunsTable(out / RUNS_CSV)
        n_workers = workers if workers is not None else cpu_count()
        batch_size = max(1, math.ceil(n_workers / spec.seeds_per_trial))
        beat = _Heartbeat(store)
        bar = tqdm(
            total=spec.trials,
            initial=min(done, spec.trials),
            unit="trial",
            desc=f"tune {ctx.planner}",
            disable=quiet,
            file=sys.stderr,
            dynamic_ncols=True,
        )
        _show_best(bar, study, spec)
        pending: dict[int, Any] = {}
        try:
            with make_executor(
                kind, workers=workers, address=address, worker=worker, retries=retries, quiet=quiet
            ) as ex:
                while done < spec.trials:
                    batch = [study.ask(distributions) for _ in range(min(batch_size, spec.trials - done))]
                    for trial in batch:
                        pending[trial.number] = trial
                        beat.add(trial._trial_id)
                    n = _run_batch(study, spec, ctx, batch, table, ex)
                    for trial in batch:
                        beat.remove(trial._trial_id)
                        pending.pop(trial.number, None)
                    done = _n_done(study)
                    n_run += n
                    bar.n = min(done, spec.trials)
                    _show_best(bar, study, spec)
        except KeyboardInterrupt:
            interrupted = True
            from optuna.trial import TrialState

            for trial in pending.values():  # their finished runs are in runs.csv: queue them again
                with contextlib.suppress(Exception):
                    study.tell(trial, state=TrialState.FAIL)
                    study.enqueue_trial(trial.params, user_attrs={**_carry_attrs(trial), "retry_of": trial.number})
        finally:
            beat.stop()
            bar.close()
        target = Path(outputs).resolve() if outputs is not None else out
        files = write_outputs(
            study,
            spec,
            target,
            planner=ctx.planner,
            avoidance=ctx.avoidance,
            scenario_name=ctx.scenario_name,
            figures=figures and not interrupted,
        )
    from pybullet_swarm.tuning.outputs import best_records, trial_records

    return TuneResult(
        out=out,
        study_name=name,
        storage=url,
        spec=spec,
        planner=ctx.planner,
        avoidance=ctx.avoidance,
        scenario_name=ctx.scenario_name,
        trials=tuple(trial_records(study, spec)),
        best=tuple(best_records(study, spec)),
        n_run=n_run,
        wall_time_s=time.perf_counter() - t0,
        files=tuple(files),
        interrupted=interrupted,
    )


def _run_batch(study: Any, spec: TuneSpec, ctx: _Context, batch: Sequence[Any], table: RunsTable, ex: Any) -> int:
    """Run the runs of a batch of asked trials that are not finished yet, then tell each trial; returns
    the number of trials told."""
    from optuna.trial import TrialState

    specs: dict[int, tuple[RunSpec, ...]] = {}
    for trial in batch:
        values = {p.key: trial.params[p.key] for p in spec.param_specs}
        try:
            specs[trial.number] = ctx.plan(values)
        except ConfigError as exc:
            trial.set_user_attr("error", str(exc))
            study.tell(trial, state=TrialState.FAIL)
    todo: dict[str, RunSpec] = {}
    for runs in specs.values():
        for s in runs:
            if _cached_row(table, s) is None:
                todo.setdefault(s.run_id, s)
    if todo:
        for row in ex.imap_unordered(list(todo.values())):
            table.append(row)
    n = 0
    for trial in batch:
        if trial.number not in specs:
            continue
        rows = [
            table.get(s.run_id) or {"exit_status": RunStatus.ERROR.value, "error": "no row"}
            for s in specs[trial.number]
        ]
        try:
            scores, attrs = trial_scores(spec, rows)  # type: ignore[arg-type]
        except MissingMetric as exc:
            trial.set_user_attr("error", str(exc))
            study.tell(trial, state=TrialState.FAIL)
        else:
            for k, v in attrs.items():
                trial.set_user_attr(k, v)
            study.tell(trial, list(scores))
        n += 1
    return n


def _show_best(bar: Any, study: Any, spec: TuneSpec) -> None:
    """The best value so far (single objective) or the size of the Pareto front, on the progress bar."""
    from optuna.trial import TrialState

    if not study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)):
        return
    if spec.multi:
        bar.set_postfix({"pareto": len(study.best_trials)}, refresh=True)
    else:
        bar.set_postfix({"best": f"{study.best_value:.4g}", "trial": study.best_trial.number}, refresh=True)


__all__ = [
    "GRACE_PERIOD_S",
    "HEARTBEAT_S",
    "SamplerKind",
    "TuneResult",
    "TuneSpec",
    "default_storage",
    "make_sampler",
    "open_storage",
    "probe_run",
    "run_tuning",
    "trial_scores",
]
