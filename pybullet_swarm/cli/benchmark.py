"""``pybullet-swarm benchmark SUITE --split dev|holdout`` and ``pybullet-swarm benchmark compare A.json B.json``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from pybullet_swarm.cli import add_overrides_option
from pybullet_swarm.errors import ConfigError

USAGE = (
    "pybullet-swarm benchmark SUITE --split dev|holdout [--workers K] [--executor ray] [--dry-run] [--out DIR]\n"
    "       [--planners A,B] [--seeds N] [--set KEY.PATH=VALUE ...]\n"
    "       pybullet-swarm benchmark compare A.json B.json [--out FILE]"
)


def register(sub: Any) -> None:
    """Add the ``benchmark`` command to the sub-command parsers."""
    p = sub.add_parser(
        "benchmark",
        usage=USAGE,
        help="run a suite's dev or holdout split (resumable) and write its JSON, table and figure; or compare two",
        description="Run every layout x planner x avoidance x seed of a suite's split (scenarios/suites/), resumable, "
        "and write benchmark.json, benchmark.md and benchmark.png; `benchmark compare A.json B.json` gives paired "
        "differences B - A with bootstrap 95 % intervals.",
    )
    p.add_argument("suite", metavar="SUITE", help="suite file or bundled suite name (construction); or `compare`")
    p.add_argument("files", nargs="*", type=Path, metavar="JSON", help="with compare: the two benchmark JSON files")
    p.add_argument("--split", choices=("dev", "holdout"), default=None, help="which split to run")
    p.add_argument("--workers", type=int, default=None, metavar="K", help="parallel runs (default: the cores)")
    p.add_argument("--executor", choices=("local", "ray"), default="local", help="local process pool or Ray tasks")
    p.add_argument("--address", default=None, metavar="ADDR", help="Ray cluster address (with --executor ray)")
    p.add_argument("--dry-run", action="store_true", help="print the planned runs (layout, planner, avoidance, seed)")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="benchmark directory (default runs/benchmark-<suite>-v<version>-<split>); with compare: JSON file",
    )
    p.add_argument(
        "--planners",
        default=None,
        metavar="A,B",
        help="a study on the split: run only these of its planners (comma-separated)",
    )
    p.add_argument(
        "--seeds",
        type=int,
        default=None,
        metavar="N",
        help="a study on the split: N seeds from its first seed on, instead of its own (more runs per layout)",
    )
    add_overrides_option(
        p,
        "a study on the split: scenario override on top of the suite's (an ablation: "
        "avoidance_params.wake_column=false); a directory holds one set of overrides",
    )
    p.add_argument("--retry-failed", action="store_true", help="run again the runs recorded as errors")
    p.add_argument("--no-figure", action="store_true", help="skip benchmark.png")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no table")
    p.set_defaults(func=_cmd_benchmark)


def _cmd_benchmark(args: argparse.Namespace) -> int:
    if args.suite == "compare":
        return _cmd_compare(args)
    if args.files:
        raise ConfigError(f"takes one suite, got also {', '.join(map(str, args.files))}", source="benchmark")
    if args.split is None:
        raise ConfigError("is required: dev or holdout", source="--split")
    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"must be >= 1, got {args.workers}", source="--workers")
    if args.address is not None and args.executor != "ray":
        raise ConfigError("needs --executor ray", source="--address")
    from pybullet_swarm.experiment import benchmark
    from pybullet_swarm.experiment.scenario import parse_override

    variant = benchmark.Variant(
        planners=tuple(p.strip() for p in args.planners.split(",") if p.strip()) if args.planners else (),
        seeds=args.seeds,
        overrides=tuple(parse_override(o) for o in args.overrides),
    )
    if args.dry_run:
        plan = benchmark.plan_benchmark(args.suite, args.split, args.out, build=False, variant=variant)
        lines = plan.lines()
        print("\n".join(lines))
        if not args.quiet:
            print(
                f"{len(lines)} runs ({len(plan.split.layouts)} layouts x {len(plan.split.planners)} planners x "
                f"{len(plan.split.avoidance)} avoidance x {len(plan.split.seeds)} seeds) into {plan.out}",
                file=sys.stderr,
            )
        return 0
    if args.out is not None:
        from pybullet_swarm.experiment.rundir import check_output_dir

        check_output_dir(args.out, source="--out")
    result = benchmark.run_benchmark(
        args.suite,
        args.split,
        args.out,
        executor=args.executor,
        workers=args.workers,
        address=args.address,
        quiet=args.quiet,
        figure=not args.no_figure,
        retry_failed=args.retry_failed,
        variant=variant,
        command=" ".join(["pybullet-swarm", *(sys.argv[1:] if sys.argv[1:2] == ["benchmark"] else ["benchmark"])]),
    )
    if result.interrupted:
        print(
            f"pybullet-swarm: error: interrupted; {result.data['recorded_runs']} runs recorded in {result.out}; "
            "run the same command again to resume",
            file=sys.stderr,
        )
        return 130
    failed = sum(c["error"] for c in result.data["configurations"])
    if not args.quiet:
        print(benchmark.markdown_table(result.data))
        print(
            f"benchmark directory: {result.out} ({result.n_planned} runs: {result.n_run} run now, "
            f"{result.n_skipped} skipped; {result.wall_time_s:.1f} s)"
        )
        print("\n".join(str(f) for f in result.files))
    if failed:
        print(
            f"pybullet-swarm: error: {failed} runs failed to run (exit_status=error in {result.out / 'runs.csv'}; "
            "--retry-failed runs them again)",
            file=sys.stderr,
        )
        return 1
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from pybullet_swarm.experiment import benchmark

    if len(args.files) != 2:
        raise ConfigError(f"takes two benchmark JSON files (A B), got {len(args.files)}", source="benchmark compare")
    if args.split is not None or args.dry_run:
        raise ConfigError("--split and --dry-run are for running a suite, not for compare", source="benchmark compare")
    a, b = (benchmark.read_benchmark(f) for f in args.files)
    result = benchmark.compare(a, b)
    if args.out is not None:
        from pybullet_swarm.experiment.rundir import write_json

        write_json(args.out, result)
    if not args.quiet:
        print(benchmark.compare_table(result))
        for note in result["notes"]:
            print(f"note: {note}")
        if args.out is not None:
            print(args.out)
    elif args.out is None:
        print(json.dumps(result, indent=1))
    return 0
