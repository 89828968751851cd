"""``report.html`` of a sweep directory: what was swept, the comparison table with confidence intervals
(``summary.csv``), the comparison figures and a line per run, drawn by ``plotting.report``.

``pybullet-swarm sweep`` writes it at the end of a sweep that was not interrupted;
``pybullet-swarm report SWEEP_DIR`` writes it again.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any, Sequence

from pybullet_swarm.experiment.report import REPORT_NAME, plot_files
from pybullet_swarm.experiment.rundir import atomic_write
from pybullet_swarm.experiment.summary import HEADLINE_METRICS
from pybullet_swarm.experiment.sweep import load_sweep, read_manifest
from pybullet_swarm.plotting.report import SweepPage, sweep_report_html

RUN_COLUMNS_SHOWN = ("completion_time_s", "sim_time_s", "collisions.total")  # outcomes in the runs table


def _seed_text(seeds: Sequence[int]) -> str:
    seeds = list(seeds)
    if seeds and seeds == list(range(seeds[0], seeds[0] + len(seeds))):
        return f"{len(seeds)} ({seeds[0]} .. {seeds[-1]})"
    return ", ".join(str(s) for s in seeds)


def sweep_page(sweep_dir: Path) -> SweepPage:
    """What the page of a sweep directory shows."""
    rows, group_by = load_sweep(sweep_dir)
    manifest = read_manifest(sweep_dir) or {}
    spec = manifest.get("sweep", {}) or {}
    name = manifest.get("scenario_name") or spec.get("scenario") or sweep_dir.name

    def axis(values: Sequence[Any]) -> str:
        return ", ".join("the scenario's" if v is None else str(v) for v in values)

    setup = [
        ("scenario", str(spec.get("scenario", name))),
        ("planners", axis(spec.get("planners", []))),
        ("avoidance", axis(spec.get("avoidance", []))),
        ("grid", "; ".join(f"{k} = {v}" for k, v in (spec.get("grid") or {}).items()) or "-"),
        ("seeds", _seed_text(spec.get("seeds", []))),
        ("overrides", "; ".join(f"{k} = {v}" for k, v in (spec.get("overrides") or {}).items()) or "-"),
        ("configuration columns", ", ".join(group_by)),
    ]
    statuses: dict[str, int] = {}
    for r in rows:
        statuses[str(r.get("exit_status"))] = statuses.get(str(r.get("exit_status")), 0) + 1
    summary: list[dict[str, str]] = []
    if (sweep_dir / "summary.csv").is_file():
        with open(sweep_dir / "summary.csv", newline="", encoding="utf-8") as fh:
            summary = list(csv.DictReader(fh))
    columns = ["run_id", *[c for c in group_by if c != "run_id"], "seed", "exit_status", *RUN_COLUMNS_SHOWN]
    runs = []
    for r in rows:
        where = Path(str(r.get("run_dir") or Path("runs") / str(r.get("run_id"))))
        page = (where if where.is_absolute() else sweep_dir / where) / REPORT_NAME  # run_dir: relative to the sweep
        try:
            link = page.resolve().relative_to(sweep_dir.resolve()).as_posix() if page.is_file() else None
        except ValueError:
            link = None
        runs.append({**{c: r.get(c) for c in columns}, "link": link})
    return SweepPage(
        name=str(name),
        directory=str(sweep_dir.resolve()),
        setup=setup,
        statuses=statuses,
        summary=summary,
        metric_order=HEADLINE_METRICS,
        figures=plot_files(sweep_dir),
        run_columns=columns,
        runs=runs,
    )


def write_sweep_report(sweep_dir: Path | str) -> Path:
    """Write ``report.html`` into a sweep directory; returns its path.

    Raises:
        ConfigError: not a sweep directory (no ``runs.csv``).
    """
    sweep_dir = Path(sweep_dir)
    text = sweep_report_html(sweep_page(sweep_dir))
    path = sweep_dir / REPORT_NAME
    atomic_write(path, lambda fh: fh.write(text))
    return path
