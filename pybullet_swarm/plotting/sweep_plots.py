"""Comparison figures of many runs, drawn from result rows only (``runs.csv`` of a sweep, run directories).

- ``box_<metric>.png``: one box plot per metric across configurations, every run drawn as a point.
- ``time_vs_collisions.png``: completion time against collisions, one colour per configuration;
  runs that did not complete are drawn at their end time with a cross.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from pybullet_swarm.plotting.common import save_figure
from matplotlib.ticker import MaxNLocator
from numpy.typing import NDArray

Group = tuple[str, Sequence[Mapping[str, Any]]]  # (configuration label, its rows)

#: Metrics drawn first, when present.
PREFERRED = (
    "completed",
    "completion_time_s",
    "sim_time_s",
    "collisions.total",
    "collisions.agent_agent",
    "path_length_m.total",
    "energy_j",
)


_save = save_figure


def _values(rows: Sequence[Mapping[str, Any]], metric: str) -> NDArray[np.float64]:
    """Finite values of a metric over rows, (k,)."""
    out = []
    for r in rows:
        v = r.get(metric)
        if isinstance(v, (bool, int, float)) and math.isfinite(float(v)):
            out.append(float(v))
    return np.asarray(out, dtype=float)


def _file_name(metric: str) -> str:
    return "box_" + re.sub(r"[^A-Za-z0-9_.-]+", "_", metric) + ".png"


def _wrap(label: str, width: int = 18) -> str:
    """Break a long configuration label at spaces so that tick labels stay readable."""
    words, lines, line = label.split(" "), [], ""
    for w in words:
        if line and len(line) + 1 + len(w) > width:
            lines.append(line)
            line = w
        else:
            line = f"{line} {w}".strip()
    lines.append(line)
    return "\n".join(lines)


def plot_metric_box(groups: Sequence[Group], metric: str, path: Path) -> Path:
    """Box plot of one metric per configuration, with each run as a jittered point.

    Args:
        groups: (label, rows) per configuration.
        metric: the column to draw.
        path: PNG file to write.

    Returns:
        The file written.
    """
    data = [_values(rows, metric) for _, rows in groups]
    labels = [_wrap(label) for label, _ in groups]
    fig = Figure(figsize=(max(5.0, 1.3 * len(groups) + 2.0), 4.5), layout="constrained")
    ax = fig.subplots()
    positions = np.arange(1, len(groups) + 1)
    drawn = [(p, d) for p, d in zip(positions, data) if d.size]
    if drawn:
        ax.boxplot(
            [d for _, d in drawn],
            positions=[p for p, _ in drawn],
            widths=0.5,
            showfliers=False,
            medianprops={"color": "k"},
        )
    rng = np.random.default_rng(0)  # fixed jitter: the same figure every time
    for p, d in zip(positions, data):
        ax.plot(p + rng.uniform(-0.12, 0.12, d.size), d, "o", ms=4, alpha=0.6, color="tab:blue")
        ax.annotate(f"n={d.size}", (p, 1.0), xycoords=("data", "axes fraction"), ha="center", va="bottom", fontsize=7)
    ax.set_xticks(positions, labels, fontsize=8)
    ax.set_xlim(0.4, len(groups) + 0.6)
    ax.set_ylabel(metric)
    ax.set_title(f"{metric} per configuration", pad=14)
    ax.grid(alpha=0.3, axis="y")
    return _save(fig, path)


def plot_time_vs_collisions(groups: Sequence[Group], path: Path) -> Path:
    """Completion time against total collisions, one colour per configuration.

    Completed runs are dots at ``completion_time_s``; the others are crosses at their end time
    (``sim_time_s``). Collision counts are jittered by up to +-0.15 so that equal counts stay visible.

    Args:
        groups: (label, rows) per configuration; rows need ``collisions.total`` and ``sim_time_s``.
        path: PNG file to write.

    Returns:
        The file written.
    """
    fig = Figure(figsize=(8, 5), layout="constrained")
    ax = fig.subplots()
    rng = np.random.default_rng(0)
    colours = [f"C{i % 10}" for i in range(len(groups))]
    any_open = False
    top = 1.0
    for (label, rows), colour in zip(groups, colours):
        done_x, done_y, open_x, open_y = [], [], [], []
        for r in rows:
            c, t_end, t_done = r.get("collisions.total"), r.get("sim_time_s"), r.get("completion_time_s")
            if not isinstance(c, (int, float)):
                continue
            if isinstance(t_done, (int, float)) and r.get("exit_status") == "completed":
                done_x.append(float(t_done))
                done_y.append(float(c))
            elif isinstance(t_end, (int, float)):
                open_x.append(float(t_end))
                open_y.append(float(c))
        top = max([top, *done_y, *open_y])
        jit = lambda y: np.asarray(y) + rng.uniform(-0.15, 0.15, len(y))  # noqa: E731
        ax.scatter(done_x, jit(done_y), s=28, color=colour, alpha=0.75, label=label)
        if open_x:
            any_open = True
            ax.scatter(open_x, jit(open_y), s=36, color=colour, marker="x", alpha=0.9)
    if any_open:
        ax.scatter([], [], marker="x", color="0.3", label="not completed (at end time)")
    ax.set_xlabel("completion time [s]")
    ax.set_ylabel("collisions (all contact classes, jittered +-0.15)")
    ax.set_title("completion time vs collisions")
    ax.set_ylim(-0.5, top + 0.5)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.grid(alpha=0.3)
    if groups:
        ax.legend(fontsize=8, loc="best")
    return _save(fig, path)


def plot_comparison(groups: Sequence[Group], metrics: Sequence[str], out_dir: Path) -> list[Path]:
    """Draw every comparison figure into ``out_dir``; returns the files written.

    A metric with the same value in every run gets no box plot (there is nothing to compare).

    Args:
        groups: (label, rows) per configuration, rows of runs that did not raise.
        metrics: numeric columns to draw.
        out_dir: figure directory.
    """
    out_dir = Path(out_dir)
    order = [m for m in PREFERRED if m in metrics] + [m for m in metrics if m not in PREFERRED]
    files = []
    for m in order:
        values = np.concatenate([_values(rows, m) for _, rows in groups]) if groups else np.empty(0)
        if values.size == 0 or np.ptp(values) == 0.0:
            continue
        files.append(plot_metric_box(groups, m, out_dir / _file_name(m)))
    if any(r.get("collisions.total") is not None for _, rows in groups for r in rows):
        files.append(plot_time_vs_collisions(groups, out_dir / "time_vs_collisions.png"))
    return files
