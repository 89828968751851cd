"""Flight metrics from recorded time series: path length, rotor energy, tracking error, tilt."""

from __future__ import annotations

from typing import Any

import numpy as np

from pybullet_swarm.control.rotations import quat_to_matrix
from pybullet_swarm.types import TimeSeries


def path_lengths(positions: np.ndarray) -> np.ndarray:
    """Length of each agent's path (n,) m from positions (m, n, 3) m."""
    p = np.asarray(positions, dtype=float)
    if p.shape[0] < 2:
        return np.zeros(p.shape[1])
    return np.linalg.norm(np.diff(p, axis=0), axis=2).sum(axis=0)


def rotor_energy(t: np.ndarray, rotor_speeds: np.ndarray, km: float) -> np.ndarray:
    """Mechanical energy (n,) J the rotors spent against drag: integral of km w^3 per rotor (trapezoid)."""
    power = km * np.sum(np.asarray(rotor_speeds, dtype=float) ** 3, axis=2)  # (m, n) W
    if power.shape[0] < 2:
        return np.zeros(power.shape[1])
    return np.trapezoid(power, np.asarray(t, dtype=float), axis=0)


def flight_metrics(ts: TimeSeries, km: float) -> dict[str, Any]:
    """Path length, energy, tracking error and tilt of a run's recorded series."""
    pl = path_lengths(ts.positions)
    energy = rotor_energy(ts.t, ts.rotor_speeds, km)
    err = np.linalg.norm(ts.positions.astype(float) - ts.ref_positions, axis=2)
    tilt = np.degrees(np.arccos(np.clip(quat_to_matrix(ts.quaternions.astype(float))[..., 2, 2], -1.0, 1.0)))
    return {
        "path_length_m": {"total": float(pl.sum()), "per_agent": [float(x) for x in pl]},
        "energy_j": float(energy.sum()),
        "tracking_rmse_m": float(np.sqrt(np.mean(err**2))),
        "tracking_max_m": float(err.max()),
        "max_tilt_deg": float(tilt.max()),
    }
