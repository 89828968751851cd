"""The benchmark figure, drawn from a benchmark JSON only (``experiment.benchmark``).

Four panels, one bar (or column) per configuration (planner + avoidance layer): the completion
rate; the median completion time with its bootstrap 95 % interval; the share of runs with a
contact of each class; and the completion rate of every layout (a heat map).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np
from matplotlib.figure import Figure

from pybullet_swarm.plotting.common import save_figure


def _label(c: Mapping[str, Any]) -> str:
    return str(c["planner"]) if c["avoidance"] == "none" else f"{c['planner']}\n+ {c['avoidance']}"


def benchmark_figure(data: Mapping[str, Any], path: Path) -> Path:
    """Draw the benchmark figure of ``data`` (a benchmark JSON) into ``path`` (png); returns the path."""
    configs = list(data.get("configurations", []))
    labels = [_label(c) for c in configs]
    x = np.arange(len(configs))
    layouts = list(data.get("layouts", []))
    fig = Figure(figsize=(11.0, 4.0 + 0.22 * len(layouts)), layout="constrained")
    grid = fig.add_gridspec(2, 3, height_ratios=[1.0, max(1.0, 0.12 * len(layouts))])
    ax_done, ax_time, ax_contact = (fig.add_subplot(grid[0, k]) for k in range(3))
    rate = [c["completion_rate"] if c.get("completion_rate") is not None else np.nan for c in configs]
    ax_done.bar(x, rate, color="tab:green")
    ax_done.set_ylim(0.0, 1.05)
    ax_done.set_title("completed / runs", fontsize=10)
    med = np.array([c["median_time_s"] if c.get("median_time_s") is not None else np.nan for c in configs])
    lo = np.array([(c.get("median_time_ci") or [m, m])[0] for c, m in zip(configs, med)], dtype=float)
    hi = np.array([(c.get("median_time_ci") or [m, m])[1] for c, m in zip(configs, med)], dtype=float)
    ax_time.bar(x, med, color="tab:blue")
    ax_time.errorbar(x, med, yerr=[np.nan_to_num(med - lo), np.nan_to_num(hi - med)], fmt="none", color="k", capsize=4)
    ax_time.set_title("median completion time [s] (95 % CI)", fontsize=10)
    classes = list(data.get("contact_classes", []))
    width = 0.8 / max(1, len(classes))
    for k, cls in enumerate(classes):
        share = [c["contact_runs"].get(cls, 0) / c["runs"] if c.get("runs") else np.nan for c in configs]
        ax_contact.bar(x - 0.4 + width * (k + 0.5), share, width, label=cls.replace("_", "-"))
    ax_contact.set_ylim(0.0, 1.05)
    ax_contact.set_title("runs with a contact / runs", fontsize=10)
    if classes:
        ax_contact.legend(fontsize=7)
    for ax in (ax_done, ax_time, ax_contact):
        ax.set_xticks(x, labels, fontsize=7)
    heat = fig.add_subplot(grid[1, :])
    values = np.full((len(configs), len(layouts)), np.nan)
    for i, c in enumerate(configs):
        for rec in c.get("layouts", []):
            if rec["layout"] in layouts and rec.get("completion_rate") is not None:
                values[i, layouts.index(rec["layout"])] = rec["completion_rate"]
    im = heat.imshow(values, vmin=0.0, vmax=1.0, cmap="RdYlGn", aspect="auto")
    heat.set_yticks(range(len(configs)), [s.replace("\n", " ") for s in labels], fontsize=7)
    heat.set_xticks(range(len(layouts)), layouts, rotation=60, ha="right", fontsize=7)
    heat.set_title("completed / runs per layout", fontsize=10)
    for (i, j), v in np.ndenumerate(values):
        heat.text(j, i, "-" if not math.isfinite(v) else f"{v:.2f}", ha="center", va="center", fontsize=6)
    fig.colorbar(im, ax=heat, fraction=0.02)
    fig.suptitle(
        f"{data.get('suite')} v{data.get('suite_version')} {data.get('split')} ({data.get('commit')}, "
        f"{data.get('recorded_runs')} runs)",
        fontsize=11,
    )
    return save_figure(fig, path)
