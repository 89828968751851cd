"""Figures of a construction run (thesis Figs. 3.8-3.12, 5.3, 5.4), drawn from saved arrays only."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.artist import Artist
from matplotlib.collections import PatchCollection
from matplotlib.figure import Figure

from pybullet_swarm.plotting.common import save_figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Rectangle
from numpy.typing import ArrayLike

from pybullet_swarm.metrics.collisions import COLLISION_CLASSES

MAX_AGENTS_DRAWN = 10
"""Above this many agents the nearest-neighbour figure shows the min/median/max over agents."""


_save = save_figure


def plot_nn_distance(t: ArrayLike, nn: ArrayLike, threshold: float, path: Path | str) -> Path:
    """Nearest-neighbour distance of each agent over time with the collision line (thesis Fig. 3.12).

    Args:
        t: (m,) s.
        nn: (m, n) m, distance of each agent to its nearest other agent.
        threshold: m, collision distance (drawn dashed).
        path: PNG file to write.

    Returns:
        The file written.
    """
    tt = np.asarray(t, dtype=float)
    d = np.asarray(nn, dtype=float).reshape(tt.size, -1)
    fig = Figure(figsize=(9, 4.5), layout="constrained")
    ax = fig.subplots()
    n = d.shape[1]
    if n <= MAX_AGENTS_DRAWN:
        for i in range(n):
            ax.plot(tt, d[:, i], lw=1.0, label=f"agent {i}")
    else:
        ax.fill_between(tt, d.min(axis=1), d.max(axis=1), alpha=0.25, label=f"min-max over {n} agents")
        ax.plot(tt, np.median(d, axis=1), lw=1.2, label="median")
    ax.axhline(threshold, color="k", ls="--", lw=1.2, label=f"collision line {threshold:.2f} m")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("distance to nearest agent [m]")
    ax.set_title("nearest-neighbour distance (centre to centre)")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=3, loc="upper right")
    return _save(fig, path)


def plot_box_to_goal(t: ArrayLike, total: ArrayLike, path: Path | str, completion_time: float | None = None) -> Path:
    """Total box-to-goal distance over time (thesis Fig. 5.4).

    Args:
        t: (m,) s.
        total: (m,) m, summed distance of the boxes to their assigned slots.
        path: PNG file to write.
        completion_time: s, marked with a vertical line when given.

    Returns:
        The file written.
    """
    fig = Figure(figsize=(9, 4.5), layout="constrained")
    ax = fig.subplots()
    ax.plot(np.asarray(t, dtype=float), np.asarray(total, dtype=float), lw=1.5, color="tab:blue")
    if completion_time is not None:
        ax.axvline(completion_time, color="k", ls=":", lw=1.2, label=f"completed at {completion_time:.1f} s")
        ax.legend(loc="upper right")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("total box-to-goal distance [m]")
    ax.set_title("distance of the boxes to the goal structure")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def _slot_layers(slots: np.ndarray, box_size: float) -> np.ndarray:
    """(S,) layer index of each slot, 0 at the lowest, from its height in box edges."""
    if slots.shape[0] == 0:
        return np.zeros(0, dtype=int)
    step = box_size if box_size > 0 else 1.0
    return np.rint((slots[:, 2] - slots[:, 2].min()) / step).astype(int)


def _obstacle_patches(obstacles: Sequence[ArrayLike]) -> list[Any]:
    """Footprint patches: a row (x, y, r) is a circle, (x_min, y_min, x_max, y_max) a rectangle, m."""
    patches: list[Any] = []
    for row in obstacles:
        r = np.asarray(row, dtype=float).ravel()
        if r.size == 3:
            patches.append(Circle((r[0], r[1]), r[2]))
        elif r.size == 4:
            patches.append(Rectangle((r[0], r[1]), r[2] - r[0], r[3] - r[1]))
        else:
            raise ValueError(f"obstacles: a row needs 3 (circle) or 4 (rectangle) numbers, got {r.size}")
    return patches


def plot_top_view(
    positions: ArrayLike,
    arena_size: ArrayLike,
    boxes_start: ArrayLike,
    slots: ArrayLike,
    box_size: float,
    path: Path | str,
    obstacles: Sequence[ArrayLike] | None = None,
) -> Path:
    """Top view of the arena with the depot, the goal slots and every agent's flight path.

    The thesis's qualitative "shape of flight pattern" metric (section 3.6).

    Args:
        positions: (m, n, 3) m, agent centres.
        arena_size: (2,) m, the arena is [0, Lx] x [0, Ly].
        boxes_start: (B, 3) m, box centres in the depot (filled squares).
        slots: (S, 3) m, goal slot centres (outlined squares, darker for higher layers).
        box_size: m, box edge.
        path: PNG file to write.
        obstacles: footprints, each row (x, y, r) for a pillar or (x_min, y_min, x_max, y_max) for
            a box, m.

    Returns:
        The file written.
    """
    p = np.asarray(positions, dtype=float)
    lx, ly = (float(v) for v in np.asarray(arena_size, dtype=float).ravel()[:2])
    boxes = np.asarray(boxes_start, dtype=float).reshape(-1, 3)
    sl = np.asarray(slots, dtype=float).reshape(-1, 3)
    half = 0.5 * box_size
    fig = Figure(figsize=(10, 4.8), layout="constrained")
    ax = fig.subplots()
    ax.add_patch(Rectangle((0.0, 0.0), lx, ly, fill=False, ec="k", lw=1.5))
    if obstacles is not None and len(obstacles):
        ax.add_collection(PatchCollection(_obstacle_patches(obstacles), fc="0.55", ec="0.3", zorder=2))
    ax.add_collection(
        PatchCollection(
            [Rectangle((x - half, y - half), box_size, box_size) for x, y in boxes[:, :2]],
            fc="peru",
            ec="saddlebrown",
            zorder=3,
        )
    )
    layers = _slot_layers(sl, box_size)
    n_layers = int(layers.max()) + 1 if layers.size else 0
    # draw lower layers first so the upper (darker) outlines stay visible
    for layer in range(n_layers):
        grey = 0.85 - 0.6 * layer / max(1, n_layers - 1)
        rects = [Rectangle((x - half, y - half), box_size, box_size) for x, y in sl[layers == layer, :2]]
        ax.add_collection(PatchCollection(rects, fc=(grey, grey, grey, 0.5), ec="k", lw=1.0, zorder=3 + layer))
    n = p.shape[1] if p.ndim == 3 else 0
    colours = [f"C{i % 10}" for i in range(n)]
    for i in range(n):
        ax.plot(p[:, i, 0], p[:, i, 1], lw=0.8, color=colours[i], alpha=0.85, zorder=5)
        if p.shape[0]:
            ax.plot(p[0, i, 0], p[0, i, 1], "o", ms=6, mfc=colours[i], mec="k", zorder=6)
    handles: list[Artist] = [Patch(fc="peru", ec="saddlebrown", label="boxes (depot)")]
    handles += [
        Patch(fc=str(0.85 - 0.6 * k / max(1, n_layers - 1)), ec="k", label=f"slots, layer {k}") for k in range(n_layers)
    ]
    handles.append(Line2D([], [], ls="", marker="o", mfc="w", mec="k", label="agent start"))
    ax.legend(handles=handles, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=len(handles))
    margin = 0.05 * max(lx, ly)
    ax.set_xlim(-margin, lx + margin)
    ax.set_ylim(-margin, ly + margin)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"flight paths of {n} agents (top view)")
    ax.grid(alpha=0.2)
    return _save(fig, path)


def plot_acceleration(t: ArrayLike, acc: ArrayLike, path: Path | str, agent: int = 0) -> Path:
    """Acceleration of one agent over time: x bold, y and z faint (thesis Figs. 3.8-3.10).

    Args:
        t: (m,) s.
        acc: (m, 3) m/s^2 of the agent, or (m, n, 3) m/s^2 of the swarm (then ``agent`` selects).
        path: PNG file to write.
        agent: index of the agent (used for the title when ``acc`` is (m, 3)).

    Returns:
        The file written.
    """
    tt = np.asarray(t, dtype=float)
    a = np.asarray(acc, dtype=float)
    if a.ndim == 3:
        a = a[:, agent, :]
    fig = Figure(figsize=(9, 4.5), layout="constrained")
    ax = fig.subplots()
    ax.plot(tt, a[:, 0], lw=1.3, color="C0", label="x")
    ax.plot(tt, a[:, 1], lw=0.8, color="C1", alpha=0.45, label="y")
    ax.plot(tt, a[:, 2], lw=0.8, color="C2", alpha=0.45, label="z")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("acceleration [m/s$^2$]")
    ax.set_title(f"acceleration of agent {agent}")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")
    return _save(fig, path)


def plot_collision_timeline(
    events: Sequence[Any], sim_time: float, path: Path | str, classes: Sequence[str] = COLLISION_CLASSES
) -> Path:
    """Timeline of collision events, one row per class with its count (thesis Fig. 5.3).

    Args:
        events: objects with ``time_s`` (s), ``kind`` (a class name or ``CollisionClass``), ``a``
            and ``b`` (body ids); kinds not in ``classes`` are ignored.
        sim_time: s, length of the run (x-axis extent).
        path: PNG file to write.
        classes: class names, one row each, top to bottom.

    Returns:
        The file written.
    """
    names = [str(getattr(c, "value", c)) for c in classes]
    times: dict[str, list[float]] = {c: [] for c in names}
    for ev in events:
        kind = str(getattr(ev.kind, "value", ev.kind))
        if kind in times:
            times[kind].append(float(ev.time_s))
    fig = Figure(figsize=(9, 1.2 + 0.55 * len(names)), layout="constrained")
    ax = fig.subplots()
    rows = np.arange(len(names))[::-1]  # first class on top
    for k, (row, name) in enumerate(zip(rows, names)):
        ts = np.asarray(times[name])
        ax.plot(ts, np.full(ts.shape, row), "|", ms=14, mew=1.6, color=f"C{k % 10}")
    ax.set_yticks(rows, [f"{c} ({len(times[c])})" for c in names])
    ax.set_ylim(-0.7, len(names) - 0.3)
    ax.set_xlim(0.0, max(float(sim_time), 1e-9))
    ax.set_xlabel("time [s]")
    total = sum(len(v) for v in times.values())
    ax.set_title(f"collision events ({total} in total)")
    ax.grid(axis="x", alpha=0.3)
    return _save(fig, path)
