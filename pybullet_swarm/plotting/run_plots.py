"""Figures of one run, drawn from its saved results (never from a live simulation)."""

from __future__ import annotations

from pathlib import Path
from collections.abc import Mapping
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from pybullet_swarm.plotting.common import save_figure

from pybullet_swarm.control.rotations import quat_to_euler
from pybullet_swarm.types import TimeSeries

MAX_AGENTS_DRAWN = 10


def _agents(ts: TimeSeries) -> range:
    return range(min(ts.positions.shape[1], MAX_AGENTS_DRAWN))


_save = save_figure


def plot_positions(ts: TimeSeries, path: Path) -> Path:
    """Position and reference per axis over time."""
    fig = Figure(figsize=(9, 7), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for k, (ax, name) in enumerate(zip(axes, "xyz")):
        for i in _agents(ts):
            (line,) = ax.plot(ts.t, ts.positions[:, i, k], lw=1.2, label=f"agent {i}" if k == 0 else None)
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
    rpy = np.degrees(quat_to_euler(ts.quaternions.astype(float)))
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


def plot_run(
    ts: TimeSeries,
    out_dir: Path,
    metrics: dict[str, Any] | None = None,
    *,
    scenario: Mapping[str, Any] | None = None,
    events: list[Any] | None = None,
) -> list[Path]:
    """Draw every figure of a run into ``out_dir``; returns the files written.

    Args:
        ts: the recorded time series.
        out_dir: figure directory.
        metrics: the run's metrics (for annotations).
        scenario: the resolved scenario data (for task figures).
        events: the run's events (for the collision timeline).
    """
    out_dir = Path(out_dir)
    if ts.t.size == 0:
        return []
    files = [
        plot_positions(ts, out_dir / "position.png"),
        plot_attitude(ts, out_dir / "attitude.png"),
        plot_rotors(ts, out_dir / "rotor_speeds.png"),
    ]
    if scenario is not None:
        files += _swarm_figures(ts, out_dir, metrics or {}, scenario, events or [])
    if "est_kalman_position" in ts.extra:  # the run's onboard estimation (sensing.state estimated)
        from pybullet_swarm.plotting.estimation_plots import plot_estimation

        files += plot_estimation(
            ts.t,
            ts.positions,
            quat_to_euler(ts.quaternions.astype(float))[..., 2],
            ts.extra,
            out_dir,
            (metrics or {}).get("estimation"),
        )
    return files


def plot_saved_artifacts(run_dir: Path, out_dir: Path) -> list[Path]:
    """Redraw the figures of a run's extra state files (``pheromones.npz``, ``tour.json``)."""
    files: list[Path] = []
    pher = Path(run_dir) / "pheromones.npz"
    if pher.is_file():
        from pybullet_swarm.plotting.pheromone_plots import plot_pheromones

        with np.load(pher) as z:
            arrays = {k: z[k] for k in z.files}
        names = [str(n) for n in np.asarray(arrays["layers"]).ravel()]
        if "persistent" in arrays:
            lasting = [str(n) for n in np.asarray(arrays.pop("persistent")).ravel()]
        else:  # written before the file named them
            lasting = [n for n in names if n == "task"]
        files += plot_pheromones(arrays, out_dir, persistent=lasting)
    tour = Path(run_dir) / "tour.json"
    if tour.is_file():
        from pybullet_swarm.plotting.tour_plots import plot_saved_tour

        files.append(plot_saved_tour(tour, Path(run_dir) / "timeseries.npz", out_dir / "tour.png"))
    return files


def _swarm_figures(
    ts: TimeSeries, out_dir: Path, metrics: dict[str, Any], scenario: Mapping[str, Any], events: list[Any]
) -> list[Path]:
    from pybullet_swarm.metrics.construction import acceleration_series, box_to_goal_distance
    from pybullet_swarm.metrics.proximity import nearest_neighbour_distances
    from pybullet_swarm.plotting import construction_plots as cp
    from pybullet_swarm.vehicle import load_vehicle

    files = []
    pos = ts.positions.astype(float)
    task = scenario.get("task", {})
    arena = scenario.get("arena", {}).get("size", [3.0, 1.0])
    vehicle = load_vehicle(scenario.get("agents", {}).get("vehicle", "quad150"))
    diameter = max(vehicle.collision_size[0], vehicle.collision_size[1])
    if pos.shape[1] > 1:
        files.append(cp.plot_nn_distance(ts.t, nearest_neighbour_distances(pos), diameter, out_dir / "nn_distance.png"))
    files.append(cp.plot_collision_timeline(events, float(ts.t[-1]), out_dir / "collision_timeline.png"))
    files.append(
        cp.plot_acceleration(
            ts.t, acceleration_series(ts.t, ts.velocities.astype(float)), out_dir / "acceleration.png", agent=0
        )
    )
    if task.get("kind") == "route":
        from pybullet_swarm.plotting.flocking_plots import plot_route_run

        files += plot_route_run(ts, out_dir, metrics, scenario, events)
    if task.get("kind") == "flock":
        from pybullet_swarm.plotting.flocking_plots import plot_flock_run

        files += plot_flock_run(ts, out_dir, scenario)
    if task.get("kind") == "construction":
        boxes = np.asarray(task["boxes"], dtype=float)
        slots = np.asarray(task["structure"], dtype=float)
        files.append(cp.plot_top_view(pos, arena, boxes, slots, float(task["box_size"]), out_dir / "top_view.png"))
        if "box_positions" in ts.extra:
            total = box_to_goal_distance(ts.extra["box_positions"].astype(float), slots)
            files.append(
                cp.plot_box_to_goal(
                    ts.t, total, out_dir / "box_to_goal.png", completion_time=metrics.get("completion_time_s")
                )
            )
    return files
