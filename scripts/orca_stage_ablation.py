#!/usr/bin/env python3
"""ORCA ablation on the construction benchmark's holdout split: stages, then rules within them.

    python scripts/orca_stage_ablation.py [--out runs/orca-ablation] [--seeds 2] [--workers 2]
        [--only NAME ...] [--table docs/results/data/orca_ablation.json]

Each configuration is the split's runs of one planner (stigmergy, or the one it names) with some of
the layer's rules switched off (``--set avoidance_params.RULE=false``), run by
``pybullet_swarm.experiment.ablation`` into ``OUT/abl-NAME`` (resumable: run the same command again
to finish); the baseline, every rule on, into ``OUT/base`` (``BASELINE_SEEDS`` seeds per layout).
Each configuration is compared with the baseline on the runs both have (``benchmark compare``:
paired differences, bootstrap 95 % intervals).

A configuration is marked ``pays`` when switching its rules off makes a primary metric worse with
an interval that excludes zero (completion down, stalls or runs with a contact up, median time up);
the acceptance rule of docs/guides/benchmark.md keeps only such rules. The table is written as a
results table (``docs/results/data/NAME.json``, rendered by the docs) when ``--table`` is given.

The configurations are read from ``CONFIGS`` below: stages of rules as the layer had them when the
ablation was run, at the commit the table names (ed39819). Rules deleted since are listed by name,
so the table keeps its history; later commits refuse them, so the ablation reruns at that commit.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from pybullet_swarm.experiment import ablation

#: seeds per layout of the baseline of each planner
BASELINE_SEEDS = {"stigmergy": 4, "shortest_path": 2}

#: name -> the rules it switches off (stages, then single rules or groups within the stage that paid);
#: a name ending in ``(PLANNER)`` runs that planner instead of stigmergy
CONFIGS: dict[str, tuple[str, ...]] = {
    "stage: deadlock": (
        "sidestep",
        "climb_past",
        "make_way",
        "impatience",
        "climb_when_shorter",
        "side_memory",
        "pushed_back",
        "free_side",
    ),
    "rule: make_way": ("make_way",),
    "rule: impatience": ("impatience",),
    "rule: side_memory": ("side_memory",),
    "rule: pushed_back": ("pushed_back",),
    "rule: free_side": ("free_side",),
    "rules: climb_past, climb_when_shorter": ("climb_past", "climb_when_shorter"),
    "rules: make_way, impatience (shortest_path)": ("make_way", "impatience"),
    "stage: responsibility": (
        "weighted_way_out",
        "climb_over",
        "pinned_share",
        "wake_share_by_approach",
        "wake_share_on_course",
    ),
    "stage: bounds": ("floor_rule", "column_rule", "ground_beside"),
    "stage: inflation": ("lag_margin", "headway", "margin_overlap"),
    "stage: fallback": ("gap_weighted_fallback", "clipped_reference"),
    "stage: passthrough": ("passthrough", "passthrough_turns", "minimal_intervention"),
    "stage: wake": ("wake_column",),
    "rule: weighted_way_out": ("weighted_way_out",),
    "rules: wake_share_by_approach, wake_share_on_course": ("wake_share_by_approach", "wake_share_on_course"),
    "rule: pinned_share": ("pinned_share",),
    "rule: margin_overlap": ("margin_overlap",),
    "rule: headway": ("headway",),
    "rule: clipped_reference": ("clipped_reference",),
}


def planner_of(name: str) -> str:
    """The planner of a configuration."""
    return name[name.rindex("(") + 1 : -1] if name.endswith(")") else "stigmergy"


def configurations(only: list[str]) -> list[ablation.Ablation]:
    """The configurations of ``CONFIGS`` (those whose directory name is in ``only``, when given)."""
    cfgs = [ablation.switched_off(n, planner_of(n), "avoidance_params", r) for n, r in CONFIGS.items()]
    return [c for c in cfgs if not only or c.slug in only]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("runs/orca-ablation"))
    ap.add_argument("--seeds", type=int, default=2, help="seeds per layout of each configuration")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--only", nargs="*", default=[], help="run only these configurations (directory names)")
    ap.add_argument("--table", type=Path, default=None, help="write the results table JSON here")
    args = ap.parse_args()
    configs = configurations(args.only)
    results = ablation.run_ablation(
        configs, args.out, seeds=args.seeds, workers=args.workers, baseline_seeds=BASELINE_SEEDS
    )
    data = ablation.results_table(
        results,
        configs,
        title="ORCA ablation on the construction holdout split (rules off against every rule on)",
        command=f"python scripts/orca_stage_ablation.py --seeds {args.seeds}",
        notes=[
            "Planner stigmergy + orca unless the configuration names another. Baseline: "
            + ", ".join(f"{p} {n}" for p, n in BASELINE_SEEDS.items())
            + f" seeds per layout; each configuration: {args.seeds} seeds per layout (21 generated layouts), "
            "paired on the runs both have.",
        ],
    )
    ablation.report(data, args.table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
