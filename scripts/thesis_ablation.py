#!/usr/bin/env python3
"""Thesis ablation: from ``preset: thesis``, switch our extensions back on one at a time, over seeds.

    python scripts/thesis_ablation.py [--seeds 20] [--planners shortest_path,stigmergy,layered_stigmergy]
        [--base EXT[,EXT...]] [--workers K] [--out runs/thesis_ablation] [--set key=value ...]
        [--ci t|bootstrap] [--quiet]

For each planner the configurations are: the thesis preset; with ``--base``, the preset with those
extensions on (those a planner has; e.g. ``--base wide_view``: the stigmergy planners under the
preset see no bottom slot, see docs/results/history/2026-11-27-thesis-preset-ablation.md); the
preset (plus the base) with each other extension on alone; and our defaults (every extension on).
The extensions are read from the planner's parameter model (``planning.params.extensions``: every
field the preset sets to a value other than the default), so a new switch joins the ablation by
itself.

Each planner's configurations run as one sweep (``pybullet_swarm.experiment.sweep``, the grid
being ``planner.params``) in ``OUT/<planner>/``: resumable, run it again to add seeds or finish an
interrupted batch. Per configuration the script tables completed runs, completion time (of the
completed runs), the thesis's collision count and utility of space, as mean with a 95 % interval,
and writes ``OUT/ablation.csv``, ``OUT/ablation.json``, ``OUT/ablation.png`` (every configuration)
and ``OUT/thesis_preset_defaults.png`` (the thesis's reported runs, the preset, the preset with the
base extensions and our defaults).

The thesis's collision count is ``thesis_collisions`` (per-agent crossings under the collision
line, its Figure 3.12 and section 3.6) when the runs report it, else ``proximity_violations``
(onsets over agent pairs, about half as many); the table says which.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path
from typing import Any, Mapping, Sequence

from pybullet_swarm.experiment.results import plain_cell
from pybullet_swarm.experiment.summary import CIMethod, describe
from pybullet_swarm.experiment.sweep import Sweep, run_sweep
from pybullet_swarm.planning.params import Preset, extensions
from pybullet_swarm.planning.registry import planners as registered_planners

PLANNERS = ("shortest_path", "stigmergy", "layered_stigmergy")
#: the thesis's single runs (Tables 5.3 and 6.2); it gives no table for its shortest-path baseline
THESIS = {
    "stigmergy": {"collisions": 18, "completion_time_s": 120.1, "utility_of_space": 0.74},
    "layered_stigmergy": {"collisions": 23, "completion_time_s": 242.8, "utility_of_space": 0.78},
}
PRESET = "thesis preset"
DEFAULTS = "defaults"


def configurations(planner: str, base: Sequence[str] = ()) -> list[tuple[str, dict[str, Any]]]:
    """``(label, planner.params)`` of a planner's ablation, in order (see the module's docstring)."""
    model = registered_planners()[planner].params
    ext = extensions(model, Preset.THESIS)
    on = {k: ext[k][1] for k in base if k in ext}
    preset = {"preset": Preset.THESIS.value}
    out = [(PRESET, dict(preset))]
    if on:
        out.append(("preset + " + " + ".join(on), {**preset, **on}))
    for name, (_, default) in ext.items():
        if name not in on:
            out.append((f"+ {name}", {**preset, **on, name: default}))
    out.append((DEFAULTS, {}))
    return out


def _number(v: Any) -> float:
    try:
        return float(v) if v not in (None, "") else math.nan
    except (TypeError, ValueError):
        return math.nan


def collision_metric(rows: Sequence[Mapping[str, Any]]) -> str:
    """``thesis_collisions`` when the runs report it, else ``proximity_violations``."""
    return (
        "thesis_collisions"
        if any(math.isfinite(_number(r.get("thesis_collisions"))) for r in rows)
        else "proximity_violations"
    )


def table_rows(
    planner: str,
    configs: Sequence[tuple[str, dict[str, Any]]],
    rows: Sequence[Mapping[str, Any]],
    collisions: str,
    ci: CIMethod,
) -> tuple[list[dict[str, Any]], list[tuple[str, list[dict[str, Any]]]]]:
    """Statistics per configuration, and each configuration's runs as plain numbers (for the figure)."""
    table, runs_by = [], []
    for label, params in configs:
        cell = plain_cell(params)
        mine = [r for r in rows if r.get("planner.params") == cell and r.get("exit_status") != "error"]
        runs: list[dict[str, Any]] = [
            {
                "completed": r.get("exit_status") == "completed",
                "sim_time_s": _number(r.get("sim_time_s")),
                "completion_time_s": _number(r.get("completion_time_s")),
                "collisions": _number(r.get(collisions)),
                "utility_of_space": _number(r.get("utility_of_space")),
                "boxes_placed": _number(r.get("boxes_placed")),
                "seed": r.get("seed"),
            }
            for r in mine
        ]
        runs_by.append((label, runs))
        rec: dict[str, Any] = {
            "planner": planner,
            "configuration": label,
            "params": params,
            "runs": len(runs),
            "completed": sum(r["completed"] for r in runs),
        }
        for key in ("completion_time_s", "collisions", "utility_of_space", "boxes_placed"):
            vals = [float(r[key]) for r in runs if key != "completion_time_s" or r["completed"]]
            s = describe(vals, ci=ci)
            rec.update(
                {
                    f"{key}_n": s.n,
                    f"{key}_mean": s.mean,
                    f"{key}_ci95_low": s.ci95_low,
                    f"{key}_ci95_high": s.ci95_high,
                    f"{key}_median": s.median,
                }
            )
        table.append(rec)
    return table, runs_by


def _cell(rec: Mapping[str, Any], key: str, digits: str) -> str:
    m, lo, hi = rec[f"{key}_mean"], rec[f"{key}_ci95_low"], rec[f"{key}_ci95_high"]
    if not math.isfinite(m):
        return "-"
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return f"{m:{digits}}"
    return f"{m:{digits}} [{lo:{digits}}, {hi:{digits}}]"


def markdown(table: Sequence[Mapping[str, Any]], collisions: str) -> str:
    """The table as Markdown (as in the results history of the docs)."""
    head = (
        "| planner | configuration | completed | completion time [s] | "
        f"collisions ({collisions}) | utility of space | boxes placed |"
    )
    lines = [head, "|---|---|---|---|---|---|---|"]
    for planner in dict.fromkeys(r["planner"] for r in table):
        thesis = THESIS.get(planner)
        if thesis:
            lines.append(
                f"| {planner} | thesis (one run) | 1/1 | {thesis['completion_time_s']:g} | "
                f"{thesis['collisions']:g} | {thesis['utility_of_space']:g} | 9 |"
            )
        for r in (r for r in table if r["planner"] == planner):
            lines.append(
                f"| {planner} | {r['configuration']} | {r['completed']}/{r['runs']} | "
                f"{_cell(r, 'completion_time_s', '.1f')} | {_cell(r, 'collisions', '.1f')} | "
                f"{_cell(r, 'utility_of_space', '.2f')} | {_cell(r, 'boxes_placed', '.1f')} |"
            )
    return "\n".join(lines)


def _figures(
    out: Path, planners: Sequence[str], runs: Mapping[str, list[tuple[str, list[dict[str, Any]]]]], collisions: str
) -> list[Path]:
    from pybullet_swarm.plotting.thesis_plots import ablation_distributions_figure

    metrics = (
        ("completion_time_s", "completion time [s]"),
        ("collisions", f"collisions ({collisions})"),
        ("utility_of_space", "utility of space"),
    )

    def column(p: str, keep: Sequence[str] | None) -> dict[str, Any]:
        configs = [(label, r) for label, r in runs[p] if keep is None or label in keep]
        return {"planner": p, "configs": configs, "thesis": THESIS.get(p, {})}

    every = ablation_distributions_figure(
        [column(p, None) for p in planners], metrics, out / "ablation.png", rotate=True
    )
    side = ablation_distributions_figure(
        [
            column(p, [label for label, _ in runs[p] if label in (PRESET, DEFAULTS) or label.startswith("preset + ")])
            for p in planners
        ],
        metrics,
        out / "thesis_preset_defaults.png",
    )
    return [every, side]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--planners", default=",".join(PLANNERS))
    ap.add_argument("--base", default="", help="extensions on in every configuration but the preset's (comma list)")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("runs/thesis_ablation"))
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE")
    ap.add_argument("--ci", choices=[m.value for m in CIMethod], default=CIMethod.T.value)
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    planners = tuple(p for p in args.planners.split(",") if p)
    base = tuple(b for b in args.base.split(",") if b)
    unknown = [p for p in planners if p not in registered_planners() or not registered_planners()[p].params.PRESETS]
    if unknown:
        ap.error(f"planners without a thesis preset: {', '.join(unknown)}")
    ci = CIMethod(args.ci)
    all_rows: dict[str, list[Mapping[str, Any]]] = {}
    configs = {p: configurations(p, base) for p in planners}
    for p in planners:
        sweep = Sweep(
            "construction",
            planners=(p,),
            seeds=args.seeds,
            overrides=args.overrides,
            grid={"planner.params": [params for _, params in configs[p]]},
        )
        result = run_sweep(sweep, args.out / p, workers=args.workers, quiet=args.quiet, figures=False)
        all_rows[p] = [dict(r) for r in result.rows]
    collisions = collision_metric([r for rows in all_rows.values() for r in rows])
    table: list[dict[str, Any]] = []
    runs: dict[str, list[tuple[str, list[dict[str, Any]]]]] = {}
    for p in planners:
        t, runs[p] = table_rows(p, configs[p], all_rows[p], collisions, ci)
        table.extend(t)
    args.out.mkdir(parents=True, exist_ok=True)
    fields = [k for k in table[0] if k != "params"]
    with open(args.out / "ablation.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=[*fields, "params"])
        w.writeheader()
        w.writerows({**{k: r[k] for k in fields}, "params": json.dumps(r["params"], sort_keys=True)} for r in table)
    meta = {
        "seeds": args.seeds,
        "overrides": args.overrides,
        "base": list(base),
        "collision_metric": collisions,
        "ci": ci.value,
        "thesis": THESIS,
        "table": table,
        "runs": {p: {label: r for label, r in runs[p]} for p in planners},
    }
    (args.out / "ablation.json").write_text(json.dumps(meta, indent=1, default=str), encoding="utf-8")
    figures = _figures(args.out, planners, runs, collisions)
    print(markdown(table, collisions))
    print("\n" + "\n".join(str(f) for f in [args.out / "ablation.csv", args.out / "ablation.json", *figures]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
