"""Motor model and rotor forces, as compiled kernels over all agents.

The motor is a first-order lag on rotor speed, integrated exactly over a physics step
(``w += (w_cmd - w) (1 - exp(-dt / tau))``) and saturated to ``[0, w_max]``. Rotor i produces
thrust ``kf w_i^2`` along body z and a drag torque ``-spin_i km w_i^2`` about body z; the four
rotors become one body wrench through the mixer.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray


def motor_alpha(dt: float, time_constant: float) -> float:
    """Fraction of the remaining step a first-order motor covers in ``dt`` s: 1 - exp(-dt / tau)."""
    return 1.0 - math.exp(-dt / time_constant)


@numba.njit(cache=True, inline="always")
def motor_update_row(w: NDArray[np.float64], i: int, w_cmd: NDArray[np.float64], alpha: float, w_max: float) -> None:
    """Advance the 4 rotor speeds (rad/s) of agent i one step towards their commands, saturated."""
    for k in range(4):
        c = w_cmd[k]
        if c < 0.0:
            c = 0.0
        elif c > w_max:
            c = w_max
        w[i, k] += (c - w[i, k]) * alpha


@numba.njit(cache=True)
def motor_update(w: NDArray[np.float64], w_cmd: NDArray[np.float64], alpha: float, w_max: float) -> None:
    """Advance rotor speeds w (n, 4) rad/s in place towards w_cmd (n, 4), saturated to [0, w_max]."""
    for i in range(w.shape[0]):
        motor_update_row(w, i, w_cmd[i], alpha, w_max)


@numba.njit(cache=True)
def rotor_wrench(w: NDArray[np.float64], mixer: NDArray[np.float64], out: NDArray[np.float64]) -> None:
    """Body wrench [thrust N, tau_x, tau_y, tau_z N m] (n, 4) of rotor speeds w (n, 4) rad/s."""
    for i in range(w.shape[0]):
        for r in range(4):
            acc = 0.0
            for k in range(4):
                acc += mixer[r, k] * w[i, k] * w[i, k]
            out[i, r] = acc


def ground_effect_factor(height: NDArray[np.float64], rotor_radius: float) -> NDArray[np.float64]:
    """Thrust multiplier in ground effect (Cheeseman-Bennett), 1 / (1 - (R / 4z)^2), capped at 2."""
    z = np.maximum(np.asarray(height, dtype=float), 1e-3)
    return np.minimum(1.0 / np.maximum(1.0 - (rotor_radius / (4.0 * z)) ** 2, 0.5), 2.0)
