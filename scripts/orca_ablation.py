#!/usr/bin/env python3
"""ORCA ablation: switch the layer's extension rules off one at a time, and all of them (the paper's ORCA), over seeds.

    python scripts/orca_ablation.py [--seeds 10] [--planners stigmergy[,shortest_path]] [--workers 2]
        [--out runs/orca_ablation] [--set key.path=value ...] [--quiet]

On the construction task, per planner, the configurations are: every rule on (our defaults);
each rule of ``pybullet_swarm.planning.orca.Rule`` switched off alone (``- climb_over`` ...);
and ``preset: paper``, every rule off: the ORCA of van den Berg et al. alone. The rules are read
from the layer's parameter model, so a new rule joins the ablation by itself.

All runs go through one sweep (``pybullet_swarm.experiment.sweep``, the grid being
``avoidance_params``) in ``OUT/``: resumable, run the same command again to finish an
interrupted batch or add seeds. Per configuration the script tables:

* completed runs (and how the others ended: ``timeout``, ``crashed`` ...);
* ``agent_agent`` contact events (mean and 95 % t-interval; with ``collisions: ghost``, the
  default of ``construction.yaml``, overlaps that a physical run would turn into contacts) and
  how many runs had any;
* contacts of agents with boxes and the structure (``agent_box`` + ``agent_structure``, what
  ``static_obstacles`` is for), mean and 95 % t-interval, and how many runs had any;
* ``thesis_collisions`` (the thesis's count of crossings of the collision line), mean and 95 %
  t-interval;
* the median completion time with a distribution-free 95 % interval (order statistics of the
  binomial, coverage >= 95 %: ``[x_(k), x_(n+1-k)]``, undefined below 6 runs). A run that did not
  complete counts as slower than every one that did (its time is infinite), so the median says
  how long half of the runs took at most, whatever became of the others.

and writes ``OUT/ablation.md`` and ``OUT/ablation.json`` (the table and every run's numbers).
"""

from __future__ import annotations

import argparse
import json
import math
from collections import Counter
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from scipy import stats

from pybullet_swarm.experiment.results import plain_cell
from pybullet_swarm.experiment.summary import describe
from pybullet_swarm.experiment.sweep import Sweep, run_sweep
from pybullet_swarm.planning.orca import OrcaParams, Rule
from pybullet_swarm.planning.params import Preset, extensions

PLANNERS = ("stigmergy",)
ALL_ON = "every rule on"
PAPER = "paper (every rule off)"
LEVEL = 0.95  # of every interval


def configurations() -> list[tuple[str, dict[str, Any]]]:
    """``(label, avoidance_params)`` of the ablation, in order: all on, each rule off alone, all off."""
    rules = list(extensions(OrcaParams, Preset.PAPER))  # the fields the paper preset switches off
    assert rules == [r.value for r in Rule]
    return [(ALL_ON, {}), *((f"- {name}", {name: False}) for name in rules), (PAPER, {"preset": Preset.PAPER.value})]


def median_interval(values: Sequence[float], level: float = LEVEL) -> tuple[float, float, float]:
    """Median and distribution-free interval ``[x_(k), x_(n+1-k)]`` of the median (NaN when n is too small).

    k is the largest rank with P(B <= k - 1) <= (1 - level) / 2, B ~ Binomial(n, 1/2), so the
    interval covers the median with probability >= ``level`` whatever the distribution.
    Infinite values (runs that did not complete) are ordered last.
    """
    x = np.sort(np.asarray(values, dtype=float))
    n = x.size
    if n == 0:
        return math.nan, math.nan, math.nan
    median = float(x[(n - 1) // 2]) if n % 2 else float(0.5 * (x[n // 2 - 1] + x[n // 2]))
    k = 0
    while k + 1 <= n and stats.binom.cdf(k, n, 0.5) <= (1.0 - level) / 2.0:
        k += 1
    if k == 0:
        return median, math.nan, math.nan
    return median, float(x[k - 1]), float(x[n - k])


def _number(v: Any) -> float:
    try:
        return float(v) if v not in (None, "") else math.nan
    except (TypeError, ValueError):
        return math.nan


def table_rows(
    planner: str, configs: Sequence[tuple[str, dict[str, Any]]], rows: Sequence[Mapping[str, Any]]
) -> tuple[list[dict[str, Any]], dict[str, list[dict[str, Any]]]]:
    """Statistics per configuration of one planner, and each configuration's runs as plain numbers."""
    table: list[dict[str, Any]] = []
    runs_by: dict[str, list[dict[str, Any]]] = {}
    for label, params in configs:
        cell = plain_cell(params)
        mine = [
            r
            for r in rows
            if r.get("planner") == planner and r.get("avoidance_params") == cell and r.get("exit_status") != "error"
        ]
        runs: list[dict[str, Any]] = [
            {
                "seed": r.get("seed"),
                "exit_status": r.get("exit_status"),
                "completed": r.get("exit_status") == "completed",
                "completion_time_s": _number(r.get("completion_time_s")),
                "agent_agent": _number(r.get("collisions.agent_agent")),
                "agent_static": _number(r.get("collisions.agent_box")) + _number(r.get("collisions.agent_structure")),
                "thesis_collisions": _number(r.get("thesis_collisions")),
                "boxes_placed": _number(r.get("boxes_placed")),
                "orca_changed_fraction": _number(r.get("orca_changed_fraction")),
            }
            for r in sorted(mine, key=lambda r: int(r.get("seed", 0)))
        ]
        runs_by[label] = runs
        times = [r["completion_time_s"] if r["completed"] else math.inf for r in runs]
        med, lo, hi = median_interval(times)
        rec: dict[str, Any] = {
            "planner": planner,
            "configuration": label,
            "avoidance_params": params,
            "runs": len(runs),
            "completed": sum(r["completed"] for r in runs),
            "other_exits": dict(sorted(Counter(str(r["exit_status"]) for r in runs if not r["completed"]).items())),
            "runs_with_contact": sum(r["agent_agent"] > 0 for r in runs),
            "runs_with_static_contact": sum(r["agent_static"] > 0 for r in runs),
            "completion_time_median_s": med,
            "completion_time_ci95_low_s": lo,
            "completion_time_ci95_high_s": hi,
        }
        for key in ("agent_agent", "agent_static", "thesis_collisions", "boxes_placed"):
            s = describe([r[key] for r in runs])
            rec.update({f"{key}_mean": s.mean, f"{key}_ci95_low": s.ci95_low, f"{key}_ci95_high": s.ci95_high})
        table.append(rec)
    return table, runs_by


def _fmt(x: float, digits: str) -> str:
    if math.isnan(x):
        return "-"
    if math.isinf(x):
        return "not reached"
    return f"{x:{digits}}"


def _mean_cell(rec: Mapping[str, Any], key: str) -> str:
    m, lo, hi = rec[f"{key}_mean"], rec[f"{key}_ci95_low"], rec[f"{key}_ci95_high"]
    if math.isnan(m):
        return "-"
    if math.isnan(lo) or math.isnan(hi):
        return f"{m:.1f}"
    return f"{m:.1f} [{lo:.1f}, {hi:.1f}]"


def _median_cell(rec: Mapping[str, Any]) -> str:
    med, lo, hi = (rec[f"completion_time_{k}_s"] for k in ("median", "ci95_low", "ci95_high"))
    if math.isnan(lo):
        return _fmt(med, ".1f")
    return f"{_fmt(med, '.1f')} [{_fmt(lo, '.1f')}, {_fmt(hi, '.1f')}]"


def _completed_cell(rec: Mapping[str, Any]) -> str:
    others = ", ".join(f"{v} {k}" for k, v in rec["other_exits"].items())
    return f"{rec['completed']}/{rec['runs']}" + (f" ({others})" if others else "")


def markdown(table: Sequence[Mapping[str, Any]]) -> str:
    """The table as Markdown."""
    lines = [
        "| planner | configuration | completed | agent_agent contacts | runs with contact | agent_box + "
        "agent_structure contacts | runs with contact | thesis_collisions | median completion time [s] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in table:
        lines.append(
            f"| {r['planner']} | {r['configuration']} | {_completed_cell(r)} | {_mean_cell(r, 'agent_agent')} "
            f"| {r['runs_with_contact']} | {_mean_cell(r, 'agent_static')} | {r['runs_with_static_contact']} "
            f"| {_mean_cell(r, 'thesis_collisions')} | {_median_cell(r)} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the ablation and print its table."""
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10, help="number of seeds, 0 .. N-1 (default 10)")
    ap.add_argument("--planners", default=",".join(PLANNERS), help="comma list (e.g. stigmergy,shortest_path)")
    ap.add_argument("--workers", type=int, default=None, help="parallel runs (default: the number of cores)")
    ap.add_argument("--out", type=Path, default=Path("runs/orca_ablation"), help="sweep directory")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    if args.seeds < 1 or (args.workers is not None and args.workers < 1):
        ap.error("--seeds and --workers must be >= 1")
    planners = tuple(p for p in args.planners.split(",") if p)
    configs = configurations()
    sweep = Sweep(
        "construction",
        planners=planners,
        avoidance=("orca",),
        seeds=args.seeds,
        overrides=args.overrides,
        grid={"avoidance_params": [params for _, params in configs]},
    )
    result = run_sweep(sweep, args.out, workers=args.workers, quiet=args.quiet, figures=False)
    rows = [dict(r) for r in result.rows]
    table: list[dict[str, Any]] = []
    runs: dict[str, dict[str, list[dict[str, Any]]]] = {}
    for p in planners:
        t, runs[p] = table_rows(p, configs, rows)
        table.extend(t)
    text = markdown(table)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "ablation.md").write_text(text + "\n", encoding="utf-8")
    meta = {
        "scenario": "construction",
        "seeds": args.seeds,
        "planners": list(planners),
        "overrides": args.overrides,
        "rules": {r.value: r.doc for r in Rule},
        "table": table,
        "runs": runs,
    }
    (args.out / "ablation.json").write_text(json.dumps(meta, indent=1, default=str), encoding="utf-8")
    print(text)
    print(f"\n{args.out / 'ablation.md'}\n{args.out / 'ablation.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
