"""The ``tune`` subcommand: an Optuna study over scenario fields, scored on the testbed's metrics."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from pybullet_swarm.cli import add_overrides_option
from pybullet_swarm.errors import ConfigError

_PROG = "pybullet-swarm"


def register(subparsers: Any) -> None:
    """Add the ``tune`` parser to ``subparsers`` (its handler is ``args.func``)."""
    from pybullet_swarm.tuning.objective import DEFAULT_OBJECTIVE, DEFAULT_PENALTY

    p = subparsers.add_parser(
        "tune",
        help="optimise planner parameters on run metrics (Optuna: TPE, NSGA-II, CMA-ES), resumable",
        description="Sample --param ranges with an Optuna sampler, run every sampled configuration over the "
        "same K seeds, score each with objective expressions over its metrics and write trials.csv, "
        "best.yaml (apply with `run -c best.yaml`) and figures. Running the same command again "
        "resumes the study; a larger --trials adds trials to it.",
    )
    p.add_argument("scenario", help="scenario YAML file or bundled name (see `list`)")
    p.add_argument("--planner", required=True, help="planner whose parameters are tuned")
    p.add_argument("--avoidance", default=None, help="local avoidance layer (default: the scenario's)")
    p.add_argument(
        "--param",
        dest="params",
        action="append",
        default=[],
        metavar="KEY.PATH=LOW:HIGH[:log][:int]",
        help="a tuned scenario field and its range (repeatable), e.g. "
        "planner.params.trail_pheromone=0:1 or planner.params.fatigue=0.001:0.1:log (default: the planner's "
        "own search space, where it declares one: vasarhelyi's eleven parameters)",
    )
    obj = p.add_mutually_exclusive_group()
    obj.add_argument(
        "--objective",
        default=None,
        metavar="EXPR",
        help=f"objective over a run's metrics (default: the task's, e.g. flock.fitness maximised for a flock; "
        f"else {DEFAULT_OBJECTIVE})",
    )
    obj.add_argument(
        "--objectives",
        default=None,
        metavar="EXPR1,EXPR2",
        help="several objectives: multi-objective study, Pareto front (e.g. completion_time_s,collisions.agent_agent)",
    )
    p.add_argument(
        "--directions",
        default=None,
        metavar="minimize,maximize",
        help="direction of each objective (default: minimize all)",
    )
    p.add_argument(
        "--penalty",
        type=float,
        default=None,
        help="added to each objective of a run that does not complete, after its completion_time_s "
        f"is taken as its simulated time (default {DEFAULT_PENALTY:g}; 0 for a task that never completes)",
    )
    p.add_argument("--trials", type=int, default=50, metavar="N", help="finished trials the study holds (default 50)")
    p.add_argument(
        "--seeds-per-trial",
        type=int,
        default=3,
        metavar="K",
        help="runs per trial, seeds S .. S+K-1 shared by every trial (default 3)",
    )
    p.add_argument("--seed-start", type=int, default=0, metavar="S", help="first seed of every trial (default 0)")
    p.add_argument(
        "--sampler",
        choices=("tpe", "nsga2", "cmaes", "random"),
        default=None,
        help="Optuna sampler (default: tpe; nsga2 with --objectives; cmaes on the planner's own search space)",
    )
    p.add_argument("--sampler-seed", type=int, default=0, help="seed of the sampler (default 0)")
    add_overrides_option(p, "override a scenario field in every run (repeatable)")
    p.add_argument(
        "--executor",
        choices=("local", "ray"),
        default="local",
        help="local: a process pool on this machine (default); ray: Ray tasks",
    )
    p.add_argument("--workers", type=int, default=None, metavar="W", help="parallel runs (default: the cores)")
    p.add_argument("--address", default=None, metavar="ADDR", help="Ray cluster address (with --executor ray)")
    p.add_argument(
        "--study",
        default=None,
        metavar="NAME",
        help="study name in the storage (default: <scenario>-<planner>-<avoidance>)",
    )
    p.add_argument(
        "--storage",
        default=None,
        metavar="URL",
        help="SQLAlchemy URL of the Optuna storage, e.g. postgresql://user@host/db (default: sqlite:///DIR/study.db)",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="output directory (default: runs/tune-<scenario>-<planner>)",
    )
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the ``tune`` subcommand; 0 on success, 130 when interrupted (resumable)."""
    import importlib.util

    if importlib.util.find_spec("optuna") is None:
        raise ConfigError("needs the tune extra (Optuna): pip install 'pybullet_swarm[tune]'", source="tune")
    from pybullet_swarm.tuning.objective import DEFAULT_OBJECTIVE, DEFAULT_PENALTY
    from pybullet_swarm.tuning.study import TuneSpec, run_tuning

    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"must be >= 1, got {args.workers}", source="--workers")
    if args.address is not None and args.executor != "ray":
        raise ConfigError("needs --executor ray", source="--address")
    task_default = _task_objective(args.scenario)
    params: list[Any] = list(args.params)
    baseline = None
    if not params:  # the planner's own search space (vasarhelyi: its eleven parameters), its defaults first
        from pybullet_swarm.tuning.space import planner_search_space

        params = list(planner_search_space(args.planner))
        baseline = _defaults(args.planner, params) or None
    directions = args.directions
    penalty = args.penalty if args.penalty is not None else DEFAULT_PENALTY
    if args.objectives is None and args.objective is None and task_default is not None:
        objectives: str = task_default[0]
        directions = directions or task_default[1]
        penalty = args.penalty if args.penalty is not None else task_default[2]
    else:
        objectives = args.objectives or args.objective or DEFAULT_OBJECTIVE
    multi = args.objectives is not None
    sampler = args.sampler or ("nsga2" if multi else "cmaes" if not args.params and params else "tpe")
    spec = TuneSpec(
        args.scenario,
        params=params,
        planner=args.planner,
        avoidance=args.avoidance,
        objectives=objectives if multi else [objectives],
        directions=directions,
        trials=args.trials,
        seeds_per_trial=args.seeds_per_trial,
        seed_start=args.seed_start,
        sampler=sampler,
        sampler_seed=args.sampler_seed,
        penalty=penalty,
        baseline=baseline,
        overrides=args.overrides,
        study_name=args.study,
    )
    from pybullet_swarm.experiment.rundir import check_output_dir, safe_name

    out = args.out or Path("runs") / f"tune-{safe_name(Path(str(args.scenario)).stem)}-{safe_name(args.planner)}"
    check_output_dir(out, source="--out" if args.out else None)
    result = run_tuning(
        spec,
        out,
        storage=args.storage,
        executor=args.executor,
        workers=args.workers,
        address=args.address,
        quiet=args.quiet,
        figures=not args.no_plots,
    )
    if result.interrupted:
        print(
            f"{_PROG}: error: interrupted; finished trials are stored in {result.storage}; run the same command "
            "again to resume",
            file=sys.stderr,
        )
        return 130
    if not args.quiet:
        print(format_best(result))
        for f in result.files:
            print(f)
    return 0


def _defaults(planner: str, params: list[Any]) -> dict[str, float]:
    """The planner's default values of the tuned ``planner.params.*`` keys that lie within their ranges (all or none)."""
    from pybullet_swarm.planning.registry import planners

    entry = planners().get(planner)
    if entry is None:
        return {}
    values = entry.params().model_dump()
    out = {p.key: values.get(p.key.removeprefix("planner.params.")) for p in params}
    ok = all(isinstance(v, (int, float)) and p.low <= v <= p.high for p, v in zip(params, out.values()))
    return {k: float(v) for k, v in out.items()} if ok else {}  # type: ignore[arg-type]


def _task_objective(scenario: str) -> tuple[str, str, float] | None:
    """The default (objective, direction, penalty) the scenario's task kind declares (``TUNE_OBJECTIVE``), if any."""
    from pybullet_swarm import tasks
    from pybullet_swarm.experiment.scenario import resolve_scenario_path
    from pybullet_swarm.validation import read_yaml

    try:
        data = read_yaml(resolve_scenario_path(scenario))
    except ConfigError:
        return None  # the study reports the scenario's problem itself
    kind = data.get("task", {}).get("kind") if isinstance(data, dict) and isinstance(data.get("task"), dict) else None
    model = tasks.task_models().get(kind) if isinstance(kind, str) else None
    return getattr(model, "TUNE_OBJECTIVE", None)


def format_best(result: Any) -> str:
    """The best trial (or the Pareto front) as a small table, with how to apply it."""
    from pybullet_swarm.tuning.outputs import value_columns

    spec = result.spec
    cols = value_columns(spec)
    n_done = sum(1 for t in result.trials if t["state"] == "complete")
    lines = [
        f"study {result.study_name!r}: {n_done} completed trials ({result.n_run} run now, "
        f"{result.wall_time_s:.0f} s); storage {result.storage}"
    ]
    if not result.best:
        lines.append("no completed trial")
        return "\n".join(lines)
    head = "Pareto-optimal trials" if spec.multi else "best trial"
    lines.append(f"{head} ({', '.join(o.direction.value + ' ' + o.text for o in spec.objective_list)}):")
    keys = [p.key for p in spec.param_specs]
    header = ["trial", *cols, "completed", *[k.removeprefix("planner.params.") for k in keys]]
    rows = [
        [
            str(r["trial"]),
            *[f"{r[c]:.4g}" for c in cols],
            f"{100 * (r.get('completed') or 0):.0f}%",
            *[f"{r[k]:.4g}" for k in keys],
        ]
        for r in result.best
    ]
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(header)]
    lines.append("  " + "  ".join(h.rjust(w) for h, w in zip(header, widths)))
    lines += ["  " + "  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in rows]
    lines.append(f"apply: {_PROG} run {spec.scenario} -c {result.out / 'best.yaml'}")
    return "\n".join(lines)
