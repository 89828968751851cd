#!/usr/bin/env python3
"""Ablation of on/off switches on the benchmark's holdout split: the construction planners' and ORCA's remaining ones.

    python scripts/switch_ablation.py [--round 1|2|2-six|3-six|4-six|estimated] [--out runs/switch-ablation-ROUND] [--workers 2]
        [--only NAME ...] [--baseline BENCHMARK.json] [--table docs/results/data/switch_ablation.json]

Each configuration is the split's runs of one planner with one switch (or a named group) off
(``--set planner.params.SWITCH=false``, ``--set avoidance_params.RULE=false``), run by
``pybullet_swarm.experiment.ablation`` into ``OUT/abl-PLANNER-NAME`` (resumable), and paired with
the baseline on the runs both have: the committed holdout benchmark of main, every switch on (rounds
1 and 2), or a run of it under the same condition (``estimated``: agents fly on their estimates). A
switch whose row does not pay is deleted (docs/guides/benchmark.md). The ORCA rules here are those
``scripts/orca_stage_ablation.py`` did not ablate one by one (stigmergy + orca).

``ROUNDS`` lists each round's switches as the planners had them at the commit its table names;
switches deleted since are named as they were, so the tables keep their history (later commits
refuse them, so a round reruns at its commit).
"""

from __future__ import annotations

import argparse
import dataclasses
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
}

#: ORCA rules not ablated one by one before
ORCA_RULES: tuple[tuple[str, ...], ...] = (
    ("passthrough_turns",),
    ("minimal_intervention",),
    ("floor_preferred",),
    ("column_tick",),
)

#: the stage ablation's rules kept with adverse estimates, off together (rounds 2 and 2-six)
STAGE_UNDECIDED = (
    "group: undecided ORCA rules of the stage ablation", "stigmergy", "avoidance_params",
    ("clipped_reference", "wake_share_by_approach", "wake_share_on_course", "margin_overlap"),
)  # fmt: skip

#: round 2 (a74ccbc, against the holdout benchmark after round 1's deletions): the switches round 1
#: did not run, and the undecided rows of both ablations switched off together
ROUND_2: tuple[tuple[str, str, str, tuple[str, ...]], ...] = (
    ("group: undecided ORCA rules", "stigmergy", "avoidance_params",
     ("passthrough_turns", "minimal_intervention", "column_tick", "floor_preferred")),
    STAGE_UNDECIDED,
    ("orca rules: floor_rule, floor_preferred", "stigmergy", "avoidance_params", ("floor_rule", "floor_preferred")),
    ("orca rule: ground_beside", "stigmergy", "avoidance_params", ("ground_beside",)),
    ("group: placement and traffic (shortest_path)", "shortest_path", "planner.params",
     ("retry_slots", "release_over_neighbours", "soft_landing", "recentre_box", "plumb_legs", "swap_boxes",
      "round_parked")),
    ("group: waits (shortest_path)", "shortest_path", "planner.params", ("wait_beside", "spaced_descents")),
    ("group: wake patches (shortest_path)", "shortest_path", "planner.params", ("wait_away", "park_clear", "held_pass")),
    ("switch: wake_lanes (shortest_path)", "shortest_path", "planner.params", ("wake_lanes",)),
    ("switch: wake_clear (shortest_path)", "shortest_path", "planner.params", ("wake_clear", "held_pass")),
)  # fmt: skip

#: flying on estimates (``sensing.state=estimated``, baseline run the same way): the switches built for it
ESTIMATED: tuple[tuple[str, str, str, tuple[str, ...]], ...] = (
    ("group: estimate rules (stigmergy)", "stigmergy", "planner.params", ("drift_breakoff", "loose_box_check", "retake")),
)  # fmt: skip

#: round 1 (e1f23e8, against the holdout benchmark of 376f91a): one switch off at a time, or a group
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

#: round 2 at 6 seeds per layout (126 runs, baseline run the same way): round 2's undecided ORCA rows
ROUND_2_SIX: tuple[tuple[str, str, str, tuple[str, ...]], ...] = (
    STAGE_UNDECIDED,
    ("group: floor rules", "stigmergy", "avoidance_params", ("floor_rule", "floor_preferred", "ground_beside")),
)  # fmt: skip

#: round 3 at 6 seeds per layout (126 runs on b008ec3, baseline run the same way): the planner switches still
#: undecided, and the one ORCA rule never ablated
ROUND_3_SIX: tuple[tuple[str, str, str, tuple[str, ...]], ...] = (
    ("orca rule: static_obstacles", "stigmergy", "avoidance_params", ("static_obstacles",)),
    ("switch: replan_climb (layered_stigmergy)", "layered_stigmergy", "planner.params", ("replan_climb",)),
    ("group: traffic (shortest_path)", "shortest_path", "planner.params", ("swap_boxes", "round_parked")),
)  # fmt: skip


#: round 4 at 6 seeds per layout (126 runs on 180e3c7, paired with round 3's baseline of b008ec3, whose
#: shortest_path and ORCA code is the same): the floor rules, undecided on stigmergy, on shortest_path
ROUND_4_SIX: tuple[tuple[str, str, str, tuple[str, ...]], ...] = (
    ("group: floor rules (shortest_path)", "shortest_path", "avoidance_params",
     ("floor_rule", "floor_preferred", "ground_beside")),
)  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Round:
    """One round of the ablation: its configurations and what they are paired with.

    Attributes:
        configs: the configurations.
        baseline: benchmark JSON of main to pair with, or None: a baseline is run the same way.
        common: overrides of the baseline and every configuration (a condition such as flying on estimates).
        note: what the baseline is, for the table's notes.
        seeds: seeds per layout (None: the split's 2).
    """

    configs: list[ablation.Ablation]
    baseline: str | None
    common: tuple[tuple[str, str], ...] = ()
    note: str = "every switch on"
    seeds: int | None = None


ROUNDS: dict[str, Round] = {
    "1": Round(CONFIGS, "docs/results/data/benchmarks/construction-v1-holdout-376f91a.json"),
    "2": Round(
        [ablation.switched_off(*row) for row in ROUND_2],
        "docs/results/data/benchmarks/construction-v1-holdout-4170d6c.json",
        note="every switch on, after round 1's deletions",
    ),
    "2-six": Round(
        [ablation.switched_off(*row) for row in ROUND_2_SIX],
        None,
        note="every switch on, after round 1's deletions, run the same way",
        seeds=6,
    ),
    "3-six": Round(
        [ablation.switched_off(*row) for row in ROUND_3_SIX],
        None,
        note="every switch on, run the same way",
        seeds=6,
    ),
    "4-six": Round(
        [ablation.switched_off(*row) for row in ROUND_4_SIX],
        None,
        note="every switch on, run the same way (round 3's baseline)",
        seeds=6,
    ),
    "estimated": Round(
        [ablation.switched_off(*row) for row in ESTIMATED],
        None,
        (("sensing.state", "estimated"),),
        "every switch on, run the same way (agents fly on their Kalman estimates)",
    ),
}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--round", choices=sorted(ROUNDS), default="1", help="which configurations (see ROUNDS)")
    ap.add_argument("--out", type=Path, default=None, help="default runs/switch-ablation-ROUND")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--only", nargs="*", default=[], help="run only these configurations (directory names)")
    ap.add_argument("--baseline", type=Path, default=None, help="benchmark JSON (default: the round's)")
    ap.add_argument("--table", type=Path, default=None, help="write the results table JSON here")
    args = ap.parse_args()
    rnd = ROUNDS[args.round]
    configs = [c for c in rnd.configs if not args.only or c.slug in args.only]
    out = args.out or Path(f"runs/switch-ablation-{args.round}")
    base_path = args.baseline or (Path(rnd.baseline) if rnd.baseline else None)
    base = benchmark.read_benchmark(base_path) if base_path else None
    results = ablation.run_ablation(
        configs,
        out,
        seeds=rnd.seeds,
        workers=args.workers,
        baseline=base,
        baseline_seeds={c.planner: rnd.seeds for c in configs if rnd.seeds is not None},
        common=rnd.common,
    )
    where = (
        f"{base_path.as_posix()} (commit {str(base.get('commit', ''))[:10]})"
        if base_path and base
        else "run by the script into OUT/base"
    )
    under = "".join(f" --set {k}={v}" for k, v in rnd.common)
    runs = f"the split's {rnd.seeds or 2} seeds on its 21 generated layouts"
    orca = sorted({c.planner for c in configs if any(k.startswith("avoidance_params.") for k, _ in c.overrides)})
    orca_rows = f" ORCA rows: {', '.join(orca)} + orca." if orca else ""
    data = ablation.results_table(
        results,
        configs,
        title=f"Switches on the holdout split{' flying on estimates' if rnd.common else ''}, round {args.round} "
        "(one switch or group off against every switch on)",
        command=f"python scripts/switch_ablation.py --round {args.round}",
        notes=[
            f"Baseline: {where}, {rnd.note}; each configuration: {runs}, with orca"
            f"{under and ', ' + under.strip()}, paired on the runs both have.{orca_rows}",
        ],
    )
    ablation.report(data, args.table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
