#!/usr/bin/env python3
"""Reproduce the thesis tables 5.3 (3-D stigmergy) and 6.2 (layered stigmergy) over many seeds.

    python scripts/reproduce_thesis.py [--seeds 20] [--workers 2] [--out runs/thesis] [--set key=value ...]

Runs shortest_path, stigmergy and layered_stigmergy on ``construction.yaml`` through the sweep
machinery (resumable: run it again to add seeds or finish an interrupted batch) and prints, per
planner, collisions, completion time and utility of space as mean +- std and 95 % t-interval
next to the thesis's single-run values. Collisions are reported three ways: the thesis's own
count (``thesis_collisions``: per agent, the times its nearest-neighbour distance curve drops
below the collision line of one agent diameter, summed over agents, as its Figure 3.12 counts),
the pair onsets of the same criterion (``proximity_violations``, about half of it: one onset per
pair, not per agent) and contact onsets between airframes (``collisions.agent_agent``). Utility
of space is our reading of a metric the thesis does not define; ``nn_distance_diameters`` (mean
nearest-neighbour distance in agent diameters) is reported beside it as a proximity-based reading.
``--set planner.params.preset=thesis`` runs the thesis's algorithms without our extensions. Also reports the spread of the random
search phase (time until the first box is found, i.e. the first grasp; the thesis saw 6-31 s).
Writes ``OUT/thesis_table.csv`` and ``OUT/thesis_comparison.png``.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path

import numpy as np

from pybullet_swarm.experiment.summary import describe
from pybullet_swarm.experiment.sweep import Sweep, run_sweep

#: the thesis's single runs (tables 5.3 and 6.2; shortest path from chapter 3)
THESIS = {
    "stigmergy": {"collisions": 18, "completion_time_s": 120.1, "utility_of_space": 0.74},
    "layered_stigmergy": {"collisions": 23, "completion_time_s": 242.8, "utility_of_space": 0.78},
}
PLANNERS = ("shortest_path", "stigmergy", "layered_stigmergy")
METRICS = (
    ("thesis_collisions", "collisions (thesis count, per agent)"),
    ("proximity_violations", "proximity onsets (per pair)"),
    ("collisions.agent_agent", "contact onsets agent-agent"),
    ("completion_time_s", "completion time [s]"),
    ("utility_of_space", "utility of space (our reading)"),
    ("nn_distance_diameters", "mean NN distance [diameters]"),
    ("search_phase_s", "random search phase [s]"),
)


def first_grasp(run_dir: Path) -> float:
    """Time of the first grasp in a run's events.csv (NaN when there is none)."""
    path = run_dir / "events.csv"
    if not path.is_file():
        return math.nan
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            if row["kind"] == "grasp":
                return float(row["time_s"])
    return math.nan


def _value(row: dict, key: str) -> float:
    v = row.get(key)
    try:
        return float(v) if v not in (None, "") else math.nan
    except (TypeError, ValueError):
        return math.nan


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("runs/thesis"))
    ap.add_argument("--planners", default=",".join(PLANNERS))
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    planners = tuple(p for p in args.planners.split(",") if p)
    sweep = Sweep("construction", planners=planners, seeds=args.seeds, overrides=args.overrides)
    result = run_sweep(sweep, args.out, workers=args.workers, quiet=args.quiet)
    rows = [dict(r) for r in result.rows]
    for r in rows:
        r["search_phase_s"] = first_grasp(result.out / str(r.get("run_dir", "")))
    table = []
    print(f"\nconstruction.yaml, {args.seeds} seeds per planner (mean +- std [95 % t-interval]; thesis: one run)")
    for planner in planners:
        mine = [r for r in rows if r.get("planner") == planner]
        done = sum(1 for r in mine if r.get("exit_status") == "completed")
        print(f"\n{planner}: {done}/{len(mine)} completed")
        for key, label in METRICS:
            vals = np.array([_value(r, key) for r in mine])
            if key == "completion_time_s":
                vals = vals[np.isfinite(vals)]
            s = describe(vals)
            thesis = THESIS.get(planner, {}).get("collisions" if key == "thesis_collisions" else key)
            extra = f"   thesis {thesis:g}" if thesis is not None else ""
            if key == "search_phase_s" and s.n:
                extra = f"   range {np.nanmin(vals):.1f}-{np.nanmax(vals):.1f} s (thesis 6-31 s)"
            print(f"  {label:38s} {s.mean:8.3g} +- {s.std:<8.3g} [{s.ci95_low:.3g}, {s.ci95_high:.3g}]  n={s.n}{extra}")
            table.append(
                {
                    "planner": planner,
                    "metric": key,
                    "n": s.n,
                    "mean": s.mean,
                    "std": s.std,
                    "ci95_low": s.ci95_low,
                    "ci95_high": s.ci95_high,
                    "median": s.median,
                    "thesis": thesis,
                    "completed": done,
                    "runs": len(mine),
                }
            )
    out_csv = result.out / "thesis_table.csv"
    with open(out_csv, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(table[0]))
        w.writeheader()
        w.writerows(table)
    fig_path = _figure(table, planners, result.out / "thesis_comparison.png")
    print(f"\n{out_csv}\n{fig_path}")
    return 0


def _figure(table: list[dict], planners: tuple[str, ...], path: Path) -> Path:
    from pybullet_swarm.plotting.thesis_plots import thesis_comparison_figure

    return thesis_comparison_figure(table, planners, path)


if __name__ == "__main__":
    sys.exit(main())
