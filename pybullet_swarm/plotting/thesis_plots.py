"""The thesis comparison figure: our means with 95 % intervals next to the thesis's single runs."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from pybullet_swarm.plotting.common import save_figure

PANELS = (("proximity_violations", "collisions (centre distance < diameter)"),
          ("completion_time_s", "completion time [s]"),
          ("utility_of_space", "utility of space"))


def thesis_comparison_figure(table: Sequence[Mapping[str, Any]], planners: Sequence[str], path: Path) -> Path:
    """Bars of the mean with 95 % t-intervals per planner, thesis values as diamonds.

    Args:
        table: rows with ``planner``, ``metric``, ``mean``, ``ci95_low``, ``ci95_high``, ``thesis``.
        planners: planners in drawing order.
        path: PNG file to write.
    """
    fig = Figure(figsize=(12, 4), layout="constrained")
    axes = fig.subplots(1, len(PANELS))
    x = np.arange(len(planners))
    for ax, (metric, label) in zip(axes, PANELS):
        rows = {r["planner"]: r for r in table if r["metric"] == metric}
        mean = np.array([float(rows[p]["mean"]) if p in rows else np.nan for p in planners])
        lo = np.array([float(rows[p]["ci95_low"]) if p in rows else np.nan for p in planners])
        hi = np.array([float(rows[p]["ci95_high"]) if p in rows else np.nan for p in planners])
        err = np.vstack([np.nan_to_num(mean - lo), np.nan_to_num(hi - mean)])
        ax.bar(x, mean, color="tab:blue", alpha=0.7, label="this testbed (mean, 95 % CI)")
        ax.errorbar(x, mean, yerr=err, fmt="none", ecolor="k", capsize=4)
        thesis = [rows[p].get("thesis") if p in rows else None for p in planners]
        tx = [i for i, v in enumerate(thesis) if v is not None]
        if tx:
            ax.scatter(tx, [float(thesis[i]) for i in tx], marker="D", color="tab:red", zorder=3,
                       label="thesis (single run)")
        ax.set_xticks(x, [p.replace("_", "\n") for p in planners], fontsize=8)
        ax.set_title(label, fontsize=10)
        ax.grid(alpha=0.3, axis="y")
    axes[0].legend(fontsize=7)
    return save_figure(fig, path)
