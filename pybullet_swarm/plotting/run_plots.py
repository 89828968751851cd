"""Figures of one run, drawn from its saved results (never from a live simulation)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from pybullet_swarm.experiment.recorder import TimeSeries

MAX_AGENTS_DRAWN = 10


def _agents(ts: TimeSeries) -> range:
    return range(min(ts.positions.shape[1], MAX_AGENTS_DRAWN))


def _save(fig: Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    fig.savefig(tmp, dpi=110)
    tmp.replace(path)
    return path


def plot_positions(ts: TimeSeries, path: Path) -> Path:
    """Position and reference per axis over time."""
    fig = Figure(figsize=(9, 7), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for k, (ax, name) in enumerate(zip(axes, "xyz")):
        for i in _agents(ts):
            line, = ax.plot(ts.t, ts.positions[:, i, k], lw=1.2, label=f"agent {i}" if k == 0 else None)
            ax.plot(ts.t, ts.ref_positions[:, i, k], "--", lw=0.9, color=line.get_color())
        ax.set_ylabel(f"{name} [m]")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title("position (solid) and reference (dashed)")
    if ts.positions.shape[1] <= MAX_AGENTS_DRAWN:
        axes[0].legend(fontsize=7, ncol=5, loc="best")
    return _save(fig, path)


def plot_attitude(ts: TimeSeries, path: Path) -> Path:
    """Roll, pitch and yaw over time."""
    rpy = np.degrees(ts.euler)
    fig = Figure(figsize=(9, 7), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for k, (ax, name) in enumerate(zip(axes, ("roll", "pitch", "yaw"))):
        for i in _agents(ts):
            ax.plot(ts.t, rpy[:, i, k], lw=1.0)
        ax.set_ylabel(f"{name} [deg]")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title("attitude")
    return _save(fig, path)


def plot_rotors(ts: TimeSeries, path: Path) -> Path:
    """Rotor speeds over time (one panel per rotor)."""
    fig = Figure(figsize=(9, 7), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    for r, ax in enumerate(axes):
        for i in _agents(ts):
            ax.plot(ts.t, ts.rotor_speeds[:, i, r], lw=0.9)
        ax.set_ylabel(f"rotor {r} [rad/s]")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title("rotor speeds")
    return _save(fig, path)


def plot_run(ts: TimeSeries, out_dir: Path, metrics: dict[str, Any] | None = None) -> list[Path]:
    """Draw every figure of a run into ``out_dir``; returns the files written."""
    out_dir = Path(out_dir)
    if ts.t.size == 0:
        return []
    return [
        plot_positions(ts, out_dir / "position.png"),
        plot_attitude(ts, out_dir / "attitude.png"),
        plot_rotors(ts, out_dir / "rotor_speeds.png"),
    ]
