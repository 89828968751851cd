"""Write docs/results/data/construction_suite_layouts.json: every layout of the construction suite's splits.

Per layout of ``scenarios/suites/construction.yaml`` (both splits): how it is given (a scenario, a
placed structure, or a generator seed), the structure's shapes, its slots, the swarm, the arena,
the depot grids, and the view radius the stigmergy planners are given when the layout needs more
than the default (derived at load). The docs include the file with
``<!-- results-table: construction_suite_layouts -->``.

    python scripts/suite_layouts_table.py [--suite construction] [--out docs/results/data/construction_suite_layouts.json]
"""

from __future__ import annotations

import argparse
import copy
import datetime
import json
from pathlib import Path
from typing import Any

from pybullet_swarm.experiment.benchmark import git_commit
from pybullet_swarm.experiment.scenario import apply_choices, build_scenario
from pybullet_swarm.experiment.suites import GeneratedLayout, ScenarioLayout, load_suite

ROOT = Path(__file__).resolve().parent.parent
COMMAND = "python scripts/suite_layouts_table.py"


def _shapes(structure: Any) -> str:
    """``wall``, ``tower + tower`` ... of a structure as a file holds it (``boxes`` for a list of centres)."""
    items = structure if isinstance(structure, list) else [structure]
    names = [str(s.get("shape", "voxels")) if isinstance(s, dict) else "boxes" for s in items]
    return " + ".join(names) if names and names[0] != "boxes" else "boxes"


def rows(suite_name: str) -> list[list[Any]]:
    """One row per layout of every split."""
    suite = load_suite(suite_name)
    out = []
    for split in suite.splits.values():
        for lay in split.layouts:
            data = suite.layout_data(lay, split)
            s = build_scenario(
                apply_choices(copy.deepcopy(data), planner="stigmergy", source=lay.name), source=lay.name
            )
            boxes = data["task"]["boxes"]
            given = (
                f"generator seed {lay.generator_seed}"
                if isinstance(lay, GeneratedLayout)
                else f"scenario {lay.scenario}"
                if isinstance(lay, ScenarioLayout)
                else "placed"
            )
            lx, ly = s.arena.size
            out.append(
                [
                    split.name,
                    lay.name,
                    given,
                    _shapes(data["task"]["structure"]),
                    len(s.task.structure),
                    s.agents.count,
                    f"{lx:g} x {ly:g}",
                    len(boxes) if isinstance(boxes, list) and isinstance(boxes[0], dict) else 1,
                    "-" if s.task.view_radius is None else round(float(s.task.view_radius), 3),
                ]
            )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", default="construction")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "data" / "construction_suite_layouts.json")
    args = ap.parse_args()
    suite = load_suite(args.suite)
    data = {
        "title": f"Layouts of the {suite.name} suite, version {suite.version}",
        "command": COMMAND,
        "commit": git_commit(ROOT),
        "date": datetime.date.today().isoformat(),
        "columns": [
            "split",
            "layout",
            "given as",
            "structure",
            "slots",
            "agents",
            "arena [m]",
            "depots",
            "view radius, stigmergy [m]",
        ],
        "rows": rows(args.suite),
        "notes": [
            f"dev seeds {min(suite.split('dev').seeds)}..{max(suite.split('dev').seeds)}, holdout seeds "
            f"{min(suite.split('holdout').seeds)}..{max(suite.split('holdout').seeds)}.",
            "view radius: the task's view_radius the stigmergy planners are given when the layout needs more than "
            "the default (two agent radii) for every slot to be in view; '-': the default.",
        ],
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    print(args.out)


if __name__ == "__main__":
    main()
