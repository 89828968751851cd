"""Figures of a tuning study, drawn from its trial records (``trials.csv`` rows) only.

- ``history.png``: every finished trial's objective value against its number, with the best so far
  (one panel per objective); failed trials are marked on the axis.
- ``importance.png``: PED-ANOVA importance of each parameter, one group of bars per objective.
- ``pareto.png``: the first two objectives of every finished trial, the Pareto-optimal ones
  joined by the front (multi-objective studies).
- ``tuned_vs_default.png``: the default against the tuned configuration on held-out seeds,
  mean and 95 % interval per planner (the scripted thesis study).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from pybullet_swarm.plotting.common import save_figure


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))


def plot_history(
    records: Sequence[Mapping[str, Any]],
    columns: Sequence[str],
    labels: Sequence[str],
    minimise: Sequence[bool],
    path: Path,
    *,
    title: str = "",
) -> Path:
    """Objective value per trial and the best so far.

    Args:
        records: trial records (``trial``, ``state`` and the value columns).
        columns: the value column of each objective.
        labels: the expression of each objective (axis labels).
        minimise: per objective, True when smaller is better.
        path: the figure file.
        title: figure title.
    """
    n = len(columns)
    fig = Figure(figsize=(7.0, 2.8 * n + 0.6), layout="constrained")
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    for ax, col, label, lower in zip(axes, columns, labels, minimise):
        done = [r for r in records if r.get("state") == "complete" and _finite(r.get(col))]
        x = np.array([r["trial"] for r in done], dtype=float)
        y = np.array([float(r[col]) for r in done], dtype=float)
        base = [r for r in done if r.get("baseline")]
        ax.plot(x, y, "o", ms=4, color="tab:blue", alpha=0.7, label="trial (mean over seeds)")
        if base:
            ax.plot(
                [r["trial"] for r in base],
                [float(r[col]) for r in base],
                "s",
                ms=7,
                mfc="none",
                color="tab:green",
                label="baseline (defaults)",
            )
        if len(y):
            order = np.argsort(x)
            best = np.minimum.accumulate(y[order]) if lower else np.maximum.accumulate(y[order])
            ax.step(x[order], best, where="post", color="tab:red", lw=1.8, label="best so far")
        failed = [r["trial"] for r in records if r.get("state") == "fail" and r.get("error")]
        if failed and len(y):
            ax.plot(
                failed, [np.nanmin(y) if lower else np.nanmax(y)] * len(failed), "x", color="0.4", label="failed trial"
            )
        ax.set_ylabel(label if len(label) <= 40 else label[:37] + "...", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    axes[-1].set_xlabel("trial")
    if title:
        fig.suptitle(f"{title}: optimisation history", fontsize=10)
    return save_figure(fig, path)


def plot_importance(importances: Mapping[str, Mapping[str, float]], path: Path, *, title: str = "") -> Path:
    """Horizontal bars of parameter importance (fraction of the objective's variance), per objective.

    Args:
        importances: ``{objective: {param: importance}}`` (each objective's importances sum to 1).
        path: the figure file.
        title: figure title.
    """
    params = list(dict.fromkeys(p for imp in importances.values() for p in imp))
    objs = list(importances)
    fig = Figure(figsize=(7.0, 0.5 * len(params) * max(1, len(objs)) + 1.4), layout="constrained")
    ax = fig.subplots()
    h = 0.8 / max(1, len(objs))
    ypos = np.arange(len(params), dtype=float)
    for j, obj in enumerate(objs):
        vals = [importances[obj].get(p, 0.0) for p in params]
        bars = ax.barh(ypos + (j - (len(objs) - 1) / 2) * h, vals, height=h, label=obj)
        for b, v in zip(bars, vals):
            ax.text(b.get_width() + 0.01, b.get_y() + b.get_height() / 2, f"{v:.2f}", va="center", fontsize=7)
    ax.set_yticks(ypos, [p.removeprefix("planner.params.") for p in params], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlim(0, 1.1)
    ax.set_xlabel("importance (PED-ANOVA, normalised to sum 1)")
    ax.grid(True, axis="x", alpha=0.3)
    if len(objs) > 1 or objs:
        ax.legend(fontsize=7, loc="lower right")
    if title:
        ax.set_title(f"{title}: parameter importance", fontsize=10)
    return save_figure(fig, path)


def plot_pareto(
    records: Sequence[Mapping[str, Any]],
    columns: Sequence[str],
    labels: Sequence[str],
    minimise: Sequence[bool],
    path: Path,
    *,
    title: str = "",
) -> Path:
    """The first two objectives of every finished trial with the Pareto front.

    Args:
        records: trial records (with the ``pareto`` flag).
        columns: the two value columns.
        labels: their expressions.
        minimise: per objective, True when smaller is better.
        path: the figure file.
        title: figure title.
    """
    cx, cy = columns[0], columns[1]
    done = [r for r in records if r.get("state") == "complete" and _finite(r.get(cx)) and _finite(r.get(cy))]
    front = sorted((r for r in done if r.get("pareto")), key=lambda r: float(r[cx]))
    fig = Figure(figsize=(6.4, 4.8), layout="constrained")
    ax = fig.subplots()
    ax.plot(
        [float(r[cx]) for r in done],
        [float(r[cy]) for r in done],
        "o",
        color="0.65",
        ms=4,
        label="trial (mean over seeds)",
    )
    if front:
        fx = [float(r[cx]) for r in front]
        fy = [float(r[cy]) for r in front]
        ax.step(fx, fy, where="post" if minimise[1] == minimise[0] else "pre", color="tab:red", lw=1.2)
        ax.plot(fx, fy, "o", color="tab:red", ms=6, label=f"Pareto front ({len(front)} trials)")
        for r, x, y in zip(front, fx, fy):
            ax.annotate(str(r["trial"]), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    base = [r for r in done if r.get("baseline")]
    if base:
        ax.plot(
            [float(r[cx]) for r in base],
            [float(r[cy]) for r in base],
            "s",
            ms=8,
            mfc="none",
            color="tab:green",
            label="baseline (defaults)",
        )
    whole = [r for r in done if r.get("completed") == 1 or r.get("pareto")]
    off = len(done) - len(whole)
    if whole and off:  # penalised trials (runs that did not complete) would squash the front: zoom in
        xs = [float(r[cx]) for r in whole]
        ys = [float(r[cy]) for r in whole]
        pad_x, pad_y = 0.08 * (max(xs) - min(xs) or 1.0), 0.08 * (max(ys) - min(ys) or 1.0)
        ax.set_xlim(min(xs) - pad_x, max(xs) + pad_x)
        ax.set_ylim(min(ys) - pad_y, max(ys) + pad_y)
        ax.text(
            0.99,
            0.01,
            f"{off} trial(s) with incomplete runs (penalised) beyond the axes",
            transform=ax.transAxes,
            ha="right",
            va="bottom",
            fontsize=7,
            color="0.4",
        )
    arrow = {True: "lower is better", False: "higher is better"}
    ax.set_xlabel(f"{labels[0]} ({arrow[bool(minimise[0])]})", fontsize=8)
    ax.set_ylabel(f"{labels[1]} ({arrow[bool(minimise[1])]})", fontsize=8)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    if title:
        ax.set_title(title, fontsize=10)
    return save_figure(fig, path)


def plot_tuned_vs_default(table: Sequence[Mapping[str, Any]], path: Path, *, ylabel: str, title: str = "") -> Path:
    """Default against tuned per planner: mean with its 95 % interval and every held-out run.

    Args:
        table: one record per planner and configuration: ``planner``, ``config`` (``default`` or
            ``tuned``), ``mean``, ``ci95_low``, ``ci95_high`` and ``values`` (per-run objective values).
        path: the figure file.
        ylabel: the objective's expression.
        title: figure title.
    """
    planners = list(dict.fromkeys(r["planner"] for r in table))
    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    ax = fig.subplots()
    colours = {"default": "tab:gray", "tuned": "tab:blue"}
    rng = np.random.default_rng(0)  # horizontal jitter of the points only
    for i, planner in enumerate(planners):
        for j, config in enumerate(("default", "tuned")):
            rec = next((r for r in table if r["planner"] == planner and r["config"] == config), None)
            if rec is None:
                continue
            x = i + (j - 0.5) * 0.35
            vals = np.asarray(rec.get("values") or [], dtype=float)
            ax.plot(x + rng.uniform(-0.06, 0.06, len(vals)), vals, "o", ms=3, alpha=0.5, color=colours[config])
            lo, hi = rec.get("ci95_low"), rec.get("ci95_high")
            err = None if not (_finite(lo) and _finite(hi)) else [[rec["mean"] - lo], [hi - rec["mean"]]]
            ax.errorbar(
                [x],
                [rec["mean"]],
                yerr=err,
                fmt="D",
                ms=7,
                capsize=5,
                color=colours[config],
                label=config if i == 0 else None,
            )
    ax.set_xticks(range(len(planners)), planners)
    ax.set_ylabel(ylabel if len(ylabel) <= 45 else ylabel[:42] + "...", fontsize=8)
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8, title="mean and 95 % CI", title_fontsize=7)
    if title:
        ax.set_title(title, fontsize=10)
    return save_figure(fig, path)


__all__ = ["plot_history", "plot_importance", "plot_pareto", "plot_tuned_vs_default"]
