"""Wind as aerodynamic drag: a steady wind plus seeded Dryden gusts, acting on vehicles and boxes.

A body moving at v through air moving at w feels a drag force that depends on the relative air
velocity ``u = w - v``:

* a multirotor: linear rotor drag ``F = D u``, ``D = diag(drag_xy, drag_xy, drag_z)`` N/(m/s) from
  the vehicle file (blade flapping and induced drag grow with the rotors' thrust, so near hover the
  force is linear in the relative speed; gym-pybullet-drones' Crazyflie constants, see
  ``VehicleParams.drag_coefficients``);
* a box: quadratic form drag ``F = rho C_d A |u| u / 2`` with the air density ``AIR_DENSITY``, the
  cube's ``BOX_DRAG_COEFFICIENT`` and the mean area of its faces.

Gusts (``turbulence`` > 0): per body and axis, the Dryden longitudinal spectrum's shaping filter,
``H(s) = sigma sqrt(2 L / (pi V)) / (1 + (L / V) s)``, whose output is an Ornstein-Uhlenbeck process of
standard deviation sigma (``turbulence``) and correlation time ``L / V`` (``length_scale_m`` over the
mean wind speed, at least ``MIN_AIRSPEED``: Taylor's frozen turbulence carried past a hovering
body). It is sampled exactly at the physics period from the run's ``wind`` random stream, so a
seed gives the same gusts whatever else the run draws. Bodies get independent gusts (spatially
uncorrelated; their separations are of the order of the scale length).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

#: kg/m^3, sea-level air (ISA, 15 degrees C)
AIR_DENSITY = 1.225
#: drag coefficient of a cube facing the flow (Hoerner, Fluid-Dynamic Drag, 1965)
BOX_DRAG_COEFFICIENT = 1.05
#: m/s, slowest mean wind that carries the gusts past a body (sets the longest correlation time)
MIN_AIRSPEED = 0.5


@dataclasses.dataclass(frozen=True)
class WindParams:
    """A steady wind and its gusts.

    Attributes:
        velocity: (3,) m/s, the steady wind, world frame.
        turbulence: m/s, standard deviation of the gusts per axis (0: none).
        length_scale_m: m, Dryden scale length of the gusts.
    """

    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    turbulence: float = 0.0
    length_scale_m: float = 8.0

    @property
    def correlation_time_s(self) -> float:
        """s, the gusts' correlation time L / V."""
        speed = max(float(np.linalg.norm(self.velocity)), MIN_AIRSPEED)
        return self.length_scale_m / speed


class Gusts:
    """Dryden gusts (k, 3) m/s of k bodies, advanced one physics period at a time.

    Args:
        k: number of bodies.
        params: the wind.
        dt: s, the physics period.
        rng: the run's ``wind`` stream.
    """

    def __init__(self, k: int, params: WindParams, dt: float, rng: np.random.Generator) -> None:
        self.sigma = float(params.turbulence)
        self.rng = rng
        self.decay = math.exp(-dt / params.correlation_time_s)
        self.kick = self.sigma * math.sqrt(1.0 - self.decay * self.decay)
        # stationary from the start: the first value is a draw of the process's distribution
        self.value = self.sigma * rng.standard_normal((k, 3)) if self.sigma > 0.0 else np.zeros((k, 3))

    def step(self) -> NDArray[np.float64]:
        """Advance by one physics period; the gusts (k, 3) m/s now."""
        if self.sigma > 0.0:
            self.value *= self.decay
            self.value += self.kick * self.rng.standard_normal(self.value.shape)
        return self.value


def linear_drag(
    drag: NDArray[np.float64], air: NDArray[np.float64], velocity: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Rotor drag (k, 3) N = D (w - v) of bodies at velocities (k, 3) m/s in air (k, 3) or (3,) m/s; drag (3,) N/(m/s)."""
    return np.asarray(drag, dtype=float) * (np.asarray(air, dtype=float) - np.asarray(velocity, dtype=float))


def form_drag(
    areas: NDArray[np.float64], air: NDArray[np.float64], velocity: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Form drag (k, 3) N = rho C_d A |u| u / 2, u = w - v, of boxes with areas (k,) m^2."""
    u = np.asarray(air, dtype=float) - np.asarray(velocity, dtype=float)
    speed = np.linalg.norm(u, axis=-1, keepdims=True)
    return 0.5 * AIR_DENSITY * BOX_DRAG_COEFFICIENT * np.asarray(areas, dtype=float)[:, None] * speed * u


class Wind:
    """The wind acting on n vehicles (linear drag) and k boxes (form drag), one physics period at a time.

    Args:
        params: the wind.
        n: number of vehicles.
        drag: (3,) N/(m/s), the vehicles' drag coefficients (x, y, z).
        box_areas: (k,) m^2, the boxes' drag areas.
        dt: s, the physics period.
        rng: the run's ``wind`` stream (vehicles' gusts first, then the boxes').
    """

    def __init__(
        self,
        params: WindParams,
        n: int,
        drag: NDArray[np.float64],
        box_areas: NDArray[np.float64],
        dt: float,
        rng: np.random.Generator,
    ) -> None:
        self.steady = np.asarray(params.velocity, dtype=float).reshape(3)
        self.drag = np.asarray(drag, dtype=float).reshape(3)
        self.box_areas = np.asarray(box_areas, dtype=float).reshape(-1)
        self.gusts = Gusts(n + len(self.box_areas), params, dt, rng)
        self.n = int(n)
        self.air = self.steady + self.gusts.value  # (n + k, 3) m/s

    def step(self) -> None:
        """Advance the gusts by one physics period."""
        self.air = self.steady + self.gusts.step()

    def add_to(self, state: NDArray[np.float64], force: NDArray[np.float64]) -> None:
        """Add the vehicles' drag to ``force`` (n, 3) N, world frame, from their ``state`` (n, 13)."""
        force += linear_drag(self.drag, self.air[: self.n], state[:, 7:10])

    def box_forces(self, velocities: NDArray[np.float64]) -> NDArray[np.float64]:
        """The boxes' drag (k, 3) N at velocities (k, 3) m/s."""
        return form_drag(self.box_areas, self.air[self.n :], velocities)
