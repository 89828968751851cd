"""The ``tsp`` subcommand: independent seeded ant-colony runs on a TSPLIB instance."""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass

import numpy as np
import pydantic
from tqdm import tqdm

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.memory import check_budget, colony_bytes
from pybullet_swarm.planning.aco import ACOParams, LocalSearch, Schedule, solve_tsp
from pybullet_swarm.planning.tsplib import TSPInstance, load_tsplib
from pybullet_swarm.validation import from_pydantic

_PROG = "pybullet-swarm"
MAX_RUNS = 1_000_000  # independent runs of one command
MAX_SEED = 2**63 - 1 - MAX_RUNS  # seeds seed .. seed + runs - 1 must all be valid numpy seeds
_SCHEDULES = {
    "constant": Schedule.CONSTANT,
    "linear": Schedule.LINEAR,
    "linear-no-factor": Schedule.LINEAR_NO_FACTOR,
}
_NUMERIC_OPTIONS = (
    ("alpha", "alpha"),
    ("beta", "beta"),
    ("evaporation", "rho"),
    ("ants", "ants"),
    ("iterations", "iterations"),
)
_LOCAL_SEARCHES = {
    "2opt": LocalSearch.TWO_OPT,
    "none": LocalSearch.NONE,
    "2opt+oropt": LocalSearch.TWO_OPT_OR_OPT,
}


@dataclass(frozen=True)
class RunSummary:
    """Statistics of independent runs on one instance (lengths in TSPLIB distance units).

    Attributes:
        instance: instance name.
        lengths: (runs,) best tour length of each run.
        times_s: (runs,) wall time of each run, s.
        best_tour: (n,) 0-based city indices of the shortest tour over all runs.
        optimum: known optimal length, or None.
    """

    instance: str
    lengths: tuple[float, ...]
    times_s: tuple[float, ...]
    best_tour: tuple[int, ...]
    optimum: float | None

    @property
    def mean(self) -> float:
        """Mean length over the runs."""
        return float(np.mean(self.lengths))

    @property
    def std(self) -> float:
        """Sample standard deviation of the lengths (0 for a single run)."""
        return float(np.std(self.lengths, ddof=1)) if len(self.lengths) > 1 else 0.0

    @property
    def best(self) -> float:
        """Shortest length over the runs."""
        return float(min(self.lengths))

    @property
    def gap_percent(self) -> float | None:
        """Excess of the mean over the optimum, %, or None when the optimum is unknown."""
        if self.optimum is None or self.optimum == 0:
            return None
        return 100.0 * (self.mean - self.optimum) / self.optimum

    def to_json(self, seed: int, params: ACOParams) -> dict[str, object]:
        """The JSON report: summary keys first, then per-run data and the parameters."""
        return {
            "instance": self.instance,
            "runs": len(self.lengths),
            "mean": self.mean,
            "std": self.std,
            "best": self.best,
            "optimum": self.optimum,
            "gap_percent": self.gap_percent,
            "mean_time_s": float(np.mean(self.times_s)),
            "seed": seed,
            "lengths": list(self.lengths),
            "times_s": list(self.times_s),
            "best_tour": [city + 1 for city in self.best_tour],  # TSPLIB numbers nodes from 1
            "params": _params_json(params),
        }


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``tsp`` parser to ``subparsers`` (its handler is ``args.func``)."""
    parser = subparsers.add_parser(
        "tsp",
        help="solve a TSPLIB instance with an ant colony",
        description="Run independent seeded ant-colony searches on a TSPLIB instance and report "
        "the mean, std and best tour length against the known optimum.",
    )
    parser.add_argument(
        "file", metavar="FILE", help="a TSPLIB .tsp file, or the name of a bundled instance (e.g. eil51)"
    )
    parser.add_argument("--runs", type=int, default=10, help="independent runs (default 10)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first run; run i uses seed + i (default 0)")
    parser.add_argument("--alpha", type=float, help="pheromone exponent")
    parser.add_argument("--beta", type=float, help="heuristic exponent")
    parser.add_argument("--evaporation", type=float, metavar="R", help="evaporation rate rho")
    parser.add_argument("--ants", type=int, help="ants per iteration")
    parser.add_argument("--iterations", type=int, help="iterations per run")
    parser.add_argument(
        "--schedule", choices=list(_SCHEDULES), help="alpha/beta schedule (linear: 2(k/n)A and 2((n-k)/n)B)"
    )
    parser.add_argument("--local-search", choices=list(_LOCAL_SEARCHES), help="local search on every ant's tour")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the ``tsp`` subcommand; 0 on success, 2 on bad input (message on stderr)."""
    try:
        if args.runs < 1 or args.runs > MAX_RUNS:
            raise ValueError(f"--runs: expected an integer in [1, {MAX_RUNS}], got {args.runs}")
        if not 0 <= args.seed <= MAX_SEED:
            raise ValueError(f"--seed: expected an integer in [0, 2^63 - 1 - runs], got {args.seed}")
        instance = load_tsplib(args.file)
        params = params_from_args(args)
        check_budget(
            colony_bytes(
                instance.dimension, ants=params.ants, iterations=params.iterations, candidates=params.candidates
            ),
            f"an ant colony on {instance.dimension} nodes ({params.ants} ants, {params.iterations} iterations)",
            source=instance.name,
            field="DIMENSION",
        )
    except ValueError as exc:  # ConfigError is a ValueError
        print(f"{_PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    summary = solve_runs(instance, params, runs=args.runs, seed=args.seed, progress=not args.json)
    if args.json:
        print(json.dumps(summary.to_json(args.seed, params)))
    else:
        _print_table(summary, args.seed)
    return 0


def params_from_args(args: argparse.Namespace) -> ACOParams:
    """ACOParams from the command line, defaults where an option is not given."""
    overrides: dict[str, object] = {}
    for option, name in _NUMERIC_OPTIONS:
        value = getattr(args, option)
        if value is not None:
            overrides[name] = value
    if args.schedule is not None:
        overrides["schedule"] = _SCHEDULES[args.schedule]
    if args.local_search is not None:
        overrides["local_search"] = _LOCAL_SEARCHES[args.local_search]
    try:
        return ACOParams(**overrides)  # type: ignore[arg-type]
    except pydantic.ValidationError as exc:  # name the option the user typed, not the field
        err = from_pydantic(exc, source=None, data=overrides)
        option = next((o for o, name in _NUMERIC_OPTIONS if name == err.field), err.field or "option")
        raise ConfigError(err.detail, source=f"--{option}") from None


def solve_runs(instance: TSPInstance, params: ACOParams, *, runs: int, seed: int, progress: bool = False) -> RunSummary:
    """Run ``runs`` independent colonies, run i seeded with ``seed + i``."""
    dist = instance.distance_matrix()
    solve_tsp(dist, params.model_copy(update={"iterations": 1}), seed=seed)  # JIT load, untimed
    lengths: list[float] = []
    times: list[float] = []
    best_tour: tuple[int, ...] = ()
    for i in tqdm(range(runs), desc=instance.name, unit="run", file=sys.stderr, disable=not progress):
        start = time.perf_counter()
        result = solve_tsp(dist, params, seed=seed + i)
        times.append(time.perf_counter() - start)
        if not lengths or result.length < min(lengths):
            best_tour = tuple(int(c) for c in result.tour)
        lengths.append(result.length)
    return RunSummary(instance.name, tuple(lengths), tuple(times), best_tour, instance.optimum)


def _params_json(params: ACOParams) -> dict[str, object]:
    """Parameters as JSON values (enums by their value)."""
    return params.model_dump(mode="json")


def _one_line(exc: BaseException) -> str:
    """The exception's message on one line."""
    return " ".join(str(exc).split())


def _print_table(summary: RunSummary, seed: int) -> None:
    """Per-run lengths and times, then the summary, on stdout."""
    print(f"{'run':>4} {'seed':>6} {'length':>12} {'time_s':>8}")
    for i, (length, secs) in enumerate(zip(summary.lengths, summary.times_s)):
        print(f"{i:>4} {seed + i:>6} {length:>12.1f} {secs:>8.2f}")
    optimum = "unknown" if summary.optimum is None else f"{summary.optimum:g}"
    gap = "n/a" if summary.gap_percent is None else f"{summary.gap_percent:.2f} %"
    print(
        f"{summary.instance}: mean {summary.mean:.2f}, std {summary.std:.2f}, "
        f"best {summary.best:g}, optimum {optimum}, gap of the mean {gap}, "
        f"mean time {np.mean(summary.times_s):.2f} s/run"
    )
