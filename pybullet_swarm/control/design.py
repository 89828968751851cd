"""Design the cascade's PID gains by pole placement on the sampled-data linear model of each loop.

**The model** is the linearisation about hover of what runs, sample by sample: the compiled
kernels (``kernels.physics_tick`` once per physics step h = 1/physics_hz, ``kernels.position_tick``
once every N = physics_hz/position_hz steps, T = N h) and Bullet's semi-implicit Euler step. In
acceleration units (the runtime multiplies commands by the mass and inertia and inverts the mixer
built from kf and km, so at hover the small-signal gain from a commanded to an applied
acceleration is exactly one; the motor lag acts on rotor speed, and about hover a lag on w is the
same lag on the thrust kf w^2), one physics step of an attitude axis is::

    c_k = -kp (theta_k - r) - kd w_k - ki I_k        I_{k+1} = I_k + h (theta_k - r)
    m_{k+1} = beta m_k + (1 - beta) c_k              beta = exp(-h / tau_m): the motor lag, exact
    w_{k+1} = w_k + h m_{k+1}                        the kernel applies the updated rotor speeds
    theta_{k+1} = theta_k + h w_{k+1}                Bullet: velocity first, then position

The vertical axis is the same chain from the commanded vertical acceleration (held for N steps)
to z. A horizontal axis adds ``v_{k+1} = v_k + h g theta_k`` (the thrust is tilted by the attitude
read at the start of the step) and ``x_{k+1} = x_k + h v_{k+1}``, with the attitude loop closed
and its reference ``theta_r = a_cmd / g`` held for N steps. The position loops are lifted to
their own period T (the N-step map of the fine model), so every loop is an exact discrete-time
linear system at the rate it is sampled at -- motor lag, the sample-and-hold of both loops and
the integrator included, no Pade approximation.

**What is placed.** A PID has three gains, the closed loops more poles (4 for an attitude axis
and z, 7 for x and y: the closed attitude loop's 4 and the position loop's 3). The three gains
place three of them exactly: a complex pair at ``w_n (-damping +- j sqrt(1 - damping^2))`` and a
real integral pole at ``-integral_pole_ratio w_n`` (as ``z = exp(s T)`` at the loop's period). With
one actuator, the characteristic polynomial ``det(zI - A + B K C)`` is affine in K = (kp, kd, ki),
so the three conditions are a 3x3 linear system. The remaining poles land where the model puts
them; ``LoopReport.achieved_poles`` lists every pole of the closed loop, as ``s = ln(z) / T``.

**What is checked** for each candidate w_n: the gains are positive; the closed loop is stable;
the placed poles dominate (every other pole at least ``dominance`` times farther left than the
placed pair); gain and phase margins of the loop broken at the acceleration command, on the
unit circle up to the Nyquist frequency; a bandwidth at most ``separation`` times below that of
the inner loop the loop commands: for x and y the tilt loops' (they act through tilt), for z the
motor's, 1 / tau (it acts through collective thrust, on which the tilt loop has no say); and
rotor saturation (``SaturationReport``). w_n is the largest
value (by bisection) that passes.

**Where the vehicle enters.** Only the motor time constant changes the loop dynamics in
acceleration units. Mass, inertia, kf, km, the arm length and the rotor speed limit enter
where they matter physically: the hover rotor speed sqrt(m g / 4 kf), the headroom to w_max, and
the rotor speeds the mixer asks for when the loops follow the largest reference step
(``ReferenceStep``). Loops are designed in the order tilt (roll = pitch), z, x = y, yaw; each
search also requires that the loops designed so far, following that step together, keep every
rotor command within [0, max_rotor_fraction * w_max]. Yaw comes last and takes the headroom that
is left, as the runtime mixer gives yaw the authority left after thrust, roll and pitch. When a
later loop finds no range left, the tilt loop is capped below its w_n and the design repeated. A
vehicle for which no w_n passes is refused with a ``ConfigError`` naming its file and the loop.

**Which step.** The gains are designed for the documented default ``ReferenceStep()`` -- shaped
references with the scenarios' 1 m/s^2 acceleration limit, raw 0.1 m position steps and a
0.5 rad yaw step, all at once -- so a vehicle's gains do not depend on the scenario and
``pybullet-swarm design`` shows the runtime's gains. A scenario's own step is checked against
them (``ControllerDesign.check_step``) and refused when a rotor would saturate.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import control
import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.vehicle.params import VehicleParams

#: Gain margin every loop must have, dB (the design targets more, see ``DesignSpec``).
REQUIRED_GAIN_MARGIN_DB = 6.0
#: Phase margin every loop must have, deg.
REQUIRED_PHASE_MARGIN_DEG = 45.0
#: Minimum ratio of the slower tilt (roll, pitch) bandwidth to the fastest position bandwidth.
REQUIRED_SEPARATION = 4.0

#: Step of the acceleration reference on each axis checked by default, m/s^2 (the scenario
#: default ``limits.acceleration``; shaped references change the acceleration reference by at
#: most this much).
DEFAULT_ACCELERATION_STEP = 1.0
#: Raw position step on each axis checked by default, m (references that are not shaped,
#: ``limits.velocity: null``, jump; the scenario does not bound the jump).
DEFAULT_POSITION_STEP = 0.1
#: Yaw reference step checked by default, rad (planners hold yaw at 0; scenarios do not bound it).
DEFAULT_YAW_STEP = 0.5


class Loop(str, enum.Enum):
    """The six control loops of the cascade; the value is the key used in reports and JSON."""

    ROLL = "roll"
    PITCH = "pitch"
    YAW = "yaw"
    X = "x"
    Y = "y"
    Z = "z"

    @property
    def is_attitude(self) -> bool:
        """True for roll, pitch and yaw."""
        return self in _ATTITUDE_LOOPS

    @property
    def row(self) -> int:
        """Row of this loop in ``attitude_gains`` or ``position_gains``."""
        return (_ATTITUDE_LOOPS if self.is_attitude else _POSITION_LOOPS).index(self)


_ATTITUDE_LOOPS = (Loop.ROLL, Loop.PITCH, Loop.YAW)
_POSITION_LOOPS = (Loop.X, Loop.Y, Loop.Z)
_TILT_LOOPS = (Loop.ROLL, Loop.PITCH)
_TILT_DRIVEN = (Loop.X, Loop.Y)  # the position loops that act through tilt


@dataclasses.dataclass(frozen=True)
class DesignSpec:
    """Targets and pole pattern of the design (targets keep headroom over the requirements).

    Attributes:
        gain_margin_db: target gain margin of every loop, dB (requirement 6 dB).
        phase_margin_deg: target phase margin of every loop, deg (requirement 45 deg).
        separation: target ratio of an inner loop's bandwidth to that of the loop commanding it:
            tilt to x and y, motor (1 / tau) to z (requirement 4).
        damping: damping ratio of the placed complex pole pair.
        integral_pole_ratio: the placed real (integral) pole sits at ``-integral_pole_ratio * w_n``;
            about 1/3..1/2 keeps the integral gain large enough to reject a constant disturbance
            (e.g. a 20 % payload) within a few seconds.
        dominance: every closed-loop pole that is not placed must lie at least this many times
            farther left (real part) than the placed complex pair.
        attitude_wn_max: cap on the attitude natural frequency, rad/s.
        wn_min: lower end of the natural frequency search, rad/s; a loop infeasible there is refused.
        wn_rel_tol: relative tolerance of the bisection on w_n.
        max_rotor_fraction: largest rotor speed command, as a fraction of ``max_rotor_speed``, that
            following the reference step may ask for.
    """

    gain_margin_db: float = 8.0
    phase_margin_deg: float = 50.0
    separation: float = 5.0
    damping: float = 0.8
    integral_pole_ratio: float = 0.4
    dominance: float = 2.0
    attitude_wn_max: float = 40.0
    wn_min: float = 0.05
    wn_rel_tol: float = 1e-3
    max_rotor_fraction: float = 1.0

    def __post_init__(self) -> None:
        checks = {
            "gain_margin_db": self.gain_margin_db > 0,
            "phase_margin_deg": 0 < self.phase_margin_deg < 90,
            "separation": self.separation > 0,
            "damping": 0 < self.damping < 1,
            "integral_pole_ratio": self.integral_pole_ratio > 0,
            "dominance": self.dominance >= 1,
            "attitude_wn_max": self.attitude_wn_max > self.wn_min,
            "wn_min": self.wn_min > 0,
            "wn_rel_tol": 0 < self.wn_rel_tol < 0.5,
            "max_rotor_fraction": 0 < self.max_rotor_fraction <= 1,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"DesignSpec.{name}: out of range, got {getattr(self, name)!r}")

    def placed_poles(self, wn: float) -> tuple[complex, complex, complex]:
        """The three placed poles (s-plane, rad/s) for natural frequency ``wn``: pair, then integral pole."""
        im = math.sqrt(1.0 - self.damping**2)
        return (
            wn * complex(-self.damping, im),
            wn * complex(-self.damping, -im),
            complex(-self.integral_pole_ratio * wn, 0.0),
        )


@dataclasses.dataclass(frozen=True)
class ReferenceStep:
    """The largest reference change the loops must follow, all axes at once, without saturating a rotor.

    Shaped references (a scenario velocity limit) move the position smoothly and change the
    acceleration reference by at most the scenario's ``limits.acceleration``; the two-degree-of-
    freedom prefilter (``CascadeController``) then makes the commanded acceleration equal the
    reference in the linear model, so the loops see an acceleration step. References that are
    not shaped jump: the loops see a position step. Both are checked together (conservative).

    Attributes:
        acceleration: (3,) m/s^2, step of the acceleration reference per axis x, y, z.
        position: (3,) m, raw step of the position reference per axis.
        yaw: rad, step of the yaw reference.
    """

    acceleration: tuple[float, float, float] = (DEFAULT_ACCELERATION_STEP,) * 3
    position: tuple[float, float, float] = (DEFAULT_POSITION_STEP,) * 3
    yaw: float = DEFAULT_YAW_STEP

    def __post_init__(self) -> None:
        acc = tuple(float(a) for a in np.broadcast_to(np.asarray(self.acceleration, dtype=float), (3,)))
        pos = tuple(float(a) for a in np.broadcast_to(np.asarray(self.position, dtype=float), (3,)))
        object.__setattr__(self, "acceleration", acc)
        object.__setattr__(self, "position", pos)
        object.__setattr__(self, "yaw", float(self.yaw))
        for name, values in (("acceleration", acc), ("position", pos), ("yaw", (self.yaw,))):
            if not all(math.isfinite(v) and v >= 0 for v in values):
                raise ValueError(f"ReferenceStep.{name}: must be finite and >= 0, got {values}")

    @classmethod
    def from_limits(
        cls,
        velocity: Sequence[float] | NDArray[np.float64] | None,
        acceleration: Sequence[float] | NDArray[np.float64] | float,
        *,
        yaw: float = DEFAULT_YAW_STEP,
    ) -> ReferenceStep:
        """The step a scenario's reference limits allow.

        Args:
            velocity: per-axis velocity limit (3,) m/s, or None when references are not shaped.
            acceleration: per-axis acceleration limit (3,) m/s^2.
            yaw: yaw reference step, rad.
        """
        if velocity is None:
            return cls(acceleration=(0.0, 0.0, 0.0), position=(DEFAULT_POSITION_STEP,) * 3, yaw=yaw)
        acc = np.broadcast_to(np.asarray(acceleration, dtype=float), (3,))
        return cls(acceleration=tuple(acc), position=(0.0, 0.0, 0.0), yaw=yaw)  # type: ignore[arg-type]

    def to_json_dict(self) -> dict[str, object]:
        """The step as plain Python values."""
        return {"acceleration_m_s2": list(self.acceleration), "position_m": list(self.position), "yaw_rad": self.yaw}


def _pole_list(poles: Sequence[complex]) -> list[list[float]]:
    return [[float(p.real), float(p.imag)] for p in poles]


@dataclasses.dataclass(frozen=True)
class LoopReport:
    """Poles, margins and bandwidth of one loop.

    Attributes:
        gain_margin_db: factor by which the loop gain may grow before instability, dB
            (``None`` when no phase crossover limits it, i.e. infinite).
        phase_margin_deg: smallest phase margin over all gain crossovers, deg.
        bandwidth_rad_s: -3 dB bandwidth of the closed loop from reference to output, rad/s.
        natural_frequency_rad_s: w_n of the placed poles, rad/s.
        sample_period_s: period the loop runs at (its discrete poles are z = exp(s T)), s.
        placed_poles: the three poles placed, s-plane rad/s: the complex pair, then the integral pole.
        achieved_poles: every pole of the closed loop, ``ln(z) / T`` rad/s, slowest first.
        dominance: smallest |Re| of the poles not placed over |Re| of the placed pair.
    """

    gain_margin_db: float | None
    phase_margin_deg: float
    bandwidth_rad_s: float
    natural_frequency_rad_s: float
    sample_period_s: float
    placed_poles: tuple[complex, ...]
    achieved_poles: tuple[complex, ...]
    dominance: float

    def to_json_dict(self) -> dict[str, object]:
        """The report as plain Python values; poles as lists of [re, im] in rad/s."""
        gm = None if self.gain_margin_db is None else float(self.gain_margin_db)
        return {
            "gain_margin_db": gm,
            "phase_margin_deg": float(self.phase_margin_deg),
            "bandwidth_rad_s": float(self.bandwidth_rad_s),
            "natural_frequency_rad_s": float(self.natural_frequency_rad_s),
            "sample_period_s": float(self.sample_period_s),
            "placed_poles": _pole_list(self.placed_poles),
            "achieved_poles": _pole_list(self.achieved_poles),
            "dominance": float(self.dominance),
        }


@dataclasses.dataclass(frozen=True)
class SaturationReport:
    """Rotor speed commands while the loops follow the reference step (linear model, worst signs).

    Each axis's step may have either sign; the worst combination is taken sample by sample.

    Attributes:
        step: the reference step.
        hover_fraction: hover rotor speed sqrt(m g / 4 kf) / max_rotor_speed.
        peak_fraction: largest rotor speed command / max_rotor_speed.
        min_fraction: smallest rotor speed command / max_rotor_speed; negative when a rotor would
            have to turn backwards (the runtime clips it at 0), as -sqrt(|w^2|) / max_rotor_speed.
        peak_channel: the step ('x', 'y', 'z' or 'yaw') that contributes most to the peak.
        peak_shares: each step's part of the peak rotor's squared speed, as a fraction of
            max_rotor_speed squared (the hover part under 'hover'); they add up to peak_fraction^2.
        alone: peak fraction of each step on its own, by channel.
        limit: the largest allowed rotor fraction (``DesignSpec.max_rotor_fraction``).
    """

    step: ReferenceStep
    hover_fraction: float
    peak_fraction: float
    min_fraction: float
    peak_channel: str
    peak_shares: dict[str, float]
    alone: dict[str, float]
    limit: float

    @property
    def ok(self) -> bool:
        """True when every rotor command stays within [0, limit * max_rotor_speed]."""
        return self.peak_fraction <= self.limit and self.min_fraction >= 0.0

    def to_json_dict(self) -> dict[str, object]:
        """The report as plain Python values."""
        return {
            "step": self.step.to_json_dict(),
            "hover_fraction": float(self.hover_fraction),
            "peak_fraction": float(self.peak_fraction),
            "min_fraction": float(self.min_fraction),
            "peak_channel": self.peak_channel,
            "peak_shares": {k: float(v) for k, v in self.peak_shares.items()},
            "alone": {k: float(v) for k, v in self.alone.items()},
            "limit": float(self.limit),
            "ok": self.ok,
        }


# ---------------------------------------------------------------------------------------------
# The sampled-data models


@dataclasses.dataclass(frozen=True, eq=False)
class SampledPlant:
    """A loop's plant at the loop's period: x_{k+1} = a x_k + b u_k, u the commanded acceleration.

    The loop measures its output ``cp . x`` (angle rad or position m) and that output's rate
    ``cd . x`` directly (gyro, velocity), as the runtime does.

    Attributes:
        a: (n, n) state transition over one period.
        b: (n,) input vector.
        cp: (n,) output row.
        cd: (n,) rate row.
        dt: period, s.
    """

    a: NDArray[np.float64]
    b: NDArray[np.float64]
    cp: NDArray[np.float64]
    cd: NDArray[np.float64]
    dt: float

    def augmented(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Plant with the PID's integrator: (A0 (n+1, n+1), B0 (n+1,), C0 (3, n+1)).

        State [x, I] with I_{k+1} = I_k + dt * output_k; C0 maps it to (output, rate, I), the
        signals the gains (kp, kd, ki) multiply: u = -(kp, kd, ki) . C0 X (+ kp r).
        """
        n = self.a.shape[0]
        a0 = np.zeros((n + 1, n + 1))
        a0[:n, :n] = self.a
        a0[n, :n] = self.dt * self.cp
        a0[n, n] = 1.0
        b0 = np.zeros(n + 1)
        b0[:n] = self.b
        c0 = np.zeros((3, n + 1))
        c0[0, :n], c0[1, :n], c0[2, n] = self.cp, self.cd, 1.0
        return a0, b0, c0

    def closed(self, gains: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Closed loop (A_cl (n+1, n+1), B_r (n+1,)) from the reference r to the state [x, I].

        P and I act on the error output - r, D on the measured rate (the runtime law).
        """
        a0, b0, c0 = self.augmented()
        k = np.asarray(gains, dtype=float)
        a_cl = a0 - np.outer(b0, k @ c0)
        b_r = b0 * k[0]
        b_r[-1] -= self.dt
        return a_cl, b_r

    def command(self, gains: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
        """Row and feed-through (c (n+1,), d) of the command u = c . X + d r of the closed loop."""
        _, _, c0 = self.augmented()
        k = np.asarray(gains, dtype=float)
        return -(k @ c0), float(k[0])

    def loop_response(self, gains: NDArray[np.float64], omega: NDArray[np.float64]) -> NDArray[np.complex128]:
        """L(e^{j w dt}), (len(omega),): the loop broken at the command, u -> (kp, kd, ki) . C0 X."""
        a0, b0, c0 = self.augmented()
        k = np.asarray(gains, dtype=float) @ c0
        return _frequency_response(a0, b0, k, 0.0, omega, self.dt)

    def closed_response(self, gains: NDArray[np.float64], omega: NDArray[np.float64]) -> NDArray[np.complex128]:
        """T(e^{j w dt}) of the closed loop from reference to output, (len(omega),)."""
        a_cl, b_r = self.closed(gains)
        return _frequency_response(a_cl, b_r, np.append(self.cp, 0.0), 0.0, omega, self.dt)


def _frequency_response(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    c: NDArray[np.float64],
    d: float,
    omega: NDArray[np.float64],
    dt: float,
) -> NDArray[np.complex128]:
    """c (zI - a)^-1 b + d at z = exp(j omega dt), for a SISO discrete system; (len(omega),)."""
    z = np.exp(1j * np.asarray(omega, dtype=float) * dt)
    n = a.shape[0]
    mats = np.multiply.outer(z, np.eye(n)) - a
    x = np.linalg.solve(mats, np.broadcast_to(b.astype(complex)[:, None], (z.size, n, 1)))[..., 0]
    return np.asarray(x @ c + d, dtype=complex)


def _motor_beta(h: float, tau: float) -> float:
    """Fraction of a motor's speed error left after one physics step: exp(-h / tau)."""
    return math.exp(-h / tau)


def attitude_plant(h: float, tau: float) -> SampledPlant:
    """One attitude axis (or z) at the physics period h: state [angle, rate, applied acceleration].

    Input: the commanded angular (or vertical) acceleration, applied through the motor lag
    exp(-h/tau) and integrated by Bullet's semi-implicit Euler step (see the module docstring).
    """
    beta = _motor_beta(h, tau)
    alpha = 1.0 - beta
    a = np.array([[1.0, h, h * h * beta], [0.0, 1.0, h * beta], [0.0, 0.0, beta]])
    b = np.array([h * h * alpha, h * alpha, alpha])
    return SampledPlant(a, b, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), h)


def _lift(a: NDArray[np.float64], b: NDArray[np.float64], n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """N-step map of x' = a x + b u with u held: (a^N, sum_{i<N} a^i b)."""
    phi = np.eye(a.shape[0])
    gamma = np.zeros_like(b)
    for _ in range(n):
        gamma = a @ gamma + b
        phi = a @ phi
    return phi, gamma


def vertical_plant(h: float, n: int, tau: float) -> SampledPlant:
    """z at the position period N h: state [z m, v m/s, applied vertical acceleration m/s^2]."""
    fine = attitude_plant(h, tau)
    phi, gamma = _lift(fine.a, fine.b, n)
    return SampledPlant(phi, gamma, fine.cp, fine.cd, n * h)


def _horizontal_fine(
    h: float, tau: float, tilt_gains: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One horizontal axis at the physics period with its tilt loop closed: (a (6, 6), b (6,)).

    State [x m, v m/s, phi, phi rate, applied phi acceleration, tilt integral], where
    phi = g * tilt is the horizontal acceleration the tilt makes (so g drops out); input the
    commanded horizontal acceleration a_cmd = phi_ref.
    """
    att_a, att_b = attitude_plant(h, tau).closed(tilt_gains)  # state [phi, w, m, I], input phi_ref
    a = np.zeros((6, 6))
    b = np.zeros(6)
    a[2:, 2:], b[2:] = att_a, att_b
    a[1, 1], a[1, 2] = 1.0, h  # v' = v + h phi (tilt read at the start of the step)
    a[0, :] = h * a[1, :]  # x' = x + h v'
    a[0, 0] += 1.0
    b[0] = h * b[1]
    return a, b


def horizontal_plant(h: float, n: int, tau: float, tilt_gains: NDArray[np.float64]) -> SampledPlant:
    """x or y at the position period N h, tilt loop closed inside: state as ``_horizontal_fine``."""
    a, b = _horizontal_fine(h, tau, tilt_gains)
    phi, gamma = _lift(a, b, n)
    e = np.eye(6)
    return SampledPlant(phi, gamma, e[0], e[1], n * h)


def acceleration_path_ss(
    plant_fine: tuple[NDArray[np.float64], NDArray[np.float64]],
    n: int,
    h: float,
    applied_now: NDArray[np.float64],
    applied_next: NDArray[np.float64],
) -> control.StateSpace:
    """Average applied acceleration over a position period per commanded acceleration (held).

    The output at tick j is (v_{j+1} - v_j) / T, the mean over the N physics steps of the applied
    acceleration ``applied_now . x_k + applied_next . x_{k+1}``; unit DC gain.
    """
    a, b = plant_fine
    m = a.shape[0]
    c = np.zeros(m)
    d = 0.0
    a_pow, gamma = np.eye(m), np.zeros(m)  # x_k = a_pow x_0 + gamma u
    for _ in range(n):
        nxt_pow, nxt_gamma = a @ a_pow, a @ gamma + b
        c += applied_now @ a_pow + applied_next @ nxt_pow
        d += float(applied_now @ gamma + applied_next @ nxt_gamma)
        a_pow, gamma = nxt_pow, nxt_gamma
    return control.ss(a_pow, gamma.reshape(-1, 1), (c / n).reshape(1, -1), d / n, n * h)


# ---------------------------------------------------------------------------------------------
# Placement, margins, bandwidth


def place_pid(plant: SampledPlant, poles: Sequence[complex]) -> NDArray[np.float64]:
    """PID gains (kp, kd, ki), shape (3,), that put three closed-loop poles at ``poles`` (s-plane).

    With K = (kp, kd, ki) and g(z) = C0 (zI - A0)^-1 B0, det(zI - A0 + B0 K C0) vanishes where
    K . g(z) = -1. A complex pole gives two real equations (its conjugate the same two), a real
    pole one; three poles (a pair and a real one, or three real ones) fix K.

    Raises:
        ValueError: the poles do not give three independent equations, or a pole is a pole of the plant.
    """
    a0, b0, c0 = plant.augmented()
    rows: list[NDArray[np.float64]] = []
    rhs: list[float] = []
    done: list[complex] = []
    for s in poles:
        if any(abs(s.conjugate() - p) < 1e-12 * max(1.0, abs(s)) for p in done):
            done.append(s)
            continue  # the conjugate's equations are the same
        done.append(s)
        z = np.exp(complex(s) * plant.dt)
        g = c0 @ np.linalg.solve(z * np.eye(a0.shape[0]) - a0, b0.astype(complex))
        rows.append(g.real)
        rhs.append(-1.0)
        if abs(s.imag) > 0:
            rows.append(g.imag)
            rhs.append(0.0)
    if len(rows) != 3:
        raise ValueError(f"place_pid: need three real conditions, got {len(rows)} from poles {list(poles)}")
    return np.linalg.solve(np.array(rows), np.array(rhs))


def closed_loop_poles(plant: SampledPlant, gains: NDArray[np.float64]) -> NDArray[np.complex128]:
    """Every pole of the closed loop as ln(z) / dt, rad/s, slowest (smallest |Re|) first."""
    a_cl, _ = plant.closed(gains)
    z = np.linalg.eigvals(a_cl).astype(complex)
    s = np.log(z) / plant.dt
    return s[np.lexsort((np.abs(s.imag), -s.real))]


def _refine_root(f: Callable[[NDArray[np.float64]], NDArray[np.float64]], lo: float, hi: float) -> float:
    """A root of f (vectorised over frequencies) in [lo, hi], where f changes sign, rad/s.

    Two rounds of a 64-point log grid, then linear interpolation: about 1e-9 relative.
    """
    for _ in range(2):
        grid = np.geomspace(lo, hi, 64)
        vals = f(grid)
        idx = np.nonzero(np.diff(np.sign(vals)) != 0)[0]
        if idx.size == 0:
            break
        i = int(idx[0])
        lo, hi = float(grid[i]), float(grid[i + 1])
    flo, fhi = float(f(np.array([lo]))[0]), float(f(np.array([hi]))[0])
    return lo if fhi == flo else lo + (hi - lo) * flo / (flo - fhi)


def _log_grid(dt: float, points: int) -> NDArray[np.float64]:
    """Frequencies, (points,) rad/s, from 1e-5 of the Nyquist frequency up to it (inclusive)."""
    nyq = math.pi / dt
    w = np.logspace(math.log10(nyq) - 5.0, math.log10(nyq), points)
    w[-1] = nyq
    return w


def loop_margins(plant: SampledPlant, gains: NDArray[np.float64]) -> tuple[float | None, float]:
    """Upper gain margin (dB, ``None`` if infinite) and smallest phase margin (deg) of the loop.

    L(e^{jw dt}) is evaluated from 1e-5 of the Nyquist frequency up to it, crossings are refined,
    and the Nyquist frequency itself counts as a phase crossover when L is negative real there.
    Phase crossovers where |L| > 1 (the lower margins of a conditionally stable loop) do not
    limit a gain increase and are left out.

    Raises:
        ValueError: no gain crossover (|L| never passes 1).
    """
    w = _log_grid(plant.dt, 1200)

    def resp(x: NDArray[np.float64]) -> NDArray[np.complex128]:
        return plant.loop_response(gains, x)

    big_l = resp(w)
    mag = np.abs(big_l)
    pms: list[float] = []
    for i in np.nonzero(np.diff(np.sign(mag - 1.0)) != 0)[0]:
        wc = _refine_root(lambda x: np.abs(resp(x)) - 1.0, float(w[i]), float(w[i + 1]))
        pms.append(180.0 + math.degrees(float(np.angle(resp(np.array([wc]))[0]))))
    if not pms:
        raise ValueError("loop has no gain crossover")
    upper: list[float] = []
    for i in np.nonzero((np.diff(np.sign(big_l.imag)) != 0) & (big_l.real[:-1] < 0.0))[0]:
        wp = _refine_root(lambda x: resp(x).imag, float(w[i]), float(w[i + 1]))
        val = complex(resp(np.array([wp]))[0])
        if val.real < 0 and abs(val) < 1.0:
            upper.append(1.0 / abs(val))
    at_nyquist = complex(big_l[-1])
    if at_nyquist.real < 0 and abs(at_nyquist.imag) < 1e-9 * max(1.0, abs(at_nyquist)) and abs(at_nyquist) < 1.0:
        upper.append(1.0 / abs(at_nyquist))
    gm_db = 20.0 * math.log10(min(upper)) if upper else None
    return gm_db, min(pms)


def closed_loop_bandwidth(plant: SampledPlant, gains: NDArray[np.float64]) -> float:
    """First frequency, rad/s, where |T| of the closed loop falls below 1/sqrt(2) (inf if never)."""
    w = _log_grid(plant.dt, 600)
    level = 1.0 / math.sqrt(2.0)
    mag = np.abs(plant.closed_response(gains, w))
    below = np.nonzero(mag < level)[0]
    if below.size == 0:
        return math.inf
    i = int(below[0])
    if i == 0:
        return float(w[0])
    return _refine_root(lambda x: np.abs(plant.closed_response(gains, x)) - level, float(w[i - 1]), float(w[i]))


# ---------------------------------------------------------------------------------------------
# Designing one loop


@dataclasses.dataclass(frozen=True, eq=False)
class _LoopDesign:
    """Result of designing one loop."""

    gains: NDArray[np.float64]  # (3,) kp 1/s^2, kd 1/s, ki 1/s^3
    report: LoopReport


class _Infeasible(Exception):
    """A candidate natural frequency fails a check (the message says which)."""

    def __init__(self, message: str, *, saturated: bool = False) -> None:
        super().__init__(message)
        self.saturated = saturated


class _NoGains(Exception):
    """Not even the lowest natural frequency passes; ``saturated`` when rotor saturation failed it."""

    def __init__(self, loop: str, message: str, *, saturated: bool) -> None:
        super().__init__(message)
        self.loop = loop
        self.saturated = saturated


def _evaluate(plant: SampledPlant, spec: DesignSpec, wn: float, max_bandwidth: float) -> _LoopDesign:
    """Place the pattern at ``wn`` and judge it; raises _Infeasible naming the first failed check."""
    placed = spec.placed_poles(wn)
    try:
        gains = place_pid(plant, placed)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise _Infeasible(f"cannot place the poles at w_n {wn:.3g} rad/s ({exc})") from None
    if not np.all(gains > 0.0):
        raise _Infeasible(f"gains not all positive at w_n {wn:.3g} rad/s ({gains})")
    poles = closed_loop_poles(plant, gains)
    if not np.all(np.real(poles) < 0.0):
        raise _Infeasible(f"closed loop unstable at w_n {wn:.3g} rad/s")
    others = list(poles)
    for p in placed:  # remove the placed poles, the nearest each
        others.pop(int(np.argmin([abs(q - p) for q in others])))
    pair_re = spec.damping * wn
    dominance = min(-q.real for q in others) / pair_re if others else math.inf
    if dominance < spec.dominance:
        raise _Infeasible(f"placed poles not dominant at w_n {wn:.3g} rad/s (ratio {dominance:.2f})")
    try:
        gm_db, pm_deg = loop_margins(plant, gains)
    except ValueError as exc:
        raise _Infeasible(f"{exc} at w_n {wn:.3g} rad/s") from None
    if gm_db is not None and gm_db < spec.gain_margin_db:
        raise _Infeasible(f"gain margin {gm_db:.2f} dB at w_n {wn:.3g} rad/s")
    if pm_deg < spec.phase_margin_deg:
        raise _Infeasible(f"phase margin {pm_deg:.2f} deg at w_n {wn:.3g} rad/s")
    bw = closed_loop_bandwidth(plant, gains)
    if not math.isfinite(bw) or bw > max_bandwidth:
        raise _Infeasible(f"bandwidth {bw:.3g} rad/s above {max_bandwidth:.3g} rad/s at w_n {wn:.3g} rad/s")
    report = LoopReport(
        gain_margin_db=gm_db,
        phase_margin_deg=pm_deg,
        bandwidth_rad_s=bw,
        natural_frequency_rad_s=wn,
        sample_period_s=plant.dt,
        placed_poles=tuple(placed),
        achieved_poles=tuple(complex(p) for p in poles),
        dominance=float(dominance),
    )
    return _LoopDesign(gains, report)


def _design_loop(
    plant_of: Callable[[], SampledPlant],
    spec: DesignSpec,
    wn_max: float,
    *,
    max_bandwidth: float = math.inf,
    extra: Callable[[NDArray[np.float64]], str | None] = lambda gains: None,
    name: str,
) -> _LoopDesign:
    """Largest w_n in [spec.wn_min, wn_max] that passes every check (bisection on log w_n).

    Args:
        plant_of: builds the loop's plant.
        spec: targets and pole pattern.
        wn_max: upper end of the search, rad/s.
        max_bandwidth: largest allowed closed-loop bandwidth, rad/s.
        extra: a further check of the gains (saturation); returns a reason to refuse, or None.
        name: loop name for error messages.

    Raises:
        _NoGains: not even ``spec.wn_min`` passes.
    """
    plant = plant_of()

    def attempt(wn: float) -> _LoopDesign:
        found = _evaluate(plant, spec, wn, max_bandwidth)
        why = extra(found.gains)
        if why is not None:
            raise _Infeasible(f"{why} at w_n {wn:.3g} rad/s", saturated=True)
        return found

    try:
        return attempt(wn_max)
    except _Infeasible:
        pass
    lo, hi = spec.wn_min, wn_max
    try:
        best = attempt(lo)
    except _Infeasible as exc:
        raise _NoGains(
            name, f"no gains: not even w_n = {lo:g} rad/s passes the checks ({exc})", saturated=exc.saturated
        ) from None
    while hi / lo > 1.0 + spec.wn_rel_tol:
        mid = math.sqrt(lo * hi)
        try:
            best, lo = attempt(mid), mid
        except _Infeasible:
            hi = mid
    return best


# ---------------------------------------------------------------------------------------------
# Saturation


@dataclasses.dataclass(frozen=True, eq=False)
class Airframe:
    """What the saturation check needs of a vehicle (from its ``VehicleParams`` and the gravity)."""

    mass: float  # kg
    inertia: tuple[float, float, float]  # kg m^2
    mixer_inverse: NDArray[np.float64]  # (4, 4) [T, tau] -> w^2
    max_rotor_speed: float  # rad/s
    gravity: float  # m/s^2

    @property
    def hover_speed_sq(self) -> NDArray[np.float64]:
        """(4,) (rad/s)^2, squared rotor speeds at hover."""
        return self.mixer_inverse @ np.array([self.mass * self.gravity, 0.0, 0.0, 0.0])


def _step_outputs(
    a: NDArray[np.float64], b: NDArray[np.float64], c: NDArray[np.float64], d: NDArray[np.float64], n: int
) -> NDArray[np.float64]:
    """Outputs (n, p) of x' = a x + b u, y = c x + d u from x_0 = 0 for a unit step u = 1 at k = 0.

    y_k = d + sum_{i<k} c a^i b; the Markov parameters c a^i b are built in blocks of about
    sqrt(n) (a^i b for i < B, and c a^{jB}), so the cost is O(sqrt(n)) small products.

    Args:
        a: (m, m). b: (m,). c: (p, m). d: (p,). n: samples.
    """
    m = a.shape[0]
    blk = max(1, int(math.ceil(math.sqrt(n))))
    powers_b = np.empty((blk, m))  # a^i b
    v = b.astype(float)
    for i in range(blk):
        powers_b[i] = v
        v = a @ v
    a_blk = np.linalg.matrix_power(a, blk)
    rows = -(-n // blk)
    left = np.empty((rows, c.shape[0], m))  # c a^{jB}
    q = c.astype(float)
    for j in range(rows):
        left[j] = q
        q = q @ a_blk
    markov = np.einsum("jpm,im->jip", left, powers_b).reshape(rows * blk, c.shape[0])[:n]  # (n, p)
    out = np.empty((n, c.shape[0]))
    out[0] = d
    out[1:] = d + np.cumsum(markov[:-1], axis=0)
    return out


def _loop_command(plant: SampledPlant, gains: NDArray[np.float64], step: float, n: int) -> NDArray[np.float64]:
    """(n,) commanded acceleration of a loop (at its period) after a reference step of ``step`` at k = 0."""
    a_cl, b_r = plant.closed(gains)
    c, d = plant.command(gains)
    return step * _step_outputs(a_cl, b_r, c.reshape(1, -1), np.array([d]), n)[:, 0]


def _horizontal_raw_command(
    h: float,
    n_sub: int,
    tau: float,
    tilt_gains: NDArray[np.float64],
    pos_gains: NDArray[np.float64],
    step: float,
    n: int,
) -> NDArray[np.float64]:
    """(n,) tilt-loop command at the physics rate after a raw position step of ``step`` m.

    In phi units (g times the angular acceleration; divide by g for rad/s^2), as
    ``_horizontal_fine``. The position loop runs every ``n_sub`` physics steps: its closed loop is
    stepped at the position period, and each period is expanded into its ``n_sub`` physics steps.
    """
    a_f, b_f = _horizontal_fine(h, tau, tilt_gains)  # state [x, v, phi, w, m, I_a]
    att_c, att_d = attitude_plant(h, tau).command(tilt_gains)  # over [phi, w, m, I_a]; r = phi_ref
    c_att = np.concatenate([np.zeros(2), att_c])
    coarse = horizontal_plant(h, n_sub, tau, tilt_gains)
    a_cl, b_r = coarse.closed(pos_gains)  # state [X (6), I_p]
    u_c, u_d = coarse.command(pos_gains)
    periods = -(-n // n_sub)
    c_out = np.vstack([np.hstack([np.eye(6), np.zeros((6, 1))]), u_c])  # X and u
    d_out = np.append(np.zeros(6), u_d)
    states = step * _step_outputs(a_cl, b_r, c_out, d_out, periods)  # (periods, 7)
    x_j, u_j = states[:, :6], states[:, 6]
    out = np.empty((periods, n_sub))
    a_pow, gamma = np.eye(6), np.zeros(6)  # x_{jN+i} = a^i X_j + gamma_i u_j
    for i in range(n_sub):
        out[:, i] = x_j @ (c_att @ a_pow) + u_j * (c_att @ gamma + att_d)
        a_pow, gamma = a_f @ a_pow, a_f @ gamma + b_f
    return out.reshape(-1)[:n]


def _vertical_raw_command(
    plant: SampledPlant, gains: NDArray[np.float64], step: float, n_sub: int, n: int
) -> NDArray[np.float64]:
    """(n,) commanded vertical acceleration at the physics rate (held n_sub steps) after a raw step."""
    coarse = _loop_command(plant, gains, step, -(-n // n_sub))
    return np.repeat(coarse, n_sub)[:n]


@dataclasses.dataclass(frozen=True)
class _Gains:
    """Gains designed so far (None: not yet)."""

    tilt: NDArray[np.float64] | None = None
    z: NDArray[np.float64] | None = None
    xy: NDArray[np.float64] | None = None
    yaw: NDArray[np.float64] | None = None


def _saturation(
    vehicle: Airframe,
    step: ReferenceStep,
    gains: _Gains,
    h: float,
    n_sub: int,
    tau: float,
    spec: DesignSpec,
    horizon_s: float,
) -> SaturationReport:
    """Rotor commands while the loops designed so far follow ``step`` from hover (worst signs).

    Each channel's generalised force [thrust N, tau_x, tau_y, tau_z N m] is computed at the
    physics rate from the linear model; squared rotor speeds are hover + mixer_inverse @ force,
    and the worst sign of each channel is taken at every sample (the channels add linearly).
    """
    n = max(1, int(math.ceil(horizon_s / h)))
    g = vehicle.gravity
    jx, jy, jz = vehicle.inertia
    channels: dict[str, NDArray[np.float64]] = {}  # name -> (n, 4) generalised force
    att = attitude_plant(h, tau)
    if gains.tilt is not None:
        for name, axis, col, j in (("x", 0, 2, jy), ("y", 1, 1, jx)):
            # phi units: the tilt loop's command is g * angular acceleration
            cmd = np.zeros(n)
            if step.acceleration[axis] > 0:
                cmd += _loop_command(att, gains.tilt, step.acceleration[axis], n)
            if gains.xy is not None and step.position[axis] > 0:
                cmd += _horizontal_raw_command(h, n_sub, tau, gains.tilt, gains.xy, step.position[axis], n)
            force = np.zeros((n, 4))
            force[:, col] = j * cmd / g
            channels[name] = force
    thrust = np.full(n, step.acceleration[2])
    if gains.z is not None and step.position[2] > 0:
        thrust = thrust + _vertical_raw_command(vertical_plant(h, n_sub, tau), gains.z, step.position[2], n_sub, n)
    force = np.zeros((n, 4))
    force[:, 0] = vehicle.mass * thrust
    channels["z"] = force
    if gains.yaw is not None and step.yaw > 0:
        force = np.zeros((n, 4))
        force[:, 3] = jz * _loop_command(att, gains.yaw, step.yaw, n)
        channels["yaw"] = force
    base = vehicle.hover_speed_sq  # (4,)
    contrib = {k: np.abs(f @ vehicle.mixer_inverse.T) for k, f in channels.items()}  # (n, 4) each
    total = sum(contrib.values(), np.zeros((n, 4)))
    high = base[None, :] + total
    low = base[None, :] - total
    wmax = vehicle.max_rotor_speed
    k_hi, i_hi = np.unravel_index(int(np.argmax(high)), high.shape)
    peak_channel = max(contrib, key=lambda k: contrib[k][k_hi, i_hi])
    lowest = float(low.min())
    alone = {k: float(math.sqrt(max(float((base[None, :] + c).max()), 0.0)) / wmax) for k, c in contrib.items()}
    return SaturationReport(
        step=step,
        hover_fraction=float(math.sqrt(float(base.max())) / wmax),
        peak_fraction=float(math.sqrt(float(high.max())) / wmax),
        min_fraction=float(math.copysign(math.sqrt(abs(lowest)), lowest) / wmax),
        peak_channel=str(peak_channel),
        peak_shares={
            "hover": float(base[i_hi]) / wmax**2,
            **{k: float(c[k_hi, i_hi]) / wmax**2 for k, c in contrib.items()},
        },
        alone=alone,
        limit=spec.max_rotor_fraction,
    )


#: Factor by which the tilt loop's w_n is capped when a later loop finds no rotor range left.
_TILT_CAP_FACTOR = 0.85
#: s of response the searches check for saturation (the peaks of a step come within the first
#: few tenths of a second: the proportional kick and the attitude loop's answer to it).
_SEARCH_HORIZON_S = 2.0
#: s, cap on the response the final saturation check covers.
_FINAL_HORIZON_MAX_S = 20.0


def _saturation_reason(rep: SaturationReport) -> str | None:
    if rep.ok:
        return None
    if rep.peak_fraction > rep.limit:
        shares = ", ".join(f"{k} {100 * v:.0f} %" for k, v in rep.peak_shares.items())
        return (
            f"rotor speed command {100 * rep.peak_fraction:.1f} % of max_rotor_speed (limit "
            f"{100 * rep.limit:.0f} %; parts of its square: {shares}) for the reference step"
        )
    return f"a rotor command below zero ({100 * rep.min_fraction:.1f} % of max_rotor_speed) for the reference step"


# ---------------------------------------------------------------------------------------------
# The design


@dataclasses.dataclass(frozen=True, eq=False)
class ControllerDesign:
    """Designed PID gains of the cascade with the models and reports they were judged on.

    Instances are cached by ``design_controller`` and shared: treat them as read-only.

    Attributes:
        vehicle: vehicle name.
        physics_hz: attitude loop (physics) rate, Hz.
        position_hz: position loop rate, Hz.
        attitude_gains: (3, 3) rows roll, pitch, yaw; columns kp 1/s^2, kd 1/s, ki 1/s^3
            (multiply by the axis inertia kg m^2 for torque).
        position_gains: (3, 3) rows x, y, z; columns kp 1/s^2, kd 1/s, ki 1/s^3
            (multiply by the mass kg for force).
        attitude: reports of the attitude loops, keys 'roll', 'pitch', 'yaw'.
        position: reports of the position loops, keys 'x', 'y', 'z'.
        separation: min tilt (roll, pitch) bandwidth / max horizontal (x, y) bandwidth.
        natural_frequency: w_n of each loop's placed poles, rad/s, keys as ``Loop`` values.
        motor_time_constant: first-order motor lag in the models, s.
        spec: the specification the gains were designed to.
        saturation: rotor commands while following the design's reference step ``saturation.step``.
        airframe: mass, inertia, mixer and rotor speed limit, for ``saturation_for``.
        vehicle_file: the vehicle's parameter file, if known.
    """

    vehicle: str
    physics_hz: float
    position_hz: float
    attitude_gains: NDArray[np.float64]
    position_gains: NDArray[np.float64]
    attitude: dict[str, LoopReport]
    position: dict[str, LoopReport]
    separation: float
    natural_frequency: dict[str, float]
    motor_time_constant: float
    spec: DesignSpec
    saturation: SaturationReport
    airframe: Airframe
    vehicle_file: str | None = None

    @property
    def thrust_separation(self) -> float:
        """Motor bandwidth 1 / tau over the z loop's bandwidth: z acts through collective thrust, not tilt."""
        return 1.0 / (self.motor_time_constant * self.position[Loop.Z.value].bandwidth_rad_s)

    @property
    def substeps(self) -> int:
        """Physics steps per position step."""
        return int(round(self.physics_hz / self.position_hz))

    def gains(self, loop: Loop | str) -> NDArray[np.float64]:
        """PID gains (kp 1/s^2, kd 1/s, ki 1/s^3), shape (3,), of one loop."""
        lp = Loop(loop)
        table = self.attitude_gains if lp.is_attitude else self.position_gains
        return table[lp.row]

    def report(self, loop: Loop | str) -> LoopReport:
        """Poles, margins and bandwidth of one loop."""
        lp = Loop(loop)
        return (self.attitude if lp.is_attitude else self.position)[lp.value]

    def sampled_plant(self, loop: Loop | str) -> SampledPlant:
        """The loop's plant at its period (see the module docstring)."""
        lp = Loop(loop)
        h, tau = 1.0 / self.physics_hz, self.motor_time_constant
        if lp.is_attitude:
            return attitude_plant(h, tau)
        if lp is Loop.Z:
            return vertical_plant(h, self.substeps, tau)
        tilt = Loop.PITCH if lp is Loop.X else Loop.ROLL
        return horizontal_plant(h, self.substeps, tau, self.gains(tilt))

    def plant(self, loop: Loop | str) -> control.StateSpace:
        """The plant as a discrete python-control system from commanded acceleration to output."""
        p = self.sampled_plant(loop)
        return control.ss(p.a, p.b.reshape(-1, 1), p.cp.reshape(1, -1), 0.0, p.dt)

    def open_loop(self, loop: Loop | str) -> control.StateSpace:
        """Loop transfer L(z), broken at the acceleration command: u -> (kp, kd, ki) . (y, rate, I)."""
        p = self.sampled_plant(loop)
        a0, b0, c0 = p.augmented()
        return control.ss(a0, b0.reshape(-1, 1), (self.gains(loop) @ c0).reshape(1, -1), 0.0, p.dt)

    def closed_loop(self, loop: Loop | str) -> control.StateSpace:
        """Closed loop T(z) from reference to output (P and I on the error, D on the measured rate)."""
        p = self.sampled_plant(loop)
        a_cl, b_r = p.closed(self.gains(loop))
        return control.ss(a_cl, b_r.reshape(-1, 1), np.append(p.cp, 0.0).reshape(1, -1), 0.0, p.dt)

    def acceleration_path(self, loop: Loop | str) -> control.StateSpace:
        """A position loop's inner path at the position period: commanded acceleration (held) to the
        mean applied acceleration over the period, (v_{j+1} - v_j) / T; unit DC gain."""
        lp = Loop(loop)
        if lp.is_attitude:
            raise ValueError(f"acceleration_path: expected a position loop (x, y, z), got {lp.value!r}")
        h, tau, n = 1.0 / self.physics_hz, self.motor_time_constant, self.substeps
        if lp is Loop.Z:  # only the motor state: the applied acceleration is the lagged command
            beta = _motor_beta(h, tau)
            return acceleration_path_ss((np.array([[beta]]), np.array([1.0 - beta])), n, h, np.zeros(1), np.ones(1))
        tilt = Loop.PITCH if lp is Loop.X else Loop.ROLL
        a_cl, b_r = attitude_plant(h, tau).closed(self.gains(tilt))
        return acceleration_path_ss((a_cl, b_r), n, h, np.eye(4)[0], np.zeros(4))

    def saturation_for(self, step: ReferenceStep) -> SaturationReport:
        """Rotor commands of these gains while following another reference step (e.g. a scenario's)."""
        gains = _Gains(
            tilt=self.gains(Loop.ROLL), z=self.gains(Loop.Z), xy=self.gains(Loop.X), yaw=self.gains(Loop.YAW)
        )
        slowest = self.spec.integral_pole_ratio * min(self.natural_frequency.values())
        return _saturation(
            self.airframe,
            step,
            gains,
            1.0 / self.physics_hz,
            self.substeps,
            self.motor_time_constant,
            self.spec,
            min(_FINAL_HORIZON_MAX_S, 6.0 / slowest),
        )

    def check_step(self, step: ReferenceStep) -> SaturationReport:
        """``saturation_for(step)``, refused when a rotor command leaves its range.

        Raises:
            ConfigError: names the vehicle file and the channel (loop) whose step contributes most.
        """
        rep = self.saturation_for(step)
        if not rep.ok:
            source = Path(self.vehicle_file).name if self.vehicle_file else f"vehicle {self.vehicle!r}"
            raise ConfigError(
                f"the controller cannot follow the reference step: {_saturation_reason(rep)}",
                source=source,
                field=rep.peak_channel,
            )
        return rep

    def to_json_dict(self) -> dict[str, object]:
        """The report as JSON-ready plain Python values."""

        def loop_dict(lp: Loop) -> dict[str, object]:
            kp, kd, ki = (float(g) for g in self.gains(lp))
            return {**self.report(lp).to_json_dict(), "gains": {"kp": kp, "kd": kd, "ki": ki}}

        return {
            "vehicle": str(self.vehicle),
            "vehicle_file": self.vehicle_file,
            "physics_hz": float(self.physics_hz),
            "position_hz": float(self.position_hz),
            "motor_time_constant_s": float(self.motor_time_constant),
            "attitude": {lp.value: loop_dict(lp) for lp in _ATTITUDE_LOOPS},
            "position": {lp.value: loop_dict(lp) for lp in _POSITION_LOOPS},
            "separation": float(self.separation),
            "thrust_separation": float(self.thrust_separation),
            "saturation": self.saturation.to_json_dict(),
            "requirements_met": not self.meets_requirements(),
        }

    def meets_requirements(self) -> list[str]:
        """Human-readable violations of the requirements; empty when all hold."""
        problems: list[str] = []
        for lp in Loop:
            rep = self.report(lp)
            if rep.gain_margin_db is not None and rep.gain_margin_db < REQUIRED_GAIN_MARGIN_DB:
                problems.append(f"{lp.value}: gain margin {rep.gain_margin_db:.2f} dB < {REQUIRED_GAIN_MARGIN_DB:g} dB")
            if rep.phase_margin_deg < REQUIRED_PHASE_MARGIN_DEG:
                problems.append(
                    f"{lp.value}: phase margin {rep.phase_margin_deg:.2f} deg < {REQUIRED_PHASE_MARGIN_DEG:g} deg"
                )
            if not all(p.real < 0 for p in rep.achieved_poles):
                problems.append(f"{lp.value}: closed loop unstable")
        if self.separation < REQUIRED_SEPARATION:
            problems.append(f"separation {self.separation:.2f} < {REQUIRED_SEPARATION:g}")
        if self.thrust_separation < REQUIRED_SEPARATION:
            problems.append(f"thrust separation {self.thrust_separation:.2f} < {REQUIRED_SEPARATION:g}")
        if not self.saturation.ok:
            problems.append(f"saturation: {_saturation_reason(self.saturation)}")
        return problems


# ---------------------------------------------------------------------------------------------
# Public entry points


def check_rates(physics_hz: float, position_hz: float) -> int:
    """Number of physics ticks per position tick; ValueError unless position_hz divides physics_hz."""
    if not (physics_hz > 0 and position_hz > 0 and math.isfinite(physics_hz) and math.isfinite(position_hz)):
        raise ValueError(f"physics_hz {physics_hz} and position_hz {position_hz} must be positive")
    ratio = physics_hz / position_hz
    n = round(ratio)
    if n < 1 or abs(ratio - n) > 1e-9 * ratio:
        raise ValueError(f"position_hz {position_hz} must divide physics_hz {physics_hz} exactly (ratio {ratio:g})")
    return n


def design_controller(
    params: VehicleParams,
    *,
    physics_hz: float = 240.0,
    position_hz: float = 48.0,
    spec: DesignSpec | None = None,
    step: ReferenceStep | None = None,
    gravity: float = 9.81,
) -> ControllerDesign:
    """Design the attitude and position PID gains of a vehicle (cached: same inputs, same object).

    Args:
        params: vehicle parameters (motor time constant for the dynamics; mass, inertia, kf, km,
            arm length and max rotor speed for the saturation check).
        physics_hz: attitude loop (physics) rate, Hz.
        position_hz: position loop rate, Hz; must divide ``physics_hz``.
        spec: targets and pole pattern; ``DesignSpec()`` when None.
        step: the reference step that must not saturate a rotor; ``ReferenceStep()`` when None
            (shaped references with the default acceleration limit and raw 0.1 m steps together).
        gravity: m/s^2.

    Raises:
        ValueError: the rates do not divide.
        ConfigError: no gains pass the checks for a loop, or following the step saturates a
            rotor (names the vehicle file and the loop).
    """
    check_rates(physics_hz, position_hz)
    if not (gravity > 0 and math.isfinite(gravity)):
        raise ValueError(f"gravity: must be positive, got {gravity}")
    key = (params, float(physics_hz), float(position_hz), spec or DesignSpec(), step or ReferenceStep(), float(gravity))
    design = _DESIGNS.get(key)
    if design is None:
        design = _design(*key)
        if len(_DESIGNS) >= _MAX_DESIGNS:
            _DESIGNS.pop(next(iter(_DESIGNS)))  # the oldest
        _DESIGNS[key] = design
    return design


#: designs made in this process, by their inputs (vehicle, rates, spec, step, gravity)
_DESIGNS: dict[tuple[Any, ...], ControllerDesign] = {}
_MAX_DESIGNS = 64


def known_designs() -> dict[tuple[Any, ...], ControllerDesign]:
    """The designs this process has made, by their inputs: a process that starts workers hands them
    over (``add_designs``), so that no worker designs the same controller again."""
    return dict(_DESIGNS)


def add_designs(designs: Mapping[tuple[Any, ...], ControllerDesign]) -> None:
    """Take designs made by another process (``known_designs``): ``design_controller`` returns them
    for the same inputs."""
    for key, design in designs.items():
        _DESIGNS.setdefault(key, design)


def _design(
    params: VehicleParams, physics_hz: float, position_hz: float, spec: DesignSpec, step: ReferenceStep, gravity: float
) -> ControllerDesign:
    h, n_sub, tau = 1.0 / physics_hz, check_rates(physics_hz, position_hz), float(params.motor_time_constant)
    source = params.param_file.name if params.param_file is not None else f"vehicle {params.name!r}"
    jx, jy, jz = (float(j) for j in params.inertia)
    vehicle = Airframe(
        params.mass, (jx, jy, jz), np.asarray(params.mixer_inverse, dtype=float), float(params.max_rotor_speed), gravity
    )
    hover = math.sqrt(float(vehicle.hover_speed_sq.max())) / vehicle.max_rotor_speed
    if hover >= spec.max_rotor_fraction:
        raise ConfigError(
            f"cannot hover: hover rotor speed is {100 * hover:.1f} % of max_rotor_speed", source=source, field="z"
        )

    climb = _saturation(vehicle, step, _Gains(), h, n_sub, tau, spec, h)  # the thrust step needs no gains
    if not climb.ok:
        raise ConfigError(f"{_saturation_reason(climb)}", source=source, field="z")

    def check(gains: _Gains) -> str | None:
        return _saturation_reason(_saturation(vehicle, step, gains, h, n_sub, tau, spec, _SEARCH_HORIZON_S))

    # Tilt first, then z, x/y and yaw, each within the rotor range the loops before it leave. When
    # a later loop finds no range left, the tilt loop is capped below its last w_n and all redone.
    cap = spec.attitude_wn_max
    while True:
        try:
            tilt = _design_loop(
                lambda: attitude_plant(h, tau), spec, cap, name="roll/pitch", extra=lambda g: check(_Gains(tilt=g))
            )
            max_pos_bw = tilt.report.bandwidth_rad_s / spec.separation
            wn_pos_max = tilt.report.natural_frequency_rad_s
            vert = _design_loop(
                lambda: vertical_plant(h, n_sub, tau),
                spec,
                wn_pos_max,
                max_bandwidth=1.0 / (tau * spec.separation),
                name="z",
                extra=lambda g: check(_Gains(tilt=tilt.gains, z=g)),
            )
            horiz = _design_loop(
                lambda: horizontal_plant(h, n_sub, tau, tilt.gains),
                spec,
                wn_pos_max,
                max_bandwidth=max_pos_bw,
                name="x/y",
                extra=lambda g: check(_Gains(tilt=tilt.gains, z=vert.gains, xy=g)),
            )
            yaw = _design_loop(
                lambda: attitude_plant(h, tau),
                spec,
                tilt.report.natural_frequency_rad_s,
                name="yaw",
                extra=lambda g: check(_Gains(tilt=tilt.gains, z=vert.gains, xy=horiz.gains, yaw=g)),
            )
            break
        except _NoGains as exc:
            wn_tilt = tilt.report.natural_frequency_rad_s if exc.loop != "roll/pitch" else spec.wn_min
            if not exc.saturated or wn_tilt <= spec.wn_min * _TILT_CAP_FACTOR**-1:
                raise ConfigError(str(exc), source=source, field=exc.loop) from None
            cap = wn_tilt * _TILT_CAP_FACTOR
    # The final check runs until the slowest placed pole has decayed (e^-6), in case a peak comes late.
    slowest = min(spec.integral_pole_ratio * d.report.natural_frequency_rad_s for d in (tilt, vert, horiz, yaw))
    saturation = _saturation(
        vehicle,
        step,
        _Gains(tilt.gains, vert.gains, horiz.gains, yaw.gains),
        h,
        n_sub,
        tau,
        spec,
        min(_FINAL_HORIZON_MAX_S, 6.0 / slowest),
    )
    if not saturation.ok:  # a longer horizon found a later peak than the searches looked at
        raise ConfigError(f"{_saturation_reason(saturation)}", source=source, field=saturation.peak_channel)

    by_loop = {Loop.ROLL: tilt, Loop.PITCH: tilt, Loop.YAW: yaw, Loop.X: horiz, Loop.Y: horiz, Loop.Z: vert}
    attitude_gains = np.stack([by_loop[lp].gains for lp in _ATTITUDE_LOOPS])
    position_gains = np.stack([by_loop[lp].gains for lp in _POSITION_LOOPS])
    attitude_gains.setflags(write=False)
    position_gains.setflags(write=False)
    separation = min(by_loop[lp].report.bandwidth_rad_s for lp in _TILT_LOOPS) / max(
        by_loop[lp].report.bandwidth_rad_s for lp in _TILT_DRIVEN
    )
    return ControllerDesign(
        vehicle=params.name,
        physics_hz=physics_hz,
        position_hz=position_hz,
        attitude_gains=attitude_gains,
        position_gains=position_gains,
        attitude={lp.value: by_loop[lp].report for lp in _ATTITUDE_LOOPS},
        position={lp.value: by_loop[lp].report for lp in _POSITION_LOOPS},
        separation=float(separation),
        natural_frequency={lp.value: float(by_loop[lp].report.natural_frequency_rad_s) for lp in Loop},
        motor_time_constant=tau,
        spec=spec,
        saturation=saturation,
        airframe=vehicle,
        vehicle_file=str(params.param_file) if params.param_file is not None else None,
    )


def _fmt_poles(poles: Sequence[complex]) -> str:
    parts = []
    for p in poles:
        if abs(p.imag) < 1e-9:
            parts.append(f"{p.real:.3g}")
        elif p.imag > 0:
            parts.append(f"{p.real:.3g}+-{p.imag:.3g}j")
    return ", ".join(parts)


def format_table(design: ControllerDesign) -> str:
    """Plain-text report: gains, margins, bandwidths, placed and achieved poles, saturation, requirements."""
    header = (
        f"{'loop':<6}{'wn rad/s':>10}{'kp 1/s^2':>11}{'kd 1/s':>9}{'ki 1/s^3':>11}"
        f"{'GM dB':>8}{'PM deg':>8}{'BW rad/s':>10}"
    )
    lines = [
        f"controller design: {design.vehicle}, attitude {design.physics_hz:g} Hz, position {design.position_hz:g} Hz "
        f"(sampled-data model, motor lag {1000 * design.motor_time_constant:g} ms)",
        header,
        "-" * len(header),
    ]
    for lp in Loop:
        kp, kd, ki = design.gains(lp)
        rep = design.report(lp)
        gm = "inf" if rep.gain_margin_db is None else f"{rep.gain_margin_db:.2f}"
        lines.append(
            f"{lp.value:<6}{rep.natural_frequency_rad_s:>10.3f}{kp:>11.4g}{kd:>9.4g}{ki:>11.4g}"
            f"{gm:>8}{rep.phase_margin_deg:>8.2f}{rep.bandwidth_rad_s:>10.3f}"
        )
    lines.append("-" * len(header))
    lines.append("closed-loop poles, rad/s (s = ln(z) / T): placed | achieved (every pole of the closed loop)")
    for lp in Loop:
        rep = design.report(lp)
        lines.append(f"{lp.value:<6}placed {_fmt_poles(rep.placed_poles)} | achieved {_fmt_poles(rep.achieved_poles)}")
    lines.append(
        f"separation (min tilt BW / max x, y BW): {design.separation:.2f}; "
        f"thrust separation (motor BW 1/tau / z BW): {design.thrust_separation:.2f}"
    )
    sat = design.saturation
    st = sat.step
    lines.append(
        f"saturation: step a = {st.acceleration} m/s^2, p = {st.position} m, yaw = {st.yaw:g} rad (worst signs): "
        f"rotor speed {100 * sat.min_fraction:.1f} .. {100 * sat.peak_fraction:.1f} % of max "
        f"(hover {100 * sat.hover_fraction:.1f} %, limit {100 * sat.limit:.0f} %; peak mostly {sat.peak_channel})"
    )
    problems = design.meets_requirements()
    status = "all met" if not problems else "VIOLATED: " + "; ".join(problems)
    lines.append(
        f"requirements (GM >= {REQUIRED_GAIN_MARGIN_DB:g} dB, PM >= {REQUIRED_PHASE_MARGIN_DEG:g} deg, "
        f"separations >= {REQUIRED_SEPARATION:g}, no rotor saturation): {status}"
    )
    return "\n".join(lines)
