"""Construction table of issue 5: planners x {none, orca} over many seeds, mean and 95 % t-interval.

Usage::

    python scripts/orca_table.py                       # every registered construction planner, 20 seeds
    python scripts/orca_table.py --seeds 50 --planners shortest_path --avoidance orca
    python scripts/orca_table.py --set collisions=physical --json out.json

The runs go through the sweep machinery (``pybullet_swarm.experiment.sweep``): a process pool
of ``--workers``, rows appended to ``OUT/runs.csv`` as runs finish, and running the same command
again resumes an interrupted table instead of starting over.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
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


def table_row(row: dict[str, Any]) -> dict[str, Any]:
    """The numbers of the table from a sweep row (flattened metrics)."""

    def num(key: str) -> float | None:
        v = row.get(key)
        try:
            return None if v in (None, "") else float(v)
        except (TypeError, ValueError):
            return None

    aa = num("collisions.agent_agent") or 0.0
    total = num("collisions.total") or 0.0
    out = {
        "planner": row.get("planner"),
        "avoidance": row.get("avoidance"),
        "seed": int(row.get("seed", -1)),
        "exit_status": row.get("exit_status"),
        "agent_agent": int(aa),
        "other_collisions": int(total - aa),
        "proximity_violations": num("proximity_violations"),
        "completion_time_s": num("completion_time_s"),
        "utility_of_space": num("utility_of_space"),
        "min_separation_m": num("min_separation_m"),
        "boxes_placed": num("boxes_placed"),
    }
    out.update({k: row[k] for k in row if str(k).startswith("orca_")})
    return out


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
        out.append(
            f"{planner} + {avoidance}  ({len(rs)} seeds; "
            + ", ".join(f"{k} {v}" for k, v in sorted(status.items()))
            + ")"
        )
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
    ap.add_argument("--out", type=Path, default=None, help="sweep directory (default: runs/sweep-<scenario>-<hash>)")
    args = ap.parse_args(argv)
    if args.seeds < 1 or args.workers < 1:
        ap.error("--seeds and --workers must be >= 1")

    from pybullet_swarm.planning.registry import planners

    known = planners()
    wanted = args.planners if args.planners else [p for p in PLANNERS if p in known]
    missing = [p for p in wanted if p not in known]
    if missing:
        ap.error(f"planners not registered: {', '.join(missing)}")
    from pybullet_swarm.experiment.sweep import Sweep, run_sweep

    sweep = Sweep(
        args.scenario,
        planners=tuple(wanted),
        avoidance=tuple(args.avoidance),
        seeds=tuple(range(args.seed_start, args.seed_start + args.seeds)),
        overrides=args.overrides,
    )
    result = run_sweep(sweep, args.out, workers=args.workers, quiet=False, figures=False)
    rows = [
        table_row(dict(r)) for r in result.rows if r.get("planner") in wanted and r.get("avoidance") in args.avoidance
    ]
    order = {(p, a): i for i, (p, a) in enumerate((p, a) for p in wanted for a in args.avoidance)}
    rows.sort(key=lambda r: (order[(r["planner"], r["avoidance"])], r["seed"]))
    print(table(rows))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
