"""Figures of a tour run: inspection points, planned legs and flown paths, top and side views."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from pybullet_swarm.plotting.common import save_figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from numpy.typing import ArrayLike, NDArray


_save = save_figure


def _colour(i: int) -> str:
    return f"C{i % 10}"


def _view(
    ax: Axes,
    axes: tuple[int, int],
    pts: NDArray[np.float64],
    planned: Sequence[NDArray[np.float64]],
    flown: NDArray[np.float64] | None,
    visited_by: NDArray[np.int64],
    labels: bool,
) -> None:
    """Draw one projection (axes: indices of the horizontal and vertical coordinates)."""
    a, b = axes
    if flown is not None:
        for i in range(flown.shape[1]):
            ax.plot(flown[:, i, a], flown[:, i, b], lw=1.0, color=_colour(i), alpha=0.9, zorder=3)
            ax.plot(flown[0, i, a], flown[0, i, b], "o", ms=6, mfc=_colour(i), mec="k", zorder=6)
    for i, path in enumerate(planned):
        if len(path) > 1:
            ax.plot(path[:, a], path[:, b], ls="--", lw=1.0, color=_colour(i), alpha=0.6, zorder=2)
    hit = visited_by >= 0
    ax.scatter(pts[~hit, a], pts[~hit, b], marker="x", s=40, c="k", zorder=5)
    ax.scatter(
        pts[hit, a],
        pts[hit, b],
        marker="o",
        s=30,
        c=[_colour(int(i)) for i in visited_by[hit]],
        edgecolors="k",
        linewidths=0.6,
        zorder=5,
    )
    if labels:
        for j, p in enumerate(pts):
            ax.annotate(str(j), (p[a], p[b]), xytext=(3, 3), textcoords="offset points", fontsize=6, color="0.25")
    ax.grid(alpha=0.25)


def plot_tour(
    points: ArrayLike,
    path: Path | str,
    *,
    arena_size: ArrayLike | None = None,
    planned: Sequence[ArrayLike] | None = None,
    flown: ArrayLike | None = None,
    visited_by: ArrayLike | None = None,
    visit_radius: float | None = None,
) -> Path:
    """Top view (x-y) and side view (x-z) of a tour: points, planned legs (dashed), flown paths.

    Points are coloured by the agent that visited them (black crosses: not visited); each agent's
    planned path (from its start, via its climbs, through its leg) is dashed in its colour and
    its flown path solid.

    Args:
        points: (W, 3) m, inspection points.
        path: PNG file to write.
        arena_size: (2,) m, the arena [0, Lx] x [0, Ly] (outlined in the top view).
        planned: per agent, (p_i, 3) m planned polyline.
        flown: (m, n, 3) m, recorded agent positions.
        visited_by: (W,) agent that visited each point, -1 for none.
        visit_radius: m, shown in the title.

    Returns:
        The file written.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    plans = [np.asarray(p, dtype=float).reshape(-1, 3) for p in (planned or [])]
    fl = None if flown is None else np.asarray(flown, dtype=float)
    if fl is not None and (fl.ndim != 3 or fl.shape[0] == 0):
        fl = None
    by = np.full(len(pts), -1, dtype=np.int64) if visited_by is None else np.asarray(visited_by, dtype=np.int64)
    fig = Figure(figsize=(12, 5.6), layout="constrained")
    top, side = fig.subplots(1, 2, width_ratios=[1.0, 1.25])
    _view(top, (0, 1), pts, plans, fl, by, labels=len(pts) <= 60)
    _view(side, (0, 2), pts, plans, fl, by, labels=False)
    if arena_size is not None:
        lx, ly = (float(v) for v in np.asarray(arena_size, dtype=float).ravel()[:2])
        top.add_patch(Rectangle((0.0, 0.0), lx, ly, fill=False, ec="k", lw=1.5))
        m = 0.05 * max(lx, ly)
        top.set_xlim(-m, lx + m)
        top.set_ylim(-m, ly + m)
        side.set_xlim(-m, lx + m)
    side.set_ylim(bottom=0.0)
    top.set_aspect("equal")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.set_title("top view")
    side.set_xlabel("x [m]")
    side.set_ylabel("z [m]")
    side.set_title("side view")
    n = max(len(plans), 0 if fl is None else fl.shape[1])
    handles = [Line2D([], [], color=_colour(i), lw=1.5, label=f"agent {i}") for i in range(n)]
    handles += [
        Line2D([], [], color="0.4", ls="--", label="planned"),
        Line2D([], [], color="0.4", label="flown"),
        Line2D([], [], ls="", marker="o", mfc="w", mec="k", label="start / visited point"),
        Line2D([], [], ls="", marker="x", color="k", label="not visited"),
    ]
    side.legend(handles=handles, fontsize=7, loc="upper right", ncol=2)
    visited = int(np.count_nonzero(by >= 0))
    radius = f", visit radius {visit_radius:g} m" if visit_radius is not None else ""
    fig.suptitle(f"tour: {visited} of {len(pts)} points visited{radius}")
    return _save(fig, Path(path))


def plot_saved_tour(tour_json: Path | str, timeseries: Path | str | None, path: Path | str) -> Path:
    """``plot_tour`` from a run's ``tour.json`` (and its flown paths from ``timeseries.npz``, when present)."""
    import json

    data = json.loads(Path(tour_json).read_text())
    flown = None
    if timeseries is not None and Path(timeseries).is_file():
        with np.load(timeseries) as z:
            flown = z["positions"].astype(float) if "positions" in z.files else None
    plan = data.get("plan") or {}
    return plot_tour(
        data["points"],
        path,
        arena_size=data.get("arena_size"),
        planned=plan.get("paths"),
        flown=flown,
        visited_by=data.get("visited_by"),
        visit_radius=data.get("visit_radius"),
    )
