"""``report.html`` of a run directory: one self-contained page read from what the directory holds and
drawn by ``plotting.report`` (a sweep's page: ``experiment.sweep_report``).

``run`` writes its run's page at the end (cheap: the figures are already drawn; the page adds one
events figure and one still of the replay); ``pybullet-swarm report RUN_DIR`` writes it again,
e.g. after ``plot`` or ``replay``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.results import flatten_metrics, read_events, read_scenario_data
from pybullet_swarm.experiment.rundir import atomic_write
from pybullet_swarm.plotting.report import RunPage, run_report_html

REPORT_NAME = "report.html"
STILL_WIDTH = 1280  # px, width of the still of a run's last instant (its height fits the arena)


def plot_files(directory: Path) -> list[tuple[str, bytes]]:
    """Every PNG of ``directory/plots`` as (caption, bytes), in name order."""
    plots = directory / "plots"
    return [(p.stem.replace("_", " "), p.read_bytes()) for p in sorted(plots.glob("*.png"))] if plots.is_dir() else []


def _still(run_dir: Path, metrics: dict[str, Any]) -> bytes | None:
    """PNG of the run's last instant seen from above (the replay renderer); None without samples."""
    from pybullet_swarm.experiment.replay import load_replay, still_png
    from pybullet_swarm.plotting.replay import View

    try:
        data = load_replay(run_dir, metrics)
    except ConfigError:
        return None
    lx, ly = data.arena
    height = int(min(STILL_WIDTH, max(360, 0.94 * STILL_WIDTH * ly / lx + 110))) // 2 * 2
    return still_png(data, float(data.t[-1]), view=View.TOP, size=(STILL_WIDTH, height))


def run_page(run_dir: Path) -> RunPage:
    """What the page of a run directory shows."""
    path = run_dir / "metrics.json"
    metrics: dict[str, Any] = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}
    video = next((p.name for p in (run_dir / "video.mp4", run_dir / "video.gif") if p.is_file()), None)
    return RunPage(
        directory=str(run_dir.resolve()),
        scenario=read_scenario_data(run_dir) or {},
        metrics=metrics,
        flat_metrics=list(flatten_metrics(metrics).items()),
        events=read_events(run_dir / "events.csv"),
        figures=plot_files(run_dir),
        still=_still(run_dir, metrics),
        video=video,
    )


def write_run_report(run_dir: Path | str) -> Path:
    """Write ``report.html`` into a run directory; returns its path.

    Raises:
        ConfigError: not a run directory (neither ``timeseries.npz`` nor ``metrics.json``).
    """
    run_dir = Path(run_dir)
    if not ((run_dir / "timeseries.npz").is_file() or (run_dir / "metrics.json").is_file()):
        raise ConfigError("not a run directory (no timeseries.npz)", source=str(run_dir))
    text = run_report_html(run_page(run_dir))
    path = run_dir / REPORT_NAME
    atomic_write(path, lambda fh: fh.write(text))
    return path
