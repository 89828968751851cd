"""Write ``docs/results/data/wake_model.json``: the thesis task and the construction suite with the wake model,
beside the figures of the empirical model it replaced.

New-model rows are read from the output directories of the measuring commands (a sweep's ``runs.csv``; the
construction suite's ``runs.csv``); the old model's figures were measured before the change and are quoted
from where they were recorded (``OLD``: the README at a326077, commit 5d803b3 / 7648950 of the code).

    python scripts/wake_table.py --thesis /tmp/wake_thesis [--suite runs/construction-suite] [--commit HASH]
"""

from __future__ import annotations

import argparse
import csv
import datetime
import json
import statistics
import subprocess
from pathlib import Path
from typing import Any

THESIS_CMD = (
    "pybullet-swarm sweep construction --seeds 150 --planners stigmergy,shortest_path --avoidance orca --workers 2"
)
SUITE_CMD = (
    "python scripts/construction_suite.py --seeds 5 --planners stigmergy,layered_stigmergy,shortest_path "
    "--avoidance orca --workers 2"
)
COLUMNS = [
    "task",
    "planner + avoidance",
    "wake model",
    "runs",
    "completed",
    "runs with an agent-agent contact",
    "runs with any contact",
    "incidents",
    "median completion s (seeds 0..49 / 50..99 / 100..149)",
]
#: the empirical model's figures as recorded (README at a326077: thesis on 5d803b3, suite on 5d803b3 / 7648950)
OLD: list[list[Any]] = [
    ["thesis", "stigmergy + orca", "empirical (before)", 150, "150/150", 0, 0, "-", "94.7 / 93.2 / 95.9"],
    ["thesis", "shortest_path + orca", "empirical (before)", "-", "not measured", "-", "-", "-", "-"],
    ["suite, seeds 0..4", "stigmergy + orca", "empirical (before)", 65, "65/65", 0, 0, "-", "-"],
    ["suite, seeds 0..4", "layered_stigmergy + orca", "empirical (before)", 65, "65/65", 0, 0, "-", "-"],
    ["suite, seeds 0..4", "shortest_path + orca", "empirical (before)", 65, "65/65", 0, 0, "-", "-"],
]


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _int(v: str | None) -> int:
    try:
        return int(float(v)) if v not in (None, "") else 0
    except ValueError:
        return 0


def _summary(task: str, runs: list[dict[str, str]], planner: str, thirds: bool) -> list[Any]:
    mine = [r for r in runs if r.get("planner") == planner and r.get("exit_status") not in ("", None, "error")]
    contact_keys = [k for k in (mine[0] if mine else {}) if k.startswith("collisions.")]
    done = [r for r in mine if r["exit_status"] == "completed"]
    aa = sum(1 for r in mine if _int(r.get("collisions.agent_agent")) > 0)
    anyc = sum(1 for r in mine if any(_int(r.get(k)) > 0 for k in contact_keys))
    incidents = sum(_int(r.get("incidents")) for r in mine)
    med = "-"
    if thirds:
        parts = []
        for lo in (0, 50, 100):
            t = [float(r["completion_time_s"]) for r in done if lo <= _int(r["seed"]) < lo + 50]
            n = sum(1 for r in mine if lo <= _int(r["seed"]) < lo + 50)
            parts.append(
                f"{statistics.median(t):.1f}"
                if t and n == 50
                else (f"{statistics.median(t):.1f} ({n} seeds)" if t else "-")
            )
        med = " / ".join(parts)
    return [
        task,
        f"{planner} + orca",
        "jet (this page)",
        len(mine),
        f"{len(done)}/{len(mine)}",
        aa,
        anyc,
        incidents,
        med,
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--thesis", type=Path, required=True, help="sweep directory of the thesis command")
    ap.add_argument(
        "--suite", type=Path, default=None, help="output directory of the construction suite (one per layout)"
    )
    ap.add_argument("--commit", default=None, help="commit the runs were made with (default: HEAD)")
    ap.add_argument("--suite-commit", default=None, help="commit the suite ran at, when not --commit")
    ap.add_argument("--out", type=Path, default=Path("docs/results/data/wake_model.json"))
    args = ap.parse_args()
    commit = (
        args.commit
        or subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
    )
    thesis = _rows(args.thesis / "runs.csv")
    rows: list[list[Any]] = []
    for planner in ("stigmergy", "shortest_path"):
        rows.append(OLD[0] if planner == "stigmergy" else OLD[1])
        rows.append(_summary("thesis", thesis, planner, thirds=True))
    notes = [
        "thesis: " + THESIS_CMD + f" (seeds measured: {len({r['seed'] for r in thesis})} of 150)",
        "a contact is any counted class of metrics.json 'collisions' (agent and load classes, load_ground, "
        "load_wall, load_obstacle included); incidents: metrics.json 'incidents', summed over the runs",
        "old model: the README at a326077 (thesis on 5d803b3, suite on 5d803b3 and 7648950); its shortest_path + "
        "orca thesis figure was never recorded and was not measured again",
    ]
    layouts = sorted(args.suite.glob("*/runs.csv")) if args.suite is not None else []
    if layouts:
        # a layout counts once all its runs are in (3 planners x 5 seeds)
        full = [f for f in layouts if len(_rows(f)) >= 15]
        suite = [r for f in full for r in _rows(f)]
        task = f"suite, seeds 0..4 ({len(full)} of 13 layouts)"
        for k, planner in enumerate(("stigmergy", "layered_stigmergy", "shortest_path")):
            rows.append(OLD[2 + k])
            rows.append(_summary(task, suite, planner, thirds=False))
        notes.append(
            "suite: "
            + SUITE_CMD
            + f" at {args.suite_commit or commit}; layouts measured: {', '.join(f.parent.name for f in full)} "
            "(the old model's rows are over all 13 layouts)"
        )
    else:
        rows.extend(OLD[2:])
        notes.append("suite with the new wake model: not measured (no CPU time left in the session)")
    data = {
        "title": "Thesis task and construction suite: the jet wake model beside the empirical model it replaced",
        "command": f"python scripts/wake_table.py --thesis {args.thesis}"
        + (f" --suite {args.suite}" if args.suite else ""),
        "commit": commit,
        "date": datetime.date.today().isoformat(),
        "columns": COLUMNS,
        "rows": rows,
        "notes": notes,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(data, indent=1) + "\n")
    print(args.out)
    for r in rows:
        print(" | ".join(str(c) for c in r))


if __name__ == "__main__":
    main()
