#!/usr/bin/env python3
"""ORCA ablation on the construction benchmark's holdout split: stages, then rules within them.

    python scripts/orca_stage_ablation.py [--out runs/orca-ablation] [--seeds 2] [--workers 2]
        [--only NAME ...] [--table docs/results/data/orca_ablation.json]

Each configuration is the split's runs of one planner (stigmergy, or the one it names) with some of
the layer's rules switched off (``--set avoidance_params.RULE=false``), run by
``pybullet_swarm.experiment.benchmark`` into ``OUT/abl-NAME`` (resumable: run the same command again
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
import datetime
import json
from pathlib import Path
from typing import Any

from pybullet_swarm.experiment import benchmark

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

#: the metrics of the table: (key in compare's output, column, True when a rise is worse)
METRICS = (
    ("completion_rate", "completion", False),
    ("stall_rate", "stalls", True),
    ("contact_rate_agent_agent", "a-a contact", True),
    ("contact_rate_any", "any contact", True),
    ("median_time_s", "median time [s]", True),
)


def planner_of(name: str) -> str:
    """The planner of a configuration."""
    return name[name.rindex("(") + 1 : -1] if name.endswith(")") else "stigmergy"


def slug(name: str) -> str:
    """Directory name of a configuration."""
    words = name.split(": ", 1)[1].split(" (")[0].replace(", ", "+")
    return words if planner_of(name) == "stigmergy" else f"{planner_of(name)}-{words}"


def run_all(args: argparse.Namespace) -> dict[str, dict[str, Any]]:
    """Run (or resume) the baselines and every configuration; returns name -> compare result."""
    bases: dict[str, dict[str, Any]] = {}
    results = {}
    for name, rules in CONFIGS.items():
        if args.only and slug(name) not in args.only:
            continue
        planner = planner_of(name)
        if planner not in bases:
            bases[planner] = benchmark.run_benchmark(
                "construction", "holdout", args.out / "base", workers=args.workers, figure=False,
                variant=benchmark.Variant(planners=(planner,), seeds=BASELINE_SEEDS[planner]),
            ).data  # fmt: skip
        base = bases[planner]
        variant = benchmark.Variant(
            planners=(planner,), seeds=args.seeds, overrides=tuple((f"avoidance_params.{r}", False) for r in rules)
        )
        res = benchmark.run_benchmark(
            "construction", "holdout", args.out / f"abl-{slug(name)}", workers=args.workers, figure=False,
            variant=variant,
        )  # fmt: skip
        results[name] = benchmark.compare(base, res.data)
    return results


def verdict(metrics: dict[str, Any]) -> str:
    """``pays`` when switching the rules off made a primary metric significantly worse."""
    worse = [
        col
        for key, col, rise_is_worse in METRICS
        if key in metrics and metrics[key]["significant"] and (metrics[key]["diff"] > 0) == rise_is_worse
    ]
    return "pays (" + ", ".join(worse) + ")" if worse else "does not pay"


def table(results: dict[str, dict[str, Any]], args: argparse.Namespace) -> dict[str, Any]:
    """The results table (docs/results/data schema) of the comparisons."""
    rows = []
    commit = ""
    for name, res in results.items():
        (conf,) = res["configurations"]
        commit = commit or str(res["a"].get("commit", ""))
        m = conf["metrics"]
        cells: list[Any] = [name, ", ".join(CONFIGS[name]), conf["pairs"]]
        for key, _, _ in METRICS:
            x = m.get(key)
            if x is None or x["ci"] is None:
                cells.append("-")
                continue
            star = " *" if x["significant"] else ""
            cells.append(f"{x['a']:.3g} -> {x['b']:.3g} [{x['ci'][0]:+.3g}, {x['ci'][1]:+.3g}]{star}")
        cells.append(verdict(m))
        rows.append(cells)
    return {
        "title": "ORCA ablation on the construction holdout split (rules off against every rule on)",
        "command": f"python scripts/orca_stage_ablation.py --seeds {args.seeds}",
        "commit": commit[:10],
        "date": datetime.date.today().isoformat(),
        "columns": ["configuration", "rules off", "pairs", *(c for _, c, _ in METRICS), "verdict"],
        "rows": rows,
        "notes": [
            "Each cell: all rules on -> these rules off, over the paired runs (layout and seed), with the paired "
            "bootstrap 95 % interval of the difference; * marks an interval that excludes zero.",
            "Planner stigmergy + orca unless the configuration names another. Baseline: "
            + ", ".join(f"{p} {n}" for p, n in BASELINE_SEEDS.items())
            + f" seeds per layout; each configuration: {args.seeds} seeds per layout (21 generated layouts), "
            "paired on the runs both have.",
            "A configuration pays when switching it off makes a primary metric significantly worse; rules in "
            "configurations that do not pay were deleted (docs/guides/benchmark.md).",
        ],
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("runs/orca-ablation"))
    ap.add_argument("--seeds", type=int, default=2, help="seeds per layout of each configuration")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--only", nargs="*", default=[], help="run only these configurations (directory names)")
    ap.add_argument("--table", type=Path, default=None, help="write the results table JSON here")
    args = ap.parse_args()
    results = run_all(args)
    data = table(results, args)
    for row in data["rows"]:
        print(" | ".join(str(c) for c in row))
    if args.table is not None:
        args.table.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
        print(args.table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
