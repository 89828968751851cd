"""The thesis comparison figure: our means with 95 % intervals next to the thesis's single runs."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from pybullet_swarm.plotting.common import save_figure

PANELS = (
    ("thesis_collisions", "collisions (thesis count: per agent, NN distance < diameter)"),
    ("completion_time_s", "completion time [s]"),
    ("utility_of_space", "utility of space"),
)


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
            ax.scatter(
                tx,
                [float(thesis[i] or 0.0) for i in tx],
                marker="D",
                color="tab:red",
                zorder=3,
                label="thesis (single run)",
            )
        ax.set_xticks(x, [p.replace("_", "\n") for p in planners], fontsize=8)
        ax.set_title(label, fontsize=10)
        ax.grid(alpha=0.3, axis="y")
    axes[0].legend(fontsize=7)
    return save_figure(fig, path)


def ablation_distributions_figure(
    columns: Sequence[Mapping[str, Any]], metrics: Sequence[tuple[str, str]], path: Path, *, rotate: bool = False
) -> Path:
    """Per planner (columns) and metric (rows): every run of each configuration as a point, with a box,
    and the thesis's reported single run as a red diamond.

    Args:
        columns: one mapping per planner: ``planner`` (title), ``configs``: a list of ``(label, runs)``
            where ``runs`` is a list of ``{metric: value, 'completed': bool, 'sim_time_s': s}``;
            ``thesis``: ``{metric: value}`` of the thesis's table (may be empty).
        metrics: ``(key, axis label)`` per row; for ``completion_time_s`` a run that did not complete
            is drawn at its simulated time with a cross (a lower bound of its completion time).
        path: PNG file to write.
        rotate: turn the configuration labels (many configurations).
    """
    ncol = len(columns)
    width = max(4.0, 0.45 * max(len(c["configs"]) + 1 for c in columns)) if rotate else 4.0
    fig = Figure(figsize=(width * ncol, 2.9 * len(metrics) + (1.2 if rotate else 0.3)), layout="constrained")
    axes = np.atleast_2d(fig.subplots(len(metrics), ncol, squeeze=False))
    rng = np.random.default_rng(0)  # jitter only
    for j, col in enumerate(columns):
        labels = ["thesis"] + [label for label, _ in col["configs"]]
        for i, (metric, axis_label) in enumerate(metrics):
            ax = axes[i, j]
            thesis = col.get("thesis", {}).get(metric)
            if thesis is not None:
                ax.scatter([0], [float(thesis)], marker="D", s=40, color="tab:red", zorder=3)
            for k, (_, runs) in enumerate(col["configs"], start=1):
                done = [
                    float(r[metric])
                    for r in runs
                    if _finite(r.get(metric)) and (metric != "completion_time_s" or r.get("completed"))
                ]
                if done:
                    ax.boxplot(
                        [done],
                        positions=[k],
                        widths=0.5,
                        showfliers=False,
                        medianprops={"color": "k"},
                        boxprops={"color": "0.4"},
                    )
                    ax.scatter(
                        k + rng.uniform(-0.15, 0.15, len(done)), done, s=10, color="tab:blue", alpha=0.7, zorder=3
                    )
                if metric == "completion_time_s":
                    cut = [
                        float(r["sim_time_s"]) for r in runs if not r.get("completed") and _finite(r.get("sim_time_s"))
                    ]
                    if cut:
                        ax.scatter(
                            k + rng.uniform(-0.15, 0.15, len(cut)), cut, marker="x", s=18, color="tab:orange", zorder=3
                        )
            ax.set_xticks(
                range(len(labels)),
                labels if i == len(metrics) - 1 else [""] * len(labels),
                rotation=90 if rotate else 0,
                fontsize=7,
            )
            ax.set_xlim(-0.6, len(labels) - 0.4)
            ax.grid(alpha=0.3, axis="y")
            if j == 0:
                ax.set_ylabel(axis_label, fontsize=8)
            if i == 0:
                ax.set_title(col["planner"], fontsize=10)
    fig.suptitle(
        "thesis (red: its single reported run), our runs per seed (blue; orange x: not completed, "
        "drawn at the time limit)",
        fontsize=8,
    )
    return save_figure(fig, path)


def _finite(v: Any) -> bool:
    return isinstance(v, (bool, int, float)) and np.isfinite(float(v))
