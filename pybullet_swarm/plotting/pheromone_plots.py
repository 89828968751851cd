"""Figures of a pheromone medium (thesis Figs. 5.2, 6.1, 6.2), drawn from saved arrays only."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure

from pybullet_swarm.plotting.common import save_figure
from numpy.typing import ArrayLike


_save = save_figure


def plot_pheromone_map(
    values_xy: ArrayLike, cell: float, path: Path | str, *, title: str, extent: ArrayLike | None = None
) -> Path:
    """One pheromone layer seen from above: a cell map, positive red, negative blue (thesis Fig. 5.2).

    Args:
        values_xy: (nx, ny) pheromone values, the column value of largest magnitude.
        cell: m, edge of a cell.
        path: PNG file to write.
        title: figure title.
        extent: (2,) m, (Lx, Ly) of the arena (default: nx * cell, ny * cell).

    Returns:
        The file written.
    """
    v = np.asarray(values_xy, dtype=float)
    if v.ndim != 2:
        raise ValueError(f"values_xy: expected shape (nx, ny), got {v.shape}")
    lx, ly = (v.shape[0] * cell, v.shape[1] * cell) if extent is None else np.asarray(extent, dtype=float).ravel()[:2]
    span = float(np.max(np.abs(v))) if v.size else 0.0
    span = span if span > 0 else 1.0
    fig = Figure(figsize=(9, 0.9 + 7.5 * v.shape[1] / max(v.shape[0], 1)), layout="constrained")
    ax = fig.subplots()
    im = ax.imshow(
        v.T,
        origin="lower",
        extent=(0.0, v.shape[0] * cell, 0.0, v.shape[1] * cell),
        cmap="RdBu_r",
        norm=TwoSlopeNorm(vcenter=0.0, vmin=-span, vmax=span),
        interpolation="nearest",
    )
    ax.set_xlim(0.0, lx)
    ax.set_ylim(0.0, ly)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title)
    fig.colorbar(im, ax=ax, shrink=0.9, label="pheromone")
    return _save(fig, Path(path))


def plot_pheromone_activity(t: ArrayLike, marked: Mapping[str, ArrayLike], path: Path | str) -> Path:
    """Number of marked cells of each layer over time.

    Args:
        t: (k,) s, snapshot times.
        marked: layer name -> (k,) cells holding a non-zero value.
        path: PNG file to write.

    Returns:
        The file written.
    """
    return _layer_lines(t, marked, "marked", "marked cells", "pheromone activity", path)


def plot_pheromone_mass(t: ArrayLike, mass: Mapping[str, ArrayLike], path: Path | str) -> Path:
    """Pheromone mass (sum of |value| over all cells) of each layer over time.

    Args:
        t: (k,) s, snapshot times.
        mass: layer name -> (k,) total |value|.
        path: PNG file to write.
    """
    return _layer_lines(t, mass, "mass", "pheromone mass [sum of |value|]", "pheromone mass over time", path)


def _layer_lines(
    t: ArrayLike, series: Mapping[str, ArrayLike], what: str, ylabel: str, title: str, path: Path | str
) -> Path:
    """One line per layer over the snapshot times ``t`` (each series checked against its shape)."""
    tt = np.asarray(t, dtype=float)
    fig = Figure(figsize=(9, 4), layout="constrained")
    ax = fig.subplots()
    for name, values in series.items():
        v = np.asarray(values, dtype=float)
        if v.shape != tt.shape:
            raise ValueError(f"{what}[{name!r}]: expected shape {tt.shape}, got {v.shape}")
        ax.plot(tt, v, lw=1.5, label=name)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, Path(path))


def plot_pheromone_series(
    t: ArrayLike, history: ArrayLike, cell: float, extent: ArrayLike, path: Path | str, *, title: str, count: int = 8
) -> Path:
    """A series of top views of one layer at ``count`` evenly spaced snapshots (thesis Fig. 6.2).

    Args:
        t: (k,) s, snapshot times.
        history: (k, nx, ny) horizontal views of the layer.
        cell: m, cell size.
        extent: (2,) m, arena size.
        path: PNG file to write.
        title: figure title.
        count: number of panels.
    """
    tt = np.asarray(t, dtype=float)
    hist = np.asarray(history, dtype=float)
    picks = np.unique(np.linspace(0, len(tt) - 1, min(count, len(tt))).round().astype(int))
    cols = 2
    rows = int(np.ceil(len(picks) / cols))
    fig = Figure(figsize=(11, 1.6 * rows + 0.8), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    vmax = max(float(np.abs(hist).max()), 1e-9)
    ext = np.asarray(extent, dtype=float)
    im = None
    for ax, j in zip(axes, picks):
        im = ax.imshow(
            hist[j].T,
            origin="lower",
            extent=(0, ext[0], 0, ext[1]),
            vmin=0.0,
            vmax=vmax,
            cmap="viridis",
            aspect="equal",
            interpolation="nearest",
        )
        ax.set_title(f"t = {tt[j]:.1f} s", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes[len(picks) :]:
        ax.set_visible(False)
    if im is not None:
        fig.colorbar(im, ax=axes.tolist(), shrink=0.8)
    fig.suptitle(title)
    return _save(fig, Path(path))


def plot_pheromones(arrays: Mapping[str, Any], out_dir: Path | str, *, persistent: Iterable[str] = ()) -> list[Path]:
    """All figures of a saved pheromone medium (the contents of ``pheromones.npz``).

    A persistent layer (no fading) is drawn as it ended; a fading layer, whose end state says
    little, at its busiest snapshot (thesis Fig. 6.1, a snapshot of the agents' positions).

    Args:
        arrays: ``cell``, ``extent`` (3,), ``layers``, ``snapshot_t`` (k,), and per layer ``<layer>``
            (nx, ny, nz), ``<layer>_history`` (k, nx, ny), ``<layer>_marked`` (k,).
        out_dir: directory of the figures.
        persistent: layers drawn in their final state.

    Returns:
        The files written: ``pheromone_<layer>.png`` per layer and ``pheromone_activity.png``.
    """
    out = Path(out_dir)
    cell = float(arrays["cell"])
    extent = np.asarray(arrays["extent"], dtype=float)
    keep = set(persistent)
    t = np.asarray(arrays["snapshot_t"], dtype=float)
    written: list[Path] = []
    marked: dict[str, Any] = {}
    for name in [str(n) for n in np.asarray(arrays["layers"]).ravel()]:
        hist = np.asarray(arrays[f"{name}_history"])
        counts = np.asarray(arrays[f"{name}_marked"])
        marked[name] = counts
        if name in keep or hist.shape[0] == 0:
            v = np.asarray(arrays[name], dtype=float)
            k = np.argmax(np.abs(v), axis=2)
            xy = np.take_along_axis(v, k[:, :, None], axis=2)[:, :, 0]
            title = f"pheromone layer '{name}' at the end of the run"
        else:
            j = int(np.argmax(counts))
            xy = hist[j]
            title = f"pheromone layer '{name}' at t = {t[j]:.1f} s (most cells marked)"
        written.append(plot_pheromone_map(xy, cell, out / f"pheromone_{name}.png", title=title, extent=extent[:2]))
    if t.size:
        written.append(plot_pheromone_activity(t, marked, out / "pheromone_activity.png"))
        masses = {name: arrays[f"{name}_mass"] for name in marked if f"{name}_mass" in arrays}
        if masses:
            written.append(plot_pheromone_mass(t, masses, out / "pheromone_mass.png"))
        for name in marked:
            hist = np.asarray(arrays[f"{name}_history"])
            if name not in keep and hist.shape[0] > 1:
                written.append(
                    plot_pheromone_series(
                        t,
                        hist,
                        cell,
                        extent[:2],
                        out / f"pheromone_{name}_series.png",
                        title=f"pheromone layer '{name}' over the run",
                    )
                )
    return written
