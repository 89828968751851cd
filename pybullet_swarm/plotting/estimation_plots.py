"""Figures of a run's onboard estimation (drawn from the recorded ``est_*`` channels only).

* ``estimation_axes.png``: estimate vs truth per axis (Kalman, positioning fixes, IMU dead reckoning);
* ``estimation_error.png``: position error over time of the three sources, and heading errors;
* ``estimation_variance.png``: evolution of the Kalman filter's variances (the course report's
  Fig. 15): position variance rising between fixes and dropping at each, velocity and bias.
"""

from __future__ import annotations

from pathlib import Path
from collections.abc import Mapping
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from pybullet_swarm.plotting.common import save_figure

KALMAN, GPS, IMU, TRUTH = "tab:red", "tab:green", "tab:blue", "k"


def has_estimation(extra: dict[str, Any]) -> bool:
    """True when a run recorded estimation channels."""
    return "est_kalman_position" in extra


def _wrap(a: NDArray[np.floating[Any]]) -> NDArray[np.floating[Any]]:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def _fix_samples(t: NDArray[np.floating[Any]], fix_time: NDArray[np.floating[Any]], fixes: NDArray[np.floating[Any]]):
    """The distinct fixes (times, positions) among the recorded samples of one agent."""
    _, first = np.unique(fix_time, return_index=True)
    return fix_time[first], fixes[first]


def plot_estimate_axes(
    t: NDArray[np.floating[Any]],
    truth: NDArray[np.floating[Any]],
    extra: Mapping[str, NDArray[np.floating[Any]]],
    path: Path | str,
    agent: int = 0,
) -> Path:
    """Estimate vs truth per axis of one agent.

    Args:
        t: (m,) s.
        truth: (m, n, 3) m, true positions.
        extra: the recorded ``est_*`` channels.
        path: PNG file.
        agent: which agent.
    """
    k = extra["est_kalman_position"][:, agent].astype(float)
    imu = extra["est_imu_position"][:, agent].astype(float)
    ft, fp = _fix_samples(t, extra["est_gps_time"][:, agent].astype(float), extra["est_gps_position"][:, agent])
    fig = Figure(figsize=(9, 7.5), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for a, (ax, name) in enumerate(zip(axes, "xyz")):
        tr = truth[:, agent, a].astype(float)
        ax.plot(ft, fp[:, a], ".", ms=2.5, color=GPS, label="positioning fixes" if a == 0 else None)
        ax.plot(t, imu[:, a], lw=1.0, color=IMU, label="IMU dead reckoning" if a == 0 else None)
        ax.plot(t, tr, lw=1.6, color=TRUTH, label="truth" if a == 0 else None)
        ax.plot(t, k[:, a], lw=1.0, ls="--", color=KALMAN, label="Kalman" if a == 0 else None)
        span = max(float(tr.max() - tr.min()), 0.1)
        ax.set_ylim(float(tr.min()) - 0.3 * span, float(tr.max()) + 0.3 * span)  # dead reckoning leaves the frame
        ax.set_ylabel(f"{name} [m]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, ncol=4, loc="upper right")
    axes[0].set_title(f"agent {agent}: position estimates and truth")
    axes[-1].set_xlabel("time [s]")
    return save_figure(fig, path)


def plot_estimation_error(
    t: NDArray[np.floating[Any]],
    truth: NDArray[np.floating[Any]],
    true_yaw: NDArray[np.floating[Any]],
    extra: Mapping[str, NDArray[np.floating[Any]]],
    path: Path | str,
    metrics: dict[str, Any] | None = None,
) -> Path:
    """Position error (norm, over time, worst agent drawn thin) and heading error of the three sources."""
    truth = truth.astype(float)
    err = {
        "Kalman": np.linalg.norm(extra["est_kalman_position"] - truth, axis=2),
        "positioning (last fix)": np.linalg.norm(extra["est_gps_position"] - truth, axis=2),
        "IMU dead reckoning": np.linalg.norm(extra["est_imu_position"] - truth, axis=2),
    }
    colors = {"Kalman": KALMAN, "positioning (last fix)": GPS, "IMU dead reckoning": IMU}
    fig = Figure(figsize=(9, 7), layout="constrained")
    ax, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=[2, 1])
    for name, e in err.items():
        label = name
        if metrics is not None:
            key = {"Kalman": "kalman", "positioning (last fix)": "gps", "IMU dead reckoning": "imu"}[name]
            rmse = metrics.get(key, {}).get("rmse_m")
            if rmse is not None:
                label += f" (RMSE {1000 * rmse:.1f} mm)"
        ax.semilogy(t, np.maximum(e.mean(axis=1), 1e-5), lw=1.2, color=colors[name], label=label)
    noise = metrics.get("positioning_noise_std_m") if metrics else None
    if noise:
        ax.axhline(noise * np.sqrt(3.0), color=GPS, ls=":", lw=1.0, label="fix noise, 3-D RMS")
    ax.set_ylabel("position error [m] (mean over agents)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title("estimation error")
    yaws = {"Kalman": extra["est_kalman_rpy"][:, :, 2], "IMU dead reckoning": extra["est_imu_rpy"][:, :, 2]}
    if "est_gps_yaw" in extra:
        yaws["positioning (last fix)"] = extra["est_gps_yaw"]
    for name, y in yaws.items():
        h = np.abs(_wrap(y.astype(float) - true_yaw))
        ax2.semilogy(t, np.maximum(h.mean(axis=1), 1e-6), lw=1.0, color=colors[name])
    ax2.set_ylabel("heading error [rad]")
    ax2.set_xlabel("time [s]")
    ax2.grid(alpha=0.3, which="both")
    return save_figure(fig, path)


def plot_variances(
    t: NDArray[np.floating[Any]], variance: NDArray[np.floating[Any]], path: Path | str, agent: int = 0
) -> Path:
    """Evolution of the Kalman filter's variances of one agent (the course report's Fig. 15).

    Args:
        t: (m,) s.
        variance: (m, n, 3, d) per axis x, y, z the variance of position m^2, velocity (m/s)^2
            (and acceleration bias (m/s^2)^2).
        path: PNG file.
        agent: which agent.
    """
    v = variance[:, agent].astype(float)
    d = v.shape[-1]
    names = [("position", "m$^2$"), ("velocity", "(m/s)$^2$"), ("acceleration bias", "(m/s$^2$)$^2$")][:d]
    fig = Figure(figsize=(9, 2.6 * d + 0.6), layout="constrained")
    axes = np.atleast_1d(np.asarray(fig.subplots(d, 1, sharex=True), dtype=object))
    for j, (ax, (name, unit)) in enumerate(zip(axes, names)):
        for a, axis in enumerate("xyz"):
            ax.semilogy(t, v[:, a, j], lw=1.0, label=axis)
        ax.set_ylabel(f"{name} [{unit}]")
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8, ncol=3, loc="upper right")
    axes[0].set_title(f"agent {agent}: Kalman filter variances")
    axes[-1].set_xlabel("time [s]")
    return save_figure(fig, path)


def plot_estimation(
    t: NDArray[np.floating[Any]],
    positions: NDArray[np.floating[Any]],
    true_yaw: NDArray[np.floating[Any]],
    extra: Mapping[str, NDArray[np.floating[Any]]],
    out_dir: Path | str,
    metrics: dict[str, Any] | None = None,
) -> list[Path]:
    """Every estimation figure of a run into ``out_dir``; returns the files written.

    Args:
        t: (m,) s.
        positions: (m, n, 3) m, true positions.
        true_yaw: (m, n) rad, true headings.
        extra: the recorded channels (``est_*``).
        out_dir: figure directory.
        metrics: the run's ``estimation`` metrics (for the legend), if any.
    """
    out = Path(out_dir)
    t = np.asarray(t, dtype=float)
    return [
        plot_estimate_axes(t, positions, extra, out / "estimation_axes.png"),
        plot_estimation_error(t, positions, true_yaw, extra, out / "estimation_error.png", metrics),
        plot_variances(t, extra["est_kalman_variance"], out / "estimation_variance.png"),
    ]
