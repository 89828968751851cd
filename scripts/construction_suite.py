#!/usr/bin/env python3
"""Construction benchmark suite: many layouts, every construction planner, with and without avoidance, over seeds.

    python scripts/construction_suite.py [--seeds 5] [--planners shortest_path,stigmergy,layered_stigmergy]
        [--avoidance none,orca] [--layouts NAME[,NAME...]] [--workers K] [--out runs/construction_suite]
        [--set key=value ...] [--quiet]

The layouts (``LAYOUTS``; ``--list`` prints them) are the thesis's, walls and a stepped wall of
boxes side by side (pitch = box size), a slab, towers of 5, two and three structures, 3 to 20
agents and arenas up to 6 x 3 m: each a structure placed by hand, composed into a scenario by
``pybullet_swarm.experiment.layouts.compose_layout`` (a swarm at the near end, a depot grid of as
many boxes as slots), and two drawn by ``random_layout`` (frozen in ``scenarios/suites/construction.yaml``,
whose ``dev`` split holds these layouts; ``pybullet-swarm benchmark construction --split dev`` runs them). Each is written to
``OUT/layouts/<name>.yaml`` and run as one sweep (``pybullet_swarm.experiment.sweep``: planners x
avoidance x seeds) in ``OUT/<name>/``: resumable, run it again to add seeds or finish an
interrupted batch (the table holds the runs this invocation plans, not older runs of a directory
whose planners have changed since).

Per layout and configuration (planner + avoidance) the script tables: runs, completed (and the
rate), crashed, stalled, timed out, the median completion time of completed runs, the median
efficiency (the task's lower bound / completion time), and the contacts per run by class; it
writes ``OUT/suite.csv``, ``OUT/suite.json``, ``OUT/suite.md`` (the Markdown table) and
``OUT/suite.png`` (``pybullet_swarm.plotting.suite_plots``).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import statistics
import sys
from pathlib import Path
from typing import Any, Mapping, Sequence

import yaml

from pybullet_swarm.experiment.layouts import compose_layout
from pybullet_swarm.experiment.scenario import resolve_scenario_path
from pybullet_swarm.experiment.suites import load_suite
from pybullet_swarm.experiment.sweep import Sweep, plan_sweep, run_sweep
from pybullet_swarm.validation import read_yaml

PLANNERS = ("shortest_path", "stigmergy", "layered_stigmergy")
AVOIDANCE = ("none", "orca")
CONTACTS = ("agent_agent", "agent_structure", "agent_box", "agent_ground", "agent_obstacle")
CRASH_CAUSES = ("agent_agent_contact", "wake", "other")


def _wall(origin: list[float], **kw: Any) -> dict[str, Any]:
    return {"shape": "wall", "origin": origin, **kw}


#: name -> (description, structure (placed), agents, arena) for ``compose_layout``; None: special
LAYOUTS: dict[str, tuple[str, Any, int, list[float]] | None] = {
    "thesis": None,  # the bundled construction scenario
    "solid_wall": (
        "a wall of 5 x 2 boxes side by side",
        _wall([2.6, 0.3], length=5, height=2, axis="y"),
        5,
        [3.0, 1.0],
    ),
    "solid_stepped_wall": (
        "a stepped 4-3-2-1 wall of boxes side by side",
        {"shape": "stepped_wall", "origin": [2.6, 0.35], "length": 4, "axis": "y"},
        5,
        [3.0, 1.0],
    ),
    "slab": ("a 3 x 3 floor slab", {"shape": "slab", "origin": [2.4, 0.4], "size": [3, 3]}, 5, [3.0, 1.5]),
    "tower5": ("a tower of 5 boxes", {"shape": "tower", "origin": [2.6, 0.5], "height": 5}, 5, [3.0, 1.0]),
    "two_towers": (
        "two towers of 5 boxes",
        [
            {"shape": "tower", "origin": [2.5, 0.45], "height": 5},
            {"shape": "tower", "origin": [2.5, 1.05], "height": 5},
        ],
        8,
        [3.0, 1.5],
    ),
    "double_wall": (
        "two 4-high stepped walls, 12 agents",
        [
            {"shape": "stepped_wall", "origin": [2.2, 0.2], "length": 4, "height": 4, "axis": "y", "pitch": 0.2},
            {"shape": "stepped_wall", "origin": [2.7, 0.2], "length": 4, "height": 4, "axis": "y", "pitch": 0.2},
        ],
        12,
        [3.0, 1.0],
    ),
    "pyramid": (
        "a pyramid of columns, base 3",
        {"shape": "pyramid", "origin": [3.2, 0.8], "base": 3, "pitch": 0.2},
        8,
        [4.0, 2.0],
    ),
    "ring": (
        "a ring of 4 x 4 columns",
        {"shape": "ring", "origin": [3.0, 0.7], "size": [4, 4], "pitch": 0.2},
        10,
        [4.0, 2.0],
    ),
    "three_agents": (
        "3 agents, a 6 x 2 wall at 20 cm",
        _wall([2.6, 0.25], length=6, height=2, axis="y", pitch=0.2),
        3,
        [3.0, 1.5],
    ),
    "three_structures_20": (
        "20 agents, a wall, a stepped wall and a tower in a 6 x 3 m arena",
        [
            _wall([4.6, 0.4], length=8, height=2, axis="y", pitch=0.2),
            {"shape": "stepped_wall", "origin": [5.4, 0.6], "length": 5, "axis": "y", "pitch": 0.2},
            {"shape": "tower", "origin": [4.0, 2.5], "height": 4},
        ],
        20,
        [6.0, 3.0],
    ),
    "random_3": None,  # random_layout(3) of the suite file's dev split
    "random_8": None,  # random_layout(8) of the suite file's dev split
}


def layout_data(name: str) -> dict[str, Any]:
    """Scenario data of a suite layout."""
    if name == "thesis":
        return read_yaml(resolve_scenario_path("construction"))
    if name.startswith("random_"):  # as the generator drew them when the suite was written (frozen in the suite file)
        suite = load_suite("construction")
        dev = suite.split("dev")
        return suite.layout_data(next(lay for lay in dev.layouts if lay.name == name), dev)
    spec = LAYOUTS[name]
    assert spec is not None
    description, structure, agents, arena = spec
    return compose_layout(structure, agents=agents, arena=arena, name=name, description=description)


def _number(v: Any) -> float:
    try:
        return float(v) if v not in (None, "") else math.nan
    except (TypeError, ValueError):
        return math.nan


def _median(values: Sequence[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return statistics.median(finite) if finite else math.nan


def table_rows(layout: str, rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """One record per configuration (planner + avoidance) of a layout's runs."""
    out = []
    configs = dict.fromkeys((str(r.get("planner")), str(r.get("avoidance"))) for r in rows)
    for planner, avoidance in configs:
        mine = [r for r in rows if (str(r.get("planner")), str(r.get("avoidance"))) == (planner, avoidance)]
        status = [str(r.get("exit_status")) for r in mine]
        done = [r for r in mine if r.get("exit_status") == "completed"]
        rec: dict[str, Any] = {
            "layout": layout,
            "configuration": planner if avoidance == "none" else f"{planner} + {avoidance}",
            "planner": planner,
            "avoidance": avoidance,
            "runs": len(mine),
            "completed": len(done),
            "completion_rate": len(done) / len(mine) if mine else math.nan,
            "crashed": status.count("crashed") + status.count("diverged"),
            # what came before each crash (Simulation._crash_cause): an agent-agent contact, another's wake, neither
            **{
                f"crashed_{cause}": sum(
                    1 for r in mine if r.get("exit_status") == "crashed" and r.get("crash_cause") == cause
                )
                for cause in CRASH_CAUSES
            },
            "stalled": status.count("stalled"),
            "timeout": status.count("timeout"),
            "error": status.count("error"),
            "completion_time_median_s": _median([_number(r.get("completion_time_s")) for r in done]),
            "efficiency_median": _median([_number(r.get("efficiency")) for r in done]),
            "boxes_placed_mean": statistics.fmean([_number(r.get("boxes_placed")) for r in mine]) if mine else math.nan,
            "boxes_total": _number(mine[0].get("boxes_total")) if mine else math.nan,
        }
        for cls in CONTACTS:
            counts = [_number(r.get(f"collisions.{cls}")) for r in mine]
            rec[f"contacts_{cls}_per_run"] = statistics.fmean([c for c in counts if math.isfinite(c)] or [math.nan])
        out.append(rec)
    return out


def _f(v: Any, digits: str) -> str:
    return "-" if not isinstance(v, (int, float)) or not math.isfinite(v) else format(v, digits)


def crashed(r: Mapping[str, Any]) -> str:
    """The crash count of a table record, and (when there are any) how many came after an agent-agent contact,
    in another agent's wake, or after neither."""
    if not r["crashed"]:
        return "0"
    return f"{r['crashed']} ({' / '.join(str(r.get(f'crashed_{c}', 0)) for c in CRASH_CAUSES)})"


def markdown(table: Sequence[Mapping[str, Any]]) -> str:
    """The table as Markdown."""
    lines = [
        "| layout | configuration | completed | crashed (contact / wake / other) | stalled | timeout | median completion [s] | "
        "median efficiency | boxes placed | contacts a-a / a-s / a-b per run |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in table:
        contacts = " / ".join(_f(r[f"contacts_{c}_per_run"], ".1f") for c in CONTACTS[:3])
        lines.append(
            f"| {r['layout']} | {r['configuration']} | {r['completed']}/{r['runs']} | {crashed(r)} | {r['stalled']} | "
            f"{r['timeout']} | {_f(r['completion_time_median_s'], '.1f')} | {_f(r['efficiency_median'], '.2f')} | "
            f"{_f(r['boxes_placed_mean'], '.1f')}/{_f(r['boxes_total'], '.0f')} | {contacts} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--planners", default=",".join(PLANNERS))
    ap.add_argument("--avoidance", default=",".join(AVOIDANCE))
    ap.add_argument("--layouts", default=",".join(LAYOUTS), help="comma list of layout names (default: all)")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("runs/construction_suite"))
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE")
    ap.add_argument("--list", action="store_true", help="print the layouts and exit")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    names = [n for n in args.layouts.split(",") if n]
    unknown = [n for n in names if n not in LAYOUTS]
    if unknown:
        ap.error(f"unknown layouts: {', '.join(unknown)} (known: {', '.join(LAYOUTS)})")
    if args.list:
        for n in names:
            print(f"{n:22s} {layout_data(n).get('description', '')}")
        return 0
    planners = tuple(p for p in args.planners.split(",") if p)
    avoidance = tuple(a for a in args.avoidance.split(",") if a)
    table: list[dict[str, Any]] = []
    for name in names:
        path = args.out / "layouts" / f"{name}.yaml"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(yaml.safe_dump(layout_data(name), sort_keys=False, default_flow_style=None), encoding="utf-8")
        sweep = Sweep(path, planners=planners, avoidance=avoidance, seeds=args.seeds, overrides=args.overrides)
        result = run_sweep(sweep, args.out / name, workers=args.workers, quiet=args.quiet, figures=False)
        planned = {spec.run_id for spec in plan_sweep(sweep, args.out / name).runs}  # not older runs of the directory
        table.extend(table_rows(name, [dict(r) for r in result.rows if r.get("run_id") in planned]))
        if not args.quiet:
            print(f"{name}: {result.n_run} run, {result.n_skipped} recorded before", flush=True)
    fields = list(table[0])
    with open(args.out / "suite.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        w.writerows(table)
    meta = {"seeds": args.seeds, "planners": planners, "avoidance": avoidance, "overrides": args.overrides}
    (args.out / "suite.json").write_text(json.dumps({**meta, "table": table}, indent=1), encoding="utf-8")
    text = markdown(table)
    (args.out / "suite.md").write_text(text + "\n", encoding="utf-8")
    from pybullet_swarm.plotting.suite_plots import suite_figure

    figure = suite_figure(table, args.out / "suite.png")
    print(text)
    print("\n" + "\n".join(str(f) for f in [args.out / "suite.csv", args.out / "suite.md", figure]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
