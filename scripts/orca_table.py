"""Construction table of issue 5: planners x {none, orca} over many seeds, mean and 95 % t-interval.

Usage::

    python scripts/orca_table.py                       # every registered construction planner, 20 seeds
    python scripts/orca_table.py --seeds 50 --planners shortest_path --avoidance orca
    python scripts/orca_table.py --set collisions=physical --json out.json

Each run is ``pybullet_swarm.run(scenario, planner=..., avoidance=..., seed=...)`` in a process
pool (``--workers``); only a few numbers per run travel back. The sweep machinery of the
project will replace the pool.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import math
import sys
from collections import Counter
from typing import Any

import numpy as np
from scipy import stats

#: planners of the table (those not registered are left out)
PLANNERS = ("shortest_path", "stigmergy", "layered_stigmergy")
#: (label, getter) of the metrics in the table
METRICS: tuple[tuple[str, str], ...] = (
    ("agent_agent", "agent_agent collision events"),
    ("proximity_violations", "proximity violations"),
    ("completion_time_s", "completion time, s (completed runs)"),
    ("utility_of_space", "utility of space"),
    ("other_collisions", "other collision events (box, structure, ground)"),
    ("min_separation_m", "closest approach of two centres, m"),
)


def run_one(scenario: str, planner: str, avoidance: str, seed: int, overrides: list[str]) -> dict[str, Any]:
    """Run one simulation and keep the numbers of the table."""
    import pybullet_swarm as ps

    m = ps.run(scenario, planner=planner, avoidance=avoidance, seed=seed, overrides=overrides).metrics
    coll = m.get("collisions", {})
    return {
        "planner": planner, "avoidance": avoidance, "seed": seed,
        "exit_status": m["exit_status"],
        "agent_agent": coll.get("agent_agent", 0),
        "other_collisions": sum(v for k, v in coll.items() if k != "agent_agent"),
        "proximity_violations": m.get("proximity_violations"),
        "completion_time_s": m.get("completion_time_s"),
        "utility_of_space": m.get("utility_of_space"),
        "min_separation_m": m.get("min_separation_m"),
        "boxes_placed": m.get("boxes_placed"),
        **{k: v for k, v in m.items() if k.startswith("orca_")},
    }


def mean_ci(values: list[float], level: float = 0.95) -> tuple[float, float, int]:
    """Mean and half-width of the two-sided t-interval of ``values`` (nan half-width for n < 2)."""
    x = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if x.size == 0:
        return math.nan, math.nan, 0
    if x.size < 2:
        return float(x.mean()), math.nan, 1
    half = stats.t.ppf(0.5 + level / 2, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size)
    return float(x.mean()), float(half), int(x.size)


def table(rows: list[dict[str, Any]]) -> str:
    """The text table: one block per (planner, avoidance)."""
    out = []
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["planner"], r["avoidance"]), []).append(r)
    for (planner, avoidance), rs in groups.items():
        status = Counter(r["exit_status"] for r in rs)
        out.append(f"{planner} + {avoidance}  ({len(rs)} seeds; "
                   + ", ".join(f"{k} {v}" for k, v in sorted(status.items())) + ")")
        for key, label in METRICS:
            mean, half, n = mean_ci([r[key] for r in rs])
            extra = f"  [n={n}]" if n != len(rs) else ""
            out.append(f"    {label:<48} {mean:9.3f} +- {half:7.3f}{extra}")
        aa = [r["agent_agent"] for r in rs]
        out.append(f"    {'runs with agent_agent > 0':<48} {sum(a > 0 for a in aa):9d}   (max {max(aa)})")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    """Run the table and print it."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="construction")
    ap.add_argument("--seeds", type=int, default=20, help="number of seeds (default 20)")
    ap.add_argument("--seed-start", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--planners", nargs="*", default=None, help=f"default: the registered ones of {PLANNERS}")
    ap.add_argument("--avoidance", nargs="*", default=["none", "orca"])
    ap.add_argument("--set", dest="overrides", action="append", default=[], help="key.path=value override")
    ap.add_argument("--json", default=None, help="also write every run's numbers to this file")
    args = ap.parse_args(argv)
    if args.seeds < 1 or args.workers < 1:
        ap.error("--seeds and --workers must be >= 1")

    from pybullet_swarm.planning.registry import planners

    known = planners()
    wanted = args.planners if args.planners else [p for p in PLANNERS if p in known]
    missing = [p for p in wanted if p not in known]
    if missing:
        ap.error(f"planners not registered: {', '.join(missing)}")
    jobs = [(args.scenario, p, a, s, args.overrides) for p in wanted for a in args.avoidance
            for s in range(args.seed_start, args.seed_start + args.seeds)]
    rows: list[dict[str, Any]] = []
    with cf.ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = {pool.submit(run_one, *job): job for job in jobs}
        for k, fut in enumerate(cf.as_completed(futures), 1):
            rows.append(fut.result())
            print(f"\r{k}/{len(jobs)} runs", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    order = {(p, a): i for i, (p, a) in enumerate((p, a) for p in wanted for a in args.avoidance)}
    rows.sort(key=lambda r: (order[(r["planner"], r["avoidance"])], r["seed"]))
    print(table(rows))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
