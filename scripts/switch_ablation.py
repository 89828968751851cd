#!/usr/bin/env python3
"""Ablation of on/off switches on the benchmark's holdout split: the construction planners' and ORCA's remaining ones.

    python scripts/switch_ablation.py [--out runs/switch-ablation] [--workers 2] [--only NAME ...]
        [--baseline docs/results/data/benchmarks/construction-v1-holdout-376f91a.json]
        [--table docs/results/data/switch_ablation.json]

Each configuration is the split's runs of one planner with one switch (or a named group) off
(``--set planner.params.SWITCH=false``, ``--set avoidance_params.RULE=false``), run by
``pybullet_swarm.experiment.ablation`` into ``OUT/abl-PLANNER-NAME`` (resumable), and paired with
the baseline: the committed holdout benchmark of main, every switch on, on the runs both have. A
switch whose row does not pay is deleted (docs/guides/benchmark.md). The ORCA rules here are those
``scripts/orca_stage_ablation.py`` did not ablate one by one (stigmergy + orca).

``CONFIGS`` lists the switches as the planners had them at the commit the table names; switches
deleted since are named as they were, so the table keeps its history (later commits refuse them).
"""

from __future__ import annotations

import argparse
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

#: (planner, name) -> switches off together: shortest_path's in groups of one purpose (its runs cost three
#: times stigmergy's); stigmergy's switches whose single rows did not pay with adverse point estimates
GROUPS: dict[tuple[str, str], tuple[str, ...]] = {
    ("stigmergy", "adverse single rows"): (
        "claims",
        "release_over_neighbours",
        "clear_spent_goals",
        "queue_at_slots",
    ),
    ("shortest_path", "placement"): (
        "retry_slots",
        "release_over_neighbours",
        "soft_landing",
        "recentre_box",
        "plumb_legs",
    ),
    ("shortest_path", "traffic"): ("swap_boxes", "round_parked"),
    ("shortest_path", "wake patches"): ("wait_away", "park_clear", "held_pass"),
    ("shortest_path", "waits"): ("wait_beside", "spaced_descents"),
}

#: ORCA rules not ablated one by one before (a rule whose patch would be left on goes off with it)
ORCA_RULES: tuple[tuple[str, ...], ...] = (
    ("passthrough_turns",),
    ("minimal_intervention",),
    ("floor_preferred",),
    ("column_tick",),
    ("floor_rule", "floor_preferred"),
    ("ground_beside",),
)

#: the configurations: one switch off at a time, or one of shortest_path's groups
CONFIGS = [
    *(
        ablation.switched_off(f"switch: {s} ({planner})", planner, "planner.params", [s])
        for planner, switches in SWITCHES.items()
        for s in switches
    ),
    *(
        ablation.switched_off(f"group: {g} ({planner})", planner, "planner.params", switches)
        for (planner, g), switches in GROUPS.items()
    ),
    *(
        ablation.switched_off(f"orca rules: {', '.join(rules)}", "stigmergy", "avoidance_params", rules)
        for rules in ORCA_RULES
    ),
]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("runs/switch-ablation"))
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--only", nargs="*", default=[], help="run only these configurations (directory names)")
    ap.add_argument(
        "--baseline", type=Path, default=Path("docs/results/data/benchmarks/construction-v1-holdout-376f91a.json")
    )
    ap.add_argument("--table", type=Path, default=None, help="write the results table JSON here")
    args = ap.parse_args()
    configs = [c for c in CONFIGS if not args.only or c.slug in args.only]
    base = benchmark.read_benchmark(args.baseline)
    results = ablation.run_ablation(configs, args.out, workers=args.workers, baseline=base)
    data = ablation.results_table(
        results,
        configs,
        title="Switches on the holdout split (one switch or group off against every switch on)",
        command="python scripts/switch_ablation.py",
        notes=[
            f"Baseline: {args.baseline.as_posix()} (commit {str(base.get('commit', ''))[:10]}), every switch on; "
            "each configuration: the split's 2 seeds on its 21 generated layouts, with orca, paired on the runs "
            "both have. ORCA rows: stigmergy + orca.",
        ],
    )
    ablation.report(data, args.table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
