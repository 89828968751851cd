"""Downwash: the force the rotor wake of a vehicle puts on a vehicle below it.

The model is the empirical one of gym-pybullet-drones (``BaseAviary._downwash``, credited there to
Crazyflie experiments at its lab; constants in its ``cf2x.urdf``). Shi et al., "Neural-Swarm"
(ICRA 2020), often named with it, learn the interaction with a network and give no closed form.
For a vehicle j above vehicle i,
with vertical separation ``dz = z_j - z_i > 0`` and horizontal distance ``d``, i is pushed down by

    F = A(dz) exp(-d^2 / (2 beta(dz)^2))                 (world -z, at i's centre of mass)
    A(dz) = alpha (r / (4 dz))^2                         alpha N, r the rotor radius m
    beta(dz) = zeta dz + eta                             zeta -, eta m

and nothing when ``dz <= 0``. The model gives a force only: no torque, no horizontal force.

Two rules keep it finite and physical; each has a constant in the vehicle file:

* ``airframe width`` (``downwash_min_width``, default the arm length): the wake is never narrower
  than ``min_width``, ``beta = max(zeta dz + eta, min_width)``. With the Crazyflie constants
  (eta < 0) ``zeta dz + eta`` is negative up to 0.69 m and zero there, a wake of no width and an
  infinite gradient; gym-pybullet-drones squares it, which reads a wake that narrows from 11 cm
  at the rotor plane to nothing at 0.69 m. Here the near wake has the airframe's size and
  spreads at ``zeta`` once ``zeta dz + eta`` exceeds it.
* ``momentum bound`` (``downwash_momentum_fraction`` k, default 0.5): a rotor wake carries a
  momentum flux equal to the thrust T that made it (momentum theory), and a Gaussian wake of
  width beta sends the fraction ``1 - exp(-2 r^2 / beta^2)`` of it through a disc of area
  ``4 pi r^2`` centred in it (the four rotor discs of the lower vehicle); the lower vehicle loses
  at most k times that, ``A <= k T (1 - exp(-2 r^2 / beta^2))``. k = 0.5 is a blade-element
  estimate: a rotor of these airframes' thrust coefficient (solidity 0.08 .. 0.15) in a downflow
  of one to two hover induced velocities (a near wake) loses 0.3 .. 0.8 of the momentum flux
  through it. The fitted ``A(dz)`` grows as 1 / dz^2 without bound (infinite when two vehicles
  fly level): for the Crazyflie directly below another it reaches the upper vehicle's whole
  weight at 0.53 m and 29 times it at 0.1 m, where the bound allows 0.25 times it.

``alpha`` is the force at the upper vehicle's hover thrust ``m g0`` (g0 = 9.81 m/s^2, where it
was fitted); both terms scale with the upper vehicle's current thrust ``kf sum(w^2)``, so a
vehicle whose rotors are still makes no wake. Not modelled: the wake's tilt with the upper
vehicle, a torque on a partly immersed vehicle, horizontal forces, the wake of a carried box or
on a box, ground reflections, unsteadiness.

Pairs whose force is certainly below ``eps T`` (``eps`` = ``NEGLIGIBLE``) are skipped: those
farther apart horizontally than ``2 r sqrt(k / (e eps))`` (the bound maximised over beta, whatever
dz) and those with ``d > beta sqrt(2 ln(k / eps))`` (out of the wake at their dz).
"""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np
from numpy.typing import NDArray

#: m/s^2, the gravity of the hover thrust at which ``alpha`` is given
G0 = 9.81
#: fraction of the upper vehicle's thrust below which a pair's force is skipped
NEGLIGIBLE = 1e-3
#: agents up to which every pair is checked; beyond, sweep and prune along one axis
ALL_PAIRS_MAX = 64

# The reference: gym-pybullet-drones' Crazyflie (cf2x.urdf), mass 0.027 kg.
CF_MASS = 0.027  # kg
CF_ROTOR_RADIUS = 0.0231348  # m, PROP_RADIUS
CF_ALPHA = 2267.18  # N, DW_COEFF_1
CF_ZETA = 0.16  # -, DW_COEFF_2
CF_ETA = -0.11  # m, DW_COEFF_3

# Layout of the constant array of the kernels.
D_KF = 0  # N/(rad/s)^2, thrust coefficient of the upper vehicle
D_R = 1  # m, rotor radius
D_CALPHA = 2  # -, alpha / (m g0): peak force per newton of the upper vehicle's thrust
D_ZETA = 3  # -
D_ETA = 4  # m
D_MINW = 5  # m, smallest wake width
D_KAPPA = 6  # -, momentum fraction
D_REACH = 7  # m, horizontal distance beyond which pairs are skipped
D_CUT = 8  # -, 2 ln(k / eps): pairs with d^2 > D_CUT beta^2 are skipped (F < eps T whatever the peak)
D_LEN = 9


@dataclasses.dataclass(frozen=True)
class DownwashParams:
    """Constants of the downwash model of one airframe (the vehicle file's ``downwash_*`` fields).

    Attributes:
        rotor_radius: m.
        alpha: N, peak-force coefficient at hover thrust ``m g0``.
        zeta: -, spreading rate of the wake width.
        eta: m, wake width at the rotor plane (before the ``min_width`` floor).
        min_width: m, the narrowest wake (rule ``airframe width``).
        momentum_fraction: -, share of the momentum flux through the lower rotor discs that the
            lower vehicle loses at most (rule ``momentum bound``; 0.5, a blade-element estimate).
    """

    rotor_radius: float
    alpha: float
    zeta: float
    eta: float
    min_width: float
    momentum_fraction: float = 0.5

    @classmethod
    def scaled(cls, *, mass: float, rotor_radius: float, arm_length: float) -> DownwashParams:
        """The Crazyflie constants scaled to another airframe by momentum theory.

        The wake's dynamic pressure at a given dz / r scales with the disc loading T / A, and the
        lower vehicle intercepts it over an area ~ r^2, so the force at a given dz / r scales with
        the thrust T ~ m: alpha ~ mass; lengths scale with the rotor radius (eta), zeta is a ratio;
        the narrowest wake is the arm length, the momentum fraction 0.5.
        """
        return cls(
            rotor_radius=rotor_radius,
            alpha=CF_ALPHA * mass / CF_MASS,
            zeta=CF_ZETA,
            eta=CF_ETA * rotor_radius / CF_ROTOR_RADIUS,
            min_width=arm_length,
        )

    def width(self, dz: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Wake width beta m at vertical separations dz m (> 0)."""
        return np.maximum(self.zeta * np.asarray(dz, dtype=float) + self.eta, self.min_width)

    def reach(self, negligible: float = NEGLIGIBLE) -> float:
        """m, horizontal distance beyond which the force is below ``negligible`` times the upper thrust."""
        return 2.0 * self.rotor_radius * math.sqrt(self.momentum_fraction / (math.e * negligible))

    def centreline_fraction(self, dz: float, *, mass: float) -> float:
        """The force on a vehicle ``dz`` m (> 0) straight below this airframe (of ``mass`` kg), as a fraction of
        the upper vehicle's thrust (of the weight of a lower one of the same airframe at hover)."""
        return float(_pair_force(0.0, float(dz), 1.0, self.const(kf=1.0, mass=mass)))

    def depth(self, fraction: float, *, mass: float) -> float:
        """m, how far below this airframe (of ``mass`` kg) the wake pushes a vehicle straight under it with more
        than ``fraction`` of the upper vehicle's thrust (the force falls with depth: bisection to 1 um)."""
        if not 0.0 < fraction < 1.0:
            raise ValueError(f"fraction must lie in (0, 1), got {fraction}")
        c = self.const(kf=1.0, mass=mass)  # once: the force per newton of the upper thrust, on the centreline

        def above(dz: float) -> bool:
            return float(_pair_force(0.0, dz, 1.0, c)) > fraction

        lo, hi = 1e-3, 100.0
        if not above(lo):
            return 0.0
        if above(hi):
            return hi
        while hi - lo > 1e-6:
            mid = 0.5 * (lo + hi)
            if above(mid):
                lo = mid
            else:
                hi = mid
        return hi

    def const(self, *, kf: float, mass: float, negligible: float = NEGLIGIBLE) -> NDArray[np.float64]:
        """The constant array of the kernels for an airframe of thrust coefficient ``kf`` and ``mass`` kg."""
        c = np.zeros(D_LEN)
        c[D_KF] = kf
        c[D_R] = self.rotor_radius
        c[D_CALPHA] = self.alpha / (mass * G0)
        c[D_ZETA] = self.zeta
        c[D_ETA] = self.eta
        c[D_MINW] = self.min_width
        c[D_KAPPA] = self.momentum_fraction
        c[D_REACH] = self.reach(negligible)
        c[D_CUT] = max(2.0 * math.log(self.momentum_fraction / negligible), 0.0)
        return c


@numba.njit(cache=True, inline="always")
def _pair_force(d2: float, dz: float, thrust: float, c: NDArray[np.float64]) -> float:
    """N, downward force on a vehicle dz m (> 0) below and d2 m^2 (squared horizontal distance) off
    a vehicle of thrust N."""
    r = c[D_R]
    beta = c[D_ZETA] * dz + c[D_ETA]
    if beta < c[D_MINW]:
        beta = c[D_MINW]
    b2 = beta * beta
    if d2 > c[D_CUT] * b2:  # out of the wake: below eps T even at the largest peak (k T)
        return 0.0
    q = r / (4.0 * dz)
    peak = c[D_CALPHA] * q * q
    bound = c[D_KAPPA] * (1.0 - math.exp(-2.0 * r * r / b2))
    if peak > bound:
        peak = bound
    return thrust * peak * math.exp(-0.5 * d2 / b2)


@numba.njit(cache=True, inline="always")
def _thrust(w: NDArray[np.float64], j: int, kf: float) -> float:
    return kf * (w[j, 0] * w[j, 0] + w[j, 1] * w[j, 1] + w[j, 2] * w[j, 2] + w[j, 3] * w[j, 3])


@numba.njit(cache=True)
def downwash_all_pairs(
    state: NDArray[np.float64],  # (n, >=3) positions m in the first three columns
    w: NDArray[np.float64],  # (n, 4) rotor speeds rad/s
    c: NDArray[np.float64],  # (D_LEN,) constants, see D_*
    force: NDArray[np.float64],  # (n, 3) world force N (in/out): the downwash is added to column 2
) -> None:
    """Add every vehicle's downwash on the vehicles below it to ``force``, checking every pair."""
    n = state.shape[0]
    reach2 = c[D_REACH] * c[D_REACH]
    for i in range(n):
        acc = 0.0
        for j in range(n):
            dz = state[j, 2] - state[i, 2]
            if not dz > 0.0:  # also skips a non-finite state
                continue
            dx = state[j, 0] - state[i, 0]
            dy = state[j, 1] - state[i, 1]
            d2 = dx * dx + dy * dy
            if not d2 <= reach2:
                continue
            acc += _pair_force(d2, dz, _thrust(w, j, c[D_KF]), c)
        force[i, 2] -= acc


@numba.njit(cache=True)
def downwash_sweep(
    state: NDArray[np.float64],  # (n, >=3) positions m in the first three columns
    w: NDArray[np.float64],  # (n, 4) rotor speeds rad/s
    c: NDArray[np.float64],  # (D_LEN,) constants, see D_*
    force: NDArray[np.float64],  # (n, 3) world force N (in/out): the downwash is added to column 2
) -> None:
    """As ``downwash_all_pairs``, finding the pairs by sweep and prune: agents sorted along the
    horizontal axis of the larger spread, each one's neighbours are those within the reach along it
    (O(n log n) plus the pairs in those strips)."""
    n = state.shape[0]
    reach = c[D_REACH]
    reach2 = reach * reach
    lo0, hi0, lo1, hi1 = state[0, 0], state[0, 0], state[0, 1], state[0, 1]
    for i in range(1, n):
        lo0, hi0 = min(lo0, state[i, 0]), max(hi0, state[i, 0])
        lo1, hi1 = min(lo1, state[i, 1]), max(hi1, state[i, 1])
    axis = 0 if hi0 - lo0 >= hi1 - lo1 else 1
    order = np.argsort(state[:, axis])  # deterministic for equal inputs
    for a in range(n):
        i = order[a]
        acc = 0.0
        for step in (-1, 1):
            b = a + step
            while 0 <= b < n:
                j = order[b]
                b += step
                gap = state[j, axis] - state[i, axis]
                if gap * gap > reach2:
                    break
                dz = state[j, 2] - state[i, 2]
                if not dz > 0.0:
                    continue
                dx = state[j, 0] - state[i, 0]
                dy = state[j, 1] - state[i, 1]
                d2 = dx * dx + dy * dy
                if not d2 <= reach2:
                    continue
                acc += _pair_force(d2, dz, _thrust(w, j, c[D_KF]), c)
        force[i, 2] -= acc


class Downwash:
    """The downwash of a swarm of one airframe, added to the world forces once per physics step.

    Args:
        params: the airframe's downwash constants.
        kf: thrust coefficient N/(rad/s)^2.
        mass: airframe mass kg (``alpha`` is given at its hover thrust at g0).
    """

    def __init__(self, params: DownwashParams, *, kf: float, mass: float) -> None:
        self.params = params
        self.const = params.const(kf=kf, mass=mass)
        self.last: NDArray[np.float64] = np.zeros(0)  # N, (n,) downward force on each vehicle at the last call

    def add_to(self, state: NDArray[np.float64], rotor_speeds: NDArray[np.float64], force: NDArray[np.float64]) -> None:
        """Add the downwash to ``force`` (n, 3) N, world frame, from ``state`` (n, 13) and rotor speeds (n, 4) rad/s;
        ``last`` keeps what it added (downward, N, per vehicle)."""
        if state.shape[0] < 2:
            return
        kernel = downwash_all_pairs if state.shape[0] <= ALL_PAIRS_MAX else downwash_sweep
        before = force[:, 2].copy()
        kernel(state, rotor_speeds, self.const, force)
        self.last = before - force[:, 2]
