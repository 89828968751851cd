"""The thesis's optimisation sub-problem: tune both stigmergy planners with the same budget, then
compare tuned against default on fresh held-out seeds.

Each planner gets one Optuna study (TPE by default) over the parameters the thesis names: trail
value, fatigue, view radius, local search radius and, for ``layered_stigmergy``, the strength of
the second (presence) layer. Every trial runs the construction task over the same K seeds; the
first trial of each study is the planner's default configuration. Then the default and the tuned
configuration of each planner run over held-out seeds that no trial saw, and the objective's mean,
its 95 % t-interval and the paired difference (same seeds) are reported. Last, a multi-objective
study per planner (completion time against agent-agent collisions) re-scores that planner's trials
from the runs already recorded, adds ``--pareto-trials`` NSGA-II trials and draws the Pareto front.

Everything resumes: run the same command again after a kill and only what is missing runs; a larger
``--trials`` adds trials to the studies (the held-out comparison then uses the new best trial). Other
seeds per trial make other studies: give them another ``--out``.

    python scripts/tune_thesis.py                                     # this session's budget: 30 trials x 2 seeds
    python scripts/tune_thesis.py --trials 60 --seeds-per-trial 3     # the issue's full budget

Outputs (``--out``, default ``runs/tune_thesis``): ``<planner>/`` (each study: study.db, runs.csv,
trials.csv, best.yaml, plots/history.png, plots/importance.png), ``<planner>-pareto/`` (trials.csv,
pareto/trial-<n>.yaml, plots/pareto.png), ``eval/`` (held-out sweeps), ``comparison.csv``,
``comparison.md`` and ``tuned_vs_default.png``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from pybullet_swarm.experiment.rundir import atomic_write, write_json
from pybullet_swarm.experiment.summary import describe
from pybullet_swarm.experiment.sweep import Sweep, run_sweep
from pybullet_swarm.tuning import TuneSpec, run_tuning
from pybullet_swarm.tuning.objective import DEFAULT_OBJECTIVE, DEFAULT_PENALTY, parse_objectives, score_run
from pybullet_swarm.tuning.outputs import best_overrides

SCENARIO = "construction"
AGENT_RADIUS = 0.15 / 2**0.5  # m, quad150: half the diagonal of its 15 cm x 15 cm frame

# The thesis's parameters (Tables 5.1, 5.2 and 6.1), their defaults and the ranges searched.
COMMON = {
    "planner.params.trail_pheromone": ("0.0:0.8", 0.2),  # constant (trail) pheromone; boxes are +1
    "planner.params.fatigue": ("0.0:0.03", 0.0),  # /s, task-layer fading (+1 lasts >= 33 s)
    "task.view_radius": ("0.1:0.4", 2 * AGENT_RADIUS),  # m, the thesis's 2 agent radii
    "planner.params.local_radius": ("0.05:0.6", 0.2),  # m, local search square half-width
}
LAYERED = {
    "planner.params.presence_pheromone": ("0.5:6.0", 2.0),  # second-layer strength (fades at 2/s)
}


def space(planner: str) -> dict[str, tuple[str, float]]:
    """The tuned keys of a planner: ``{key: (range, default)}``."""
    return {**COMMON, **(LAYERED if planner == "layered_stigmergy" else {})}


def tune(planner: str, args: argparse.Namespace) -> Any:
    """Run (or resume) one planner's study."""
    keys = space(planner)
    spec = TuneSpec(
        SCENARIO,
        params=[f"{k}={r}" for k, (r, _) in keys.items()],
        planner=planner,
        objectives=[args.objective],
        trials=args.trials,
        seeds_per_trial=args.seeds_per_trial,
        sampler=args.sampler,
        sampler_seed=args.sampler_seed,
        penalty=args.penalty,
        baseline={k: d for k, (_, d) in keys.items()},
    )
    return run_tuning(spec, args.out / planner, workers=args.workers, executor=args.executor, quiet=args.quiet)


def pareto(planner: str, single: Any, args: argparse.Namespace) -> Any:
    """The multi-objective study of a planner: completion time against agent-agent collisions (NSGA-II).

    It shares the single-objective study's directory: its first trials are that study's trials,
    scored again on both objectives from the runs already recorded (no simulation), then
    ``--pareto-trials`` NSGA-II trials follow.
    """
    keys = space(planner)
    seen = [{k: t[k] for k in keys} for t in single.trials if t["state"] == "complete" and not t["baseline"]]
    spec = TuneSpec(
        SCENARIO,
        params=[f"{k}={r}" for k, (r, _) in keys.items()],
        planner=planner,
        objectives=["completion_time_s", "collisions.agent_agent"],
        trials=1 + len(seen) + args.pareto_trials,
        seeds_per_trial=args.seeds_per_trial,
        sampler="nsga2",
        sampler_seed=args.sampler_seed,
        penalty=args.penalty,
        study_name=f"construction-{planner}-pareto",
        baseline={k: d for k, (_, d) in keys.items()},
        enqueue=seen,
    )
    out = args.out / f"{planner}-pareto"
    return run_tuning(
        spec,
        args.out / planner,
        workers=args.workers,
        executor=args.executor,
        quiet=args.quiet,
        figures=True,
        outputs=out,
    )


def evaluate(planner: str, result: Any, args: argparse.Namespace) -> list[dict[str, Any]]:
    """Default and tuned configuration over the held-out seeds: per-run objective values and statistics."""
    objective = parse_objectives([args.objective])
    seeds = range(args.eval_seed_start, args.eval_seed_start + args.eval_seeds)
    best = result.best[0]
    tuned = {
        k: v
        for k, v in best_overrides(best, result.spec, planner=planner, avoidance=result.avoidance).items()
        if k not in ("planner.name", "avoidance")
    }
    values: dict[str, dict[int, float]] = {}
    for config, overrides in (("default", {}), ("tuned", tuned)):
        sweep = Sweep(SCENARIO, planners=(planner,), seeds=seeds, overrides=overrides)
        name = f"{planner}-default" if config == "default" else f"{planner}-tuned-trial{best['trial']}"
        res = run_sweep(
            sweep,
            args.out / "eval" / name,
            workers=args.workers,
            executor=args.executor,
            figures=False,
            quiet=args.quiet,
        )
        values[config] = {
            int(r["seed"]): score_run(objective, r, args.penalty)[0]
            for r in res.rows
            if r.get("exit_status") != "error"
        }
    common = sorted(set(values["default"]) & set(values["tuned"]))
    out = []
    for config in ("default", "tuned"):
        v = [values[config][s] for s in common]
        st = describe(v)
        out.append(
            {
                "planner": planner,
                "config": config,
                "n": st.n,
                "mean": st.mean,
                "ci95_low": st.ci95_low,
                "ci95_high": st.ci95_high,
                "values": v,
                "trial": best["trial"] if config == "tuned" else None,
                "overrides": tuned if config == "tuned" else {},
            }
        )
    diff = describe([values["tuned"][s] - values["default"][s] for s in common])
    out.append(
        {
            "planner": planner,
            "config": "tuned - default (paired)",
            "n": diff.n,
            "mean": diff.mean,
            "ci95_low": diff.ci95_low,
            "ci95_high": diff.ci95_high,
            "values": [],
            "trial": None,
            "overrides": {},
        }
    )
    return out


def write_tables(rows: list[dict[str, Any]], args: argparse.Namespace) -> list[Path]:
    """``comparison.csv``, ``comparison.md`` and ``tuned_vs_default.png``."""
    from pybullet_swarm.plotting.tuning_plots import plot_tuned_vs_default

    cols = ["planner", "config", "n", "mean", "ci95_low", "ci95_high", "trial", "overrides"]
    lines = [",".join(cols)]
    for r in rows:
        cells = [
            json.dumps(r[c], sort_keys=True) if c == "overrides" else ("" if r[c] is None else str(r[c])) for c in cols
        ]
        lines.append(",".join(f'"{c}"' if "," in c or '"' in c else c for c in (x.replace('"', '""') for x in cells)))
    csv_path = args.out / "comparison.csv"
    atomic_write(csv_path, lambda fh: fh.write("\n".join(lines) + "\n"))
    md = [
        f"Objective `{args.objective}` (incomplete runs: completion time = time reached + {args.penalty:g}), "
        f"held-out seeds {args.eval_seed_start}..{args.eval_seed_start + args.eval_seeds - 1}; budget "
        f"{args.trials} trials x {args.seeds_per_trial} seeds per planner ({args.sampler}).",
        "",
        "| planner | configuration | n | mean | 95 % CI |",
        "|---|---|---:|---:|---|",
    ]
    md += [
        f"| {r['planner']} | {r['config']} | {r['n']} | {r['mean']:.1f} | [{r['ci95_low']:.1f}, {r['ci95_high']:.1f}] |"
        for r in rows
    ]
    md_path = args.out / "comparison.md"
    atomic_write(md_path, lambda fh: fh.write("\n".join(md) + "\n"))
    fig = plot_tuned_vs_default(
        [r for r in rows if r["config"] in ("default", "tuned")],
        args.out / "tuned_vs_default.png",
        ylabel=args.objective,
        title=f"construction, {args.eval_seeds} held-out seeds",
    )
    return [csv_path, md_path, fig]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--trials", type=int, default=30, help="trials per planner (default 30)")
    p.add_argument("--seeds-per-trial", type=int, default=2, help="seeds per trial (default 2)")
    p.add_argument("--eval-seeds", type=int, default=10, help="held-out seeds of the comparison (default 10)")
    p.add_argument("--eval-seed-start", type=int, default=1000, help="first held-out seed (default 1000)")
    p.add_argument(
        "--pareto-trials",
        type=int,
        default=4,
        help="NSGA-II trials after the re-scored trials of each multi-objective study (default 4)",
    )
    p.add_argument("--planners", default="stigmergy,layered_stigmergy")
    p.add_argument("--objective", default=DEFAULT_OBJECTIVE)
    p.add_argument("--penalty", type=float, default=DEFAULT_PENALTY)
    p.add_argument("--sampler", default="tpe", choices=("tpe", "nsga2", "cmaes", "random"))
    p.add_argument("--sampler-seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=None)
    p.add_argument("--executor", default="local", choices=("local", "ray"))
    p.add_argument("--out", type=Path, default=Path("runs/tune_thesis"))
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    args.out = args.out.resolve()
    planners = [s.strip() for s in args.planners.split(",") if s.strip()]
    write_json(args.out / "budget.json", {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()})
    results = {planner: tune(planner, args) for planner in planners}
    rows: list[dict[str, Any]] = []
    for planner, result in results.items():
        print(
            f"{planner}: best trial {result.best[0]['trial']}, objective {result.best[0]['value']:.1f} "
            f"on the tuning seeds; {args.out / planner / 'best.yaml'}",
            flush=True,
        )
        rows += evaluate(planner, result, args)
    files = write_tables(rows, args)
    for planner, result in results.items():
        files += [f for f in pareto(planner, result, args).files if f.name == "pareto.png"]
    print((args.out / "comparison.md").read_text())
    for f in files:
        print(f)
    return 0


if __name__ == "__main__":  # workers are fresh processes that import the script
    sys.exit(main())
