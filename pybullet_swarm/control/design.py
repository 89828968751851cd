"""Design the cascade PID gains from python-control models of the linearised hover dynamics.

The runtime controller (``cascade``) is a PID cascade in acceleration units, so the gains here
do not depend on mass or inertia; the runtime multiplies them by ``mass`` or ``inertia``.

Attitude loop, at ``physics_hz``, per axis roll, pitch, yaw (e = theta - theta_ref rad,
w body rate rad/s)::

    alpha_cmd = -kp e - kd (w - w_ref) - ki integral(e dt)          rad/s^2;  torque = J alpha_cmd

Position loop, at ``position_hz``, per axis x, y, z (e = p - p_ref m, v velocity m/s)::

    a_cmd = a_ref - kp e - kd (v - v_ref) - ki integral(e dt)       m/s^2

Linearised plants from the acceleration command to the output (``Pade(T)`` is a Pade
approximation of a pure delay T that models the sample-and-hold of a loop as half a period)::

    roll, pitch, yaw:  1/s^2 * 1/(tau_m s + 1) * Pade(T_a/2)                 T_a = 1/physics_hz
    x, y:              T_att(s) * Pade(T_p/2) / s^2                          T_p = 1/position_hz
    z:                 1/s^2 * 1/(tau_m s + 1) * Pade((T_p + T_a)/2)

``T_att`` is the closed attitude loop (pitch for x, roll for y) from attitude reference to attitude.

Each loop's gains come from pole placement (``control.place``) on the PID-augmented double
integrator with state [integral e, e, de/dt]: a complex pole pair at natural frequency w_n with
damping ``DesignSpec.damping`` and a real integral pole at ``-integral_pole_ratio * w_n``.
w_n is the largest value (by bisection) whose loop, evaluated on the full model with motor lag
and delay, is stable and meets the margin targets; for the position loops also the bandwidth
must stay below the slowest attitude bandwidth divided by the separation target.
"""
from __future__ import annotations

import dataclasses
import enum
import functools
import math
import control
import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.vehicle.params import VehicleParams

#: Gain margin every loop must have, dB (the design targets more, see ``DesignSpec``).
REQUIRED_GAIN_MARGIN_DB = 6.0
#: Phase margin every loop must have, deg.
REQUIRED_PHASE_MARGIN_DEG = 45.0
#: Minimum ratio of the slowest attitude bandwidth to the fastest position bandwidth.
REQUIRED_SEPARATION = 4.0


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
#: Attitude loop that realises the horizontal acceleration of each horizontal position loop.
_TILT_LOOP = {Loop.X: Loop.PITCH, Loop.Y: Loop.ROLL}


@dataclasses.dataclass(frozen=True)
class DesignSpec:
    """Targets and pole pattern of the design (targets keep headroom over the requirements).

    Attributes:
        gain_margin_db: target gain margin of every loop, dB (requirement 6 dB).
        phase_margin_deg: target phase margin of every loop, deg (requirement 45 deg).
        separation: target ratio of slowest attitude bandwidth to fastest position bandwidth
            (requirement 4).
        damping: damping ratio of the complex closed-loop pole pair of the design model.
        integral_pole_ratio: the real (integral) pole sits at ``-integral_pole_ratio * w_n``;
            about 1/3..1/2 keeps the integral gain large enough to reject a constant disturbance
            (e.g. a 20 % payload) within a few seconds.
        attitude_wn_max: cap on the attitude natural frequency, rad/s.
        wn_min: lower end of the natural frequency search, rad/s; a loop infeasible there is an error.
        pade_order: order of the Pade approximations of the hold delays.
        wn_rel_tol: relative tolerance of the bisection on w_n.
    """

    gain_margin_db: float = 8.0
    phase_margin_deg: float = 50.0
    separation: float = 5.0
    damping: float = 0.8
    integral_pole_ratio: float = 0.4
    attitude_wn_max: float = 40.0
    wn_min: float = 0.05
    pade_order: int = 2
    wn_rel_tol: float = 1e-3

    def __post_init__(self) -> None:
        checks = {
            "gain_margin_db": self.gain_margin_db > 0,
            "phase_margin_deg": 0 < self.phase_margin_deg < 90,
            "separation": self.separation > 0,
            "damping": 0 < self.damping < 1,
            "integral_pole_ratio": self.integral_pole_ratio > 0,
            "attitude_wn_max": self.attitude_wn_max > self.wn_min,
            "wn_min": self.wn_min > 0,
            "pade_order": self.pade_order >= 1,
            "wn_rel_tol": 0 < self.wn_rel_tol < 0.5,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"DesignSpec.{name}: out of range, got {getattr(self, name)!r}")


@dataclasses.dataclass(frozen=True)
class LoopReport:
    """Margins and bandwidth of one loop.

    Attributes:
        gain_margin_db: factor by which the loop gain may grow before instability, dB
            (``None`` when no phase crossover limits it, i.e. infinite).
        phase_margin_deg: smallest phase margin over all gain crossovers, deg.
        bandwidth_rad_s: -3 dB bandwidth of the closed loop from reference to output, rad/s.
    """

    gain_margin_db: float | None
    phase_margin_deg: float
    bandwidth_rad_s: float

    def to_json_dict(self) -> dict[str, float | None]:
        """The report as plain Python floats."""
        gm = None if self.gain_margin_db is None else float(self.gain_margin_db)
        return {
            "gain_margin_db": gm,
            "phase_margin_deg": float(self.phase_margin_deg),
            "bandwidth_rad_s": float(self.bandwidth_rad_s),
        }


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
        separation: min attitude bandwidth / max position bandwidth.
        natural_frequency: design natural frequency w_n of each loop, rad/s, keys as ``Loop`` values.
        motor_time_constant: first-order motor lag used in the models, s.
        spec: the specification the gains were designed to.
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

    def gains(self, loop: Loop | str) -> NDArray[np.float64]:
        """PID gains (kp 1/s^2, kd 1/s, ki 1/s^3), shape (3,), of one loop."""
        lp = Loop(loop)
        table = self.attitude_gains if lp.is_attitude else self.position_gains
        return table[lp.row]

    def report(self, loop: Loop | str) -> LoopReport:
        """Margins and bandwidth of one loop."""
        lp = Loop(loop)
        return (self.attitude if lp.is_attitude else self.position)[lp.value]

    def plant(self, loop: Loop | str) -> control.TransferFunction:
        """Linearised plant of a loop, from acceleration command (rad/s^2 or m/s^2) to output (rad or m)."""
        lp = Loop(loop)
        models = _Models(self.motor_time_constant, self.physics_hz, self.position_hz, self.spec.pade_order)
        if lp.is_attitude:
            return models.attitude_plant()
        if lp is Loop.Z:
            return models.vertical_plant()
        return models.horizontal_plant(self.closed_loop(_TILT_LOOP[lp]))

    def open_loop(self, loop: Loop | str) -> control.TransferFunction:
        """Loop transfer function L(s) = C(s) P(s), broken at the acceleration command."""
        return pid_open_loop(self.plant(loop), self.gains(loop))

    def closed_loop(self, loop: Loop | str) -> control.TransferFunction:
        """Closed loop T(s) from reference to output with the derivative on the measurement."""
        return pid_closed_loop(self.plant(loop), self.gains(loop))

    def acceleration_path(self, loop: Loop | str) -> control.TransferFunction:
        """A position loop's inner path from commanded to achieved acceleration (unity DC gain):
        closed tilt loop and hold for x and y, motor lag and holds for z."""
        lp = Loop(loop)
        if lp.is_attitude:
            raise ValueError(f"acceleration_path: expected a position loop (x, y, z), got {lp.value!r}")
        return control.minreal(self.plant(lp) * _double_integrator() ** -1, verbose=False)

    def to_json_dict(self) -> dict[str, object]:
        """The report as JSON-ready plain Python values (no gains; see ``format_table``)."""
        return {
            "vehicle": str(self.vehicle),
            "attitude": {lp.value: self.attitude[lp.value].to_json_dict() for lp in _ATTITUDE_LOOPS},
            "position": {lp.value: self.position[lp.value].to_json_dict() for lp in _POSITION_LOOPS},
            "separation": float(self.separation),
        }

    def meets_requirements(self) -> list[str]:
        """Human-readable violations of the requirements; empty when all hold."""
        problems: list[str] = []
        for lp in Loop:
            rep = self.report(lp)
            if rep.gain_margin_db is not None and rep.gain_margin_db < REQUIRED_GAIN_MARGIN_DB:
                problems.append(
                    f"{lp.value}: gain margin {rep.gain_margin_db:.2f} dB < {REQUIRED_GAIN_MARGIN_DB:g} dB"
                )
            if rep.phase_margin_deg < REQUIRED_PHASE_MARGIN_DEG:
                problems.append(
                    f"{lp.value}: phase margin {rep.phase_margin_deg:.2f} deg < {REQUIRED_PHASE_MARGIN_DEG:g} deg"
                )
            if not is_stable(self.closed_loop(lp)):
                problems.append(f"{lp.value}: closed loop unstable")
        if self.separation < REQUIRED_SEPARATION:
            problems.append(f"separation {self.separation:.2f} < {REQUIRED_SEPARATION:g}")
        return problems


# ---------------------------------------------------------------------------------------------
# Models


@dataclasses.dataclass(frozen=True)
class _Models:
    """Builds the linearised plants of one vehicle at given loop rates."""

    motor_time_constant: float  # s
    physics_hz: float           # Hz
    position_hz: float          # Hz
    pade_order: int

    def attitude_plant(self) -> control.TransferFunction:
        """theta / alpha_cmd: double integrator, motor lag, half-period hold of the attitude loop."""
        return _double_integrator() * _lag(self.motor_time_constant) * _delay(0.5 / self.physics_hz, self.pade_order)

    def horizontal_plant(self, tilt_closed_loop: control.TransferFunction) -> control.TransferFunction:
        """p / a_cmd for x or y: closed tilt loop, half-period hold of the position loop, double integrator."""
        return tilt_closed_loop * _delay(0.5 / self.position_hz, self.pade_order) * _double_integrator()

    def vertical_plant(self) -> control.TransferFunction:
        """z / a_cmd: double integrator, motor lag, holds of both loops."""
        hold = 0.5 / self.position_hz + 0.5 / self.physics_hz
        return _double_integrator() * _lag(self.motor_time_constant) * _delay(hold, self.pade_order)


def _double_integrator() -> control.TransferFunction:
    return control.tf([1.0], [1.0, 0.0, 0.0])


def _lag(tau: float) -> control.TransferFunction:
    return control.tf([1.0], [tau, 1.0])


def _delay(delay: float, order: int) -> control.TransferFunction:
    num, den = control.pade(delay, order)
    return control.tf(num, den)


def _num_den(sys: control.TransferFunction) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return np.asarray(sys.num[0][0], dtype=float), np.asarray(sys.den[0][0], dtype=float)


def pid_open_loop(plant: control.TransferFunction, gains: NDArray[np.float64]) -> control.TransferFunction:
    """Loop transfer function (kp + kd s + ki/s) P(s) of a PID with gains (kp, kd, ki), shape (3,)."""
    kp, kd, ki = (float(g) for g in gains)
    return control.tf([kd, kp, ki], [1.0, 0.0]) * plant


def pid_closed_loop(plant: control.TransferFunction, gains: NDArray[np.float64]) -> control.TransferFunction:
    """Reference-to-output closed loop of a PID with P and I on the error and D on the measurement.

    With P = N/D: y = P (kp + ki/s)(r - y) - P kd s y, hence
    T = N (kp s + ki) / (s D + N (kd s^2 + kp s + ki)), built on polynomials so it stays minimal.

    Args:
        plant: SISO plant P(s).
        gains: (kp, kd, ki), shape (3,).
    """
    kp, kd, ki = (float(g) for g in gains)
    num, den = _num_den(plant)
    t_num = np.polymul(num, [kp, ki])
    t_den = np.polyadd(np.polymul(den, [1.0, 0.0]), np.polymul(num, [kd, kp, ki]))
    return control.tf(np.trim_zeros(t_num, "f"), np.trim_zeros(t_den, "f"))


def is_stable(sys: control.TransferFunction) -> bool:
    """True when every pole of a continuous-time system lies in the open left half plane."""
    return bool(np.all(np.real(sys.poles()) < 0.0))


# ---------------------------------------------------------------------------------------------
# Gains, margins, bandwidth


def pid_gains(wn: float, damping: float, integral_pole_ratio: float) -> NDArray[np.float64]:
    """PID gains (kp 1/s^2, kd 1/s, ki 1/s^3), shape (3,), placing the poles of the design model.

    The design model is the PID-augmented double integrator with state [integral e, e, de/dt]
    and input the acceleration u = -(ki, kp, kd) . state; its poles are placed at
    w_n (-damping +- j sqrt(1 - damping^2)) and -integral_pole_ratio w_n.
    """
    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    b = np.array([[0.0], [0.0], [1.0]])
    im = math.sqrt(1.0 - damping**2)
    poles = [wn * complex(-damping, im), wn * complex(-damping, -im), -integral_pole_ratio * wn]
    ki, kp, kd = np.asarray(control.place(a, b, poles), dtype=float).ravel()
    return np.array([kp, kd, ki])


def loop_margins(loop_tf: control.TransferFunction) -> tuple[float | None, float]:
    """Upper gain margin (dB, ``None`` if infinite) and smallest phase margin (deg) of L(s).

    ``control.stability_margins`` reports the gain margin closest to 0 dB, which for a PID
    around a double integrator is the lower (conditional-stability) margin below 0 dB; the
    requirement concerns gain increase, so this takes the smallest margin above 0 dB.
    """
    gm, pm, _sm, _wpc, _wgc, _wms = control.stability_margins(loop_tf, returnall=True)
    gm = np.atleast_1d(np.asarray(gm, dtype=float))
    pm = np.atleast_1d(np.asarray(pm, dtype=float))
    upper = gm[np.isfinite(gm) & (gm > 1.0)]
    gm_db = float(20.0 * np.log10(upper.min())) if upper.size else None
    if pm.size == 0:
        raise ValueError("loop transfer function has no gain crossover")
    return gm_db, float(pm.min())


def _evaluate(plant: control.TransferFunction, gains: NDArray[np.float64]) -> LoopReport | None:
    """Report of a PID loop, or ``None`` when the closed loop is unstable."""
    closed = pid_closed_loop(plant, gains)
    if not is_stable(closed):
        return None
    gm_db, pm_deg = loop_margins(pid_open_loop(plant, gains))
    bw = float(control.bandwidth(closed))
    if not np.isfinite(bw):
        return None
    return LoopReport(gain_margin_db=gm_db, phase_margin_deg=pm_deg, bandwidth_rad_s=bw)


@dataclasses.dataclass(frozen=True)
class _LoopDesign:
    """Result of designing one loop."""

    wn: float                      # rad/s
    gains: NDArray[np.float64]     # (3,) kp 1/s^2, kd 1/s, ki 1/s^3
    report: LoopReport


def _design_loop(
    plant: control.TransferFunction,
    spec: DesignSpec,
    wn_max: float,
    max_bandwidth: float = math.inf,
    name: str = "",
) -> _LoopDesign:
    """Largest w_n in [spec.wn_min, wn_max] whose loop is stable and meets the targets.

    Bisection on log w_n; feasibility (stable, margins, bandwidth) is judged on the full plant.

    Args:
        plant: full plant of the loop, acceleration command to output.
        spec: targets and pole pattern.
        wn_max: upper end of the search, rad/s.
        max_bandwidth: largest allowed closed-loop bandwidth, rad/s.
        name: loop name for error messages.

    Raises:
        ValueError: not even ``spec.wn_min`` meets the targets.
    """
    def attempt(wn: float) -> _LoopDesign | None:
        gains = pid_gains(wn, spec.damping, spec.integral_pole_ratio)
        rep = _evaluate(plant, gains)
        if rep is None:
            return None
        ok = (
            (rep.gain_margin_db is None or rep.gain_margin_db >= spec.gain_margin_db)
            and rep.phase_margin_deg >= spec.phase_margin_deg
            and rep.bandwidth_rad_s <= max_bandwidth
        )
        return _LoopDesign(wn, gains, rep) if ok else None

    best = attempt(wn_max)
    if best is not None:
        return best
    lo, hi = spec.wn_min, wn_max
    best = attempt(lo)
    if best is None:
        raise ValueError(f"{name} loop: no natural frequency >= {lo:g} rad/s meets the design targets")
    while hi / lo > 1.0 + spec.wn_rel_tol:
        mid = math.sqrt(lo * hi)
        found = attempt(mid)
        if found is None:
            hi = mid
        else:
            lo, best = mid, found
    return best


# ---------------------------------------------------------------------------------------------
# Public entry points


def check_rates(physics_hz: float, position_hz: float) -> int:
    """Number of physics ticks per position tick; ValueError unless position_hz divides physics_hz."""
    if not (physics_hz > 0 and position_hz > 0 and math.isfinite(physics_hz) and math.isfinite(position_hz)):
        raise ValueError(f"physics_hz {physics_hz} and position_hz {position_hz} must be positive")
    ratio = physics_hz / position_hz
    n = round(ratio)
    if n < 1 or abs(ratio - n) > 1e-9 * ratio:
        raise ValueError(
            f"position_hz {position_hz} must divide physics_hz {physics_hz} exactly (ratio {ratio:g})"
        )
    return n


def design_controller(
    params: VehicleParams,
    *,
    physics_hz: float = 240.0,
    position_hz: float = 48.0,
    spec: DesignSpec | None = None,
) -> ControllerDesign:
    """Design the attitude and position PID gains of a vehicle (cached: same inputs, same object).

    Args:
        params: vehicle parameters; only ``name`` and ``motor_time_constant`` enter the design.
        physics_hz: attitude loop (physics) rate, Hz.
        position_hz: position loop rate, Hz; must divide ``physics_hz``.
        spec: targets and pole pattern; ``DesignSpec()`` when None.

    Raises:
        ValueError: the rates do not divide, or no gains meet the targets.
    """
    check_rates(physics_hz, position_hz)
    return _design_cached(params, float(physics_hz), float(position_hz), spec or DesignSpec())


@functools.lru_cache(maxsize=64)
def _design_cached(params: VehicleParams, physics_hz: float, position_hz: float, spec: DesignSpec) -> ControllerDesign:
    models = _Models(float(params.motor_time_constant), physics_hz, position_hz, spec.pade_order)

    # The attitude model does not depend on the inertia (gains are in acceleration units), so
    # roll, pitch and yaw share one design.
    att = _design_loop(models.attitude_plant(), spec, spec.attitude_wn_max, name="attitude")
    max_pos_bw = att.report.bandwidth_rad_s / spec.separation
    tilt = pid_closed_loop(models.attitude_plant(), att.gains)
    horiz = _design_loop(models.horizontal_plant(tilt), spec, att.wn, max_pos_bw, name="horizontal")
    vert = _design_loop(models.vertical_plant(), spec, att.wn, max_pos_bw, name="vertical")

    by_loop = {Loop.ROLL: att, Loop.PITCH: att, Loop.YAW: att, Loop.X: horiz, Loop.Y: horiz, Loop.Z: vert}
    attitude_gains = np.stack([by_loop[lp].gains for lp in _ATTITUDE_LOOPS])
    position_gains = np.stack([by_loop[lp].gains for lp in _POSITION_LOOPS])
    attitude_gains.setflags(write=False)
    position_gains.setflags(write=False)
    separation = min(by_loop[lp].report.bandwidth_rad_s for lp in _ATTITUDE_LOOPS) / max(
        by_loop[lp].report.bandwidth_rad_s for lp in _POSITION_LOOPS
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
        natural_frequency={lp.value: float(by_loop[lp].wn) for lp in Loop},
        motor_time_constant=float(params.motor_time_constant),
        spec=spec,
    )


def format_table(design: ControllerDesign) -> str:
    """Plain-text table of gains, margins and bandwidths of every loop, with the requirement status."""
    header = (
        f"{'loop':<6}{'wn rad/s':>10}{'kp 1/s^2':>11}{'kd 1/s':>9}{'ki 1/s^3':>11}"
        f"{'GM dB':>8}{'PM deg':>8}{'BW rad/s':>10}"
    )
    lines = [
        f"controller design: {design.vehicle}, attitude {design.physics_hz:g} Hz, position {design.position_hz:g} Hz",
        header,
        "-" * len(header),
    ]
    for lp in Loop:
        kp, kd, ki = design.gains(lp)
        rep = design.report(lp)
        gm = "inf" if rep.gain_margin_db is None else f"{rep.gain_margin_db:.2f}"
        lines.append(
            f"{lp.value:<6}{design.natural_frequency[lp.value]:>10.3f}{kp:>11.4g}{kd:>9.4g}{ki:>11.4g}"
            f"{gm:>8}{rep.phase_margin_deg:>8.2f}{rep.bandwidth_rad_s:>10.3f}"
        )
    lines.append("-" * len(header))
    lines.append(f"separation (min attitude BW / max position BW): {design.separation:.2f}")
    problems = design.meets_requirements()
    status = "all met" if not problems else "VIOLATED: " + "; ".join(problems)
    lines.append(
        f"requirements (GM >= {REQUIRED_GAIN_MARGIN_DB:g} dB, PM >= {REQUIRED_PHASE_MARGIN_DEG:g} deg, "
        f"separation >= {REQUIRED_SEPARATION:g}): {status}"
    )
    return "\n".join(lines)
