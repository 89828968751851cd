#!/usr/bin/env python3
"""Ablation of the construction planners' on/off switches on the benchmark's holdout split.

    python scripts/planner_ablation.py [--out runs/planner-ablation] [--workers 2] [--only NAME ...]
        [--baseline docs/results/data/benchmarks/construction-v1-holdout.json]
        [--table docs/results/data/planner_ablation.json]

Each configuration is the split's runs of one planner with one switch (or a named group) off
(``--set planner.params.SWITCH=false``), run by ``pybullet_swarm.experiment.ablation`` into
``OUT/abl-PLANNER-NAME`` (resumable), and paired with the baseline: the committed holdout benchmark
of main, every switch on, on the runs both have. A switch whose row does not pay is deleted
(docs/guides/benchmark.md).

``CONFIGS`` lists the switches as the planners had them at the commit the table names; switches
deleted since are named as they were, so the table keeps its history (later commits refuse them).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from pybullet_swarm.experiment import ablation, benchmark

#: planner -> switches ablated one by one (layered_stigmergy's own; it shares stigmergy's others)
SWITCHES: dict[str, tuple[str, ...]] = {
    "stigmergy": (
        "claims",
        "claims_by_load",
        "wide_view",
        "layout_altitudes",
        "leave_boxes_by_structure",
        "drift_breakoff",
        "loose_box_check",
        "retake",
        "release_over_neighbours",
        "raise_drop_point",
        "clear_spent_goals",
        "search_near",
        "queue_at_slots",
        "mark_seen_slots",
    ),
    "layered_stigmergy": ("footprint", "ahead_cone", "detour", "replan_climb"),
}

#: the configurations: one switch off at a time
CONFIGS = [
    ablation.switched_off(f"switch: {s} ({planner})", planner, "planner.params", [s])
    for planner, switches in SWITCHES.items()
    for s in switches
]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("runs/planner-ablation"))
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--only", nargs="*", default=[], help="run only these configurations (directory names)")
    ap.add_argument("--baseline", type=Path, default=Path("docs/results/data/benchmarks/construction-v1-holdout.json"))
    ap.add_argument("--table", type=Path, default=None, help="write the results table JSON here")
    args = ap.parse_args()
    configs = [c for c in CONFIGS if not args.only or c.slug in args.only]
    base = benchmark.read_benchmark(args.baseline)
    results = ablation.run_ablation(configs, args.out, workers=args.workers, baseline=base)
    data = ablation.results_table(
        results,
        configs,
        title="Construction planners' switches on the holdout split (one switch off against every switch on)",
        command="python scripts/planner_ablation.py",
        notes=[
            f"Baseline: {args.baseline.as_posix()} (commit {str(base.get('commit', ''))[:10]}), every switch on; "
            "each configuration: the split's 2 seeds on its 21 generated layouts, with orca, paired on the runs "
            "both have.",
        ],
    )
    for row in data["rows"]:
        print(" | ".join(str(c) for c in row))
    if args.table is not None:
        args.table.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
        print(args.table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
