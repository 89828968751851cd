"""Rotor wake: the mean induced flow below a vehicle and the force it puts on the bodies in it.

The flow
--------
Below a vehicle of total thrust T (its current ``kf sum(w^2)``), four rotors of radius r, arm length a
and motor-to-motor diagonal l = 2 a, the mean downward velocity at axial depth z (along the upper
vehicle's thrust axis) and radial distance rho from that axis is one self-similar profile

    U(rho, z) = Uc(z) / (1 + A (rho / b(z))^2)^2,       A = sqrt(2) - 1    (U = Uc / 2 at rho = b)

(the Schlichting-Tollmien round-jet profile; b is the half-width). Velocities scale with the hover
induced velocity of momentum theory over the four discs, U_H = sqrt(T / (2 rho_air 4 pi r^2)).

* Far field, z >= z_f = 2.5 l: the turbulent round jet of Bauersfeld, Muller, Ziegler, Coletti and
  Scaramuzza, "Robotics meets Fluid Dynamics: A Characterization of the Induced Airflow below a
  Quadrotor as a Turbulent Jet", IEEE RA-L 2024 (arXiv 2403.13321): below about 2.5 vehicle sizes the
  combined wake of the rotors is a jet whose centreline velocity falls as 1 / z and whose half-width
  grows linearly, with one set of constants for vehicles of different size once velocities are
  normalised by U_H and lengths by l:
      Uc = U_H B l / (z - z0),   b = S (z - z0),   B = 10.11, z0 = -5.817 l, S = 0.0767.
  The constants are those of the paper as transcribed in the public implementation of the model in
  the gaden gas-dispersion simulator (``QuadrotorDisturbanceFarField``, which cites the paper); the
  paper's own table of fitted values and their spread was not at hand here (see docs/science/wake.md).
  A check that needs no fit: a free jet carries the momentum flux of the thrust that made it; this
  jet carries J = rho_air pi Uc^2 b^2 / (3 A) = 0.76 (l^2 / (4 pi r^2)) T, 0.72 T for the Crazyflie and
  0.67 T for quad150, the same for every z (Uc b is constant): the fit conserves momentum, a little
  below the thrust.
* Near field, z < z_f: momentum theory at the rotor discs. The axial velocity of an actuator-disc
  wake grows from U_H at the disc to 2 U_H far below it as U_m = U_H (1 + z / sqrt(z^2 + r^2))
  (Leishman, Principles of Helicopter Aerodynamics, ch. 2); the four slipstreams are taken as one
  column of the same profile carrying the whole thrust as momentum flux, b_m = sqrt(3 A T /
  (rho_air pi U_m^2)). The two are blended over [0, z_f] with the weight s = smoothstep(z / z_f):
  Uc = (1 - s) U_m + s Uc_jet, b = (1 - s) b_m + s b_jet; at z_f the flow is the jet's.

The force on a vehicle below
----------------------------
A rotor of the lower vehicle in a uniform axial downflow V at its own (constant) rotor speed works as
a rotor in a climb at V: by blade-element momentum theory (Leishman, ch. 3: C_T = (sigma a_l / 4)
(2 theta / 3 - lambda), C_T = 2 lambda_i lambda) its thrust falls from T_k to T_k x (c + x), where
c = V / v_k is the inflow over the rotor's own hover induced velocity v_k = lambda_h w r (lambda_h =
sqrt(C_T / 2) with C_T = kf / (rho_air pi r^4), a constant of a fixed-pitch rotor) and x the root of
2 x^2 + (2 c + q) x - (2 + q (1 - c)) = 0 with q = sigma a_l / (4 lambda_h). For small c the loss is
T_k c q / (q + 4), linear in the inflow velocity (not in its momentum flux, which falls as V^2); a
thrust below zero is clamped to zero. sigma is the rotor solidity (vehicle file), a_l = 5.73 /rad the
blade-section lift slope (Leishman). V is the flow's component along the lower vehicle's thrust axis,
averaged over each of its four discs (four points on the circle at r / sqrt(2): exact for a flow
quadratic across the disc); the loss acts along the lower vehicle's thrust axis, at its centre.

The force on a box below
------------------------
A box (free or carried) gets the drag of the flow on its top face, F = 1/2 rho_air C_d A <V^2>
along the flow, C_d = 1.05 (a cube face-on to the flow: Hoerner, Fluid-Dynamic Drag, 1965, ch. 3),
A the face's area and <V^2> its mean over the face (3 x 3 Gauss points: exact for a flow of degree 5 across it).
A carrier's own box is in its carrier's near wake and is pushed down by it; so is anything under
another vehicle.

Left out: torque from an off-axis wake (the force acts at the centre), horizontal forces, a body
shielding another from the wake, the ground's reflection of the wake, the wake's unsteadiness and
meandering (the model is the time-averaged flow), the upper vehicle's motion (the wake is that of a
hovering vehicle at its current thrust, along its current thrust axis) and the lower rotor's own
speed change (the loss is at its current speed; the controller answers it).
"""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np
from numpy.typing import NDArray

#: kg/m^3, air density (ISA sea level)
RHO_AIR = 1.225
#: Bauersfeld et al. (RA-L 2024) far-field jet: Uc = U_H JET_B l / (z - JET_Z0 l)
JET_B = 10.11
#: virtual origin of the jet, in motor-to-motor diagonals l (above the vehicle: negative)
JET_Z0 = -5.817
#: spreading rate of the jet's half-width, b = JET_S (z - z0)
JET_S = 0.0767
#: the jet holds from this many l below the vehicle (Bauersfeld et al.: about 2.5 vehicle sizes)
JET_START = 2.5
#: shape constant of the round-jet profile, U / Uc = (1 + A xi^2)^-2, halved at xi = 1
PROFILE_A = math.sqrt(2.0) - 1.0
#: 1/rad, lift-curve slope of a blade section (Leishman, Principles of Helicopter Aerodynamics)
LIFT_SLOPE = 5.73
#: drag coefficient of a box's top face in the flow (a cube face-on: Hoerner, Fluid-Dynamic Drag)
BOX_DRAG = 1.05
#: profile value below which a body is out of the wake (its horizontal distance is beyond xi_cut b)
NEGLIGIBLE = 1e-3
#: m/s^2, gravity at which ``column`` evaluates hover thrusts by default
G0 = 9.81

#: 3-point Gauss-Legendre nodes and weights on [-1, 1] (exact for polynomials of degree 5), for the mean over a face
GAUSS_X = np.array([-math.sqrt(0.6), 0.0, math.sqrt(0.6)])
GAUSS_W = np.array([5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0])

# Layout of the constant array of the kernel.
D_KF = 0  # N/(rad/s)^2, thrust coefficient
D_R = 1  # m, rotor radius
D_ARM = 2  # m, arm length (centre to rotor axis)
D_L = 3  # m, motor-to-motor diagonal
D_Q = 4  # -, sigma a_l / (4 lambda_h)
D_LAMH = 5  # -, hover inflow ratio lambda_h = sqrt(C_T / 2)
D_CUT = 6  # -, xi beyond which the profile is below NEGLIGIBLE
D_CFG = 7  # rad, angle of rotor 0 from body x (x configuration pi/4, plus 0)
D_LEN = 8


@dataclasses.dataclass(frozen=True)
class DownwashParams:
    """The wake model's constants of one airframe (from its vehicle file).

    Attributes:
        rotor_radius: m.
        arm_length: m, centre to rotor axis (the motor-to-motor diagonal l is twice it).
        kf: thrust coefficient, N/(rad/s)^2.
        solidity: -, rotor solidity sigma (blade area over disc area).
        configuration: 'x' or 'plus' (where the lower vehicle's rotors are).
    """

    rotor_radius: float
    arm_length: float
    kf: float
    solidity: float
    configuration: str = "x"

    @property
    def diagonal(self) -> float:
        """m, motor-to-motor diagonal l, the jet's length scale."""
        return 2.0 * self.arm_length

    @property
    def hover_inflow(self) -> float:
        """-, lambda_h = sqrt(C_T / 2), C_T = kf / (rho_air pi r^4): a rotor's hover induced velocity per tip speed."""
        return math.sqrt(self.kf / (RHO_AIR * math.pi * self.rotor_radius**4) / 2.0)

    @property
    def blade_ratio(self) -> float:
        """-, q = sigma a_l / (4 lambda_h) of the blade-element thrust loss."""
        return self.solidity * LIFT_SLOPE / (4.0 * self.hover_inflow)

    def const(self) -> NDArray[np.float64]:
        """The constant array of the kernel."""
        c = np.zeros(D_LEN)
        c[D_KF] = self.kf
        c[D_R] = self.rotor_radius
        c[D_ARM] = self.arm_length
        c[D_L] = self.diagonal
        c[D_Q] = self.blade_ratio
        c[D_LAMH] = self.hover_inflow
        c[D_CUT] = math.sqrt((NEGLIGIBLE**-0.5 - 1.0) / PROFILE_A)
        c[D_CFG] = math.pi / 4.0 if self.configuration == "x" else 0.0
        return c

    def hover_velocity(self, thrust: float) -> float:
        """m/s, U_H = sqrt(T / (2 rho_air 4 pi r^2)) of a vehicle of total thrust ``thrust`` N."""
        return math.sqrt(thrust / (2.0 * RHO_AIR * 4.0 * math.pi * self.rotor_radius**2))

    def centreline(self, z: float, thrust: float) -> tuple[float, float]:
        """(Uc m/s, b m): centreline velocity and half-width ``z`` m (> 0) below a vehicle of ``thrust`` N."""
        uc, b = _centre(float(z), float(thrust), self.const())
        return float(uc), float(b)

    def velocity(self, rho: float, z: float, thrust: float) -> float:
        """m/s, mean downward velocity ``z`` m below and ``rho`` m beside the axis of a vehicle of ``thrust`` N."""
        uc, b = self.centreline(z, thrust)
        x = rho / b
        return uc / (1.0 + PROFILE_A * x * x) ** 2

    def force_on_vehicle(self, dz: float, *, upper_thrust: float, lower_thrust: float, offset: float = 0.0) -> float:
        """N, the kernel's force on a level vehicle ``dz`` m below and ``offset`` m beside a level vehicle of this
        airframe, the upper of ``upper_thrust`` N, the lower of ``lower_thrust`` N (rotors alike)."""
        state = np.zeros((2, 13))
        state[:, 6] = 1.0
        state[0, :3] = (0.0, 0.0, 10.0)
        state[1, :3] = (offset, 0.0, 10.0 - dz)
        w = np.empty((2, 4))
        w[0] = math.sqrt(upper_thrust / (4.0 * self.kf))
        w[1] = math.sqrt(lower_thrust / (4.0 * self.kf))
        force = np.zeros((2, 3))
        wake_forces(state, w, self.const(), np.zeros((0, 7)), np.zeros((0, 3)), force, np.zeros((0, 3)))
        return float(-force[1, 2])

    def force_on_box(self, dz: float, size: float, *, thrust: float, offset: float = 0.0) -> float:
        """N, the kernel's drag on a level cube of edge ``size`` m whose top face is ``dz`` m below and ``offset`` m
        beside a level vehicle of this airframe giving ``thrust`` N."""
        state = np.zeros((1, 13))
        state[0, :3] = (0.0, 0.0, 10.0)
        state[0, 6] = 1.0
        w = np.full((1, 4), math.sqrt(thrust / (4.0 * self.kf)))
        box = np.array([[offset, 0.0, 10.0 - dz - 0.5 * size, 0.0, 0.0, 0.0, 1.0]])
        half = np.full((1, 3), 0.5 * size)
        out = np.zeros((1, 3))
        wake_forces(state, w, self.const(), box, half, np.zeros((1, 3)), out)
        return float(-out[0, 2])

    def column(self, fraction: float, *, mass: float, load: float = 0.0, gravity: float = G0) -> tuple[float, float]:
        """(depth m, half-width m) of the column below a hovering vehicle of this airframe carrying ``load`` kg in
        which the wake pushes a hovering, unladen vehicle of the same airframe (``mass`` kg) down with more than
        ``fraction`` of its weight: the depth where the force straight below falls under it (the force falls
        with depth past its peak; bisection to 1 mm), and the largest horizontal offset with that force above it at
        any depth down to there (searched on a 1 cm grid of depths, bisection to 1 mm)."""
        if not 0.0 < fraction < 1.0:
            raise ValueError(f"fraction must lie in (0, 1), got {fraction}")
        upper, lower = (mass + load) * gravity, mass * gravity
        limit = fraction * lower

        def force(dz: float, off: float = 0.0) -> float:
            return self.force_on_vehicle(dz, upper_thrust=upper, lower_thrust=lower, offset=off)

        lo, hi = 0.01, 50.0
        if force(hi) > limit:
            depth = hi
        elif force(lo) <= limit:
            return 0.0, 0.0
        else:
            while hi - lo > 1e-3:
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if force(mid) > limit else (lo, mid)
            depth = hi
        width = 0.0
        for dz in np.arange(0.01, depth, 0.01):
            if force(float(dz)) <= limit:
                continue
            a, b = 0.0, 0.5 + 2.0 * float(dz)
            while b - a > 1e-3:
                mid = 0.5 * (a + b)
                a, b = (mid, b) if force(float(dz), mid) > limit else (a, mid)
            width = max(width, b)
        return depth, width


@numba.njit(cache=True, inline="always")
def _centre(z: float, thrust: float, c: NDArray[np.float64]) -> tuple[float, float]:
    """(Uc m/s, b m) of the blended wake ``z`` m (> 0) below a vehicle of ``thrust`` N (see the module notes)."""
    r, ell = c[D_R], c[D_L]
    if thrust <= 0.0:
        return 0.0, 1.0
    uh = math.sqrt(thrust / (2.0 * RHO_AIR * 4.0 * math.pi * r * r))
    zr = z - JET_Z0 * ell
    uj = uh * JET_B * ell / zr
    bj = JET_S * zr
    s = z / (JET_START * ell)
    if s >= 1.0:
        return uj, bj
    um = uh * (1.0 + z / math.sqrt(z * z + r * r))
    bm = math.sqrt(3.0 * PROFILE_A * thrust / (RHO_AIR * math.pi * um * um))
    w = s * s * (3.0 - 2.0 * s)
    return (1.0 - w) * um + w * uj, (1.0 - w) * bm + w * bj


@numba.njit(cache=True, inline="always")
def _flow(
    px: float, py: float, pz: float, o: NDArray[np.float64], e: NDArray[np.float64], uc: float, b: float
) -> float:
    """m/s, the wake's speed at a point of depth already used for (uc, b): o the upper vehicle's position, e its
    thrust axis (unit, up)."""
    dx, dy, dz = px - o[0], py - o[1], pz - o[2]
    z = -(dx * e[0] + dy * e[1] + dz * e[2])
    rx, ry, rz = dx + z * e[0], dy + z * e[1], dz + z * e[2]
    x2 = (rx * rx + ry * ry + rz * rz) / (b * b)
    d = 1.0 + PROFILE_A * x2
    return uc / (d * d)


@numba.njit(cache=True, inline="always")
def _rotation(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3, 3) rotation matrix of a quaternion (x, y, z, w)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    n = x * x + y * y + z * z + w * w
    s = 2.0 / n if n > 0.0 else 0.0
    R = np.empty((3, 3))
    R[0, 0] = 1.0 - s * (y * y + z * z)
    R[0, 1] = s * (x * y - z * w)
    R[0, 2] = s * (x * z + y * w)
    R[1, 0] = s * (x * y + z * w)
    R[1, 1] = 1.0 - s * (x * x + z * z)
    R[1, 2] = s * (y * z - x * w)
    R[2, 0] = s * (x * z - y * w)
    R[2, 1] = s * (y * z + x * w)
    R[2, 2] = 1.0 - s * (x * x + y * y)
    return R


@numba.njit(cache=True, inline="always")
def _rotor_loss(c_in: float, q: float) -> float:
    """-, fraction of its thrust a rotor loses at constant speed in an axial downflow of ``c_in`` times its hover
    induced velocity (blade-element momentum theory in a climb; clamped to [0, 1])."""
    if c_in <= 0.0:
        return 0.0
    p = 2.0 * c_in + q
    x = (-p + math.sqrt(p * p + 8.0 * (2.0 + q * (1.0 - c_in)))) / 4.0
    kept = x * (c_in + x)
    if kept < 0.0:
        kept = 0.0
    return 1.0 - kept if kept < 1.0 else 0.0


@numba.njit(cache=True)
def wake_forces(
    state: NDArray[np.float64],  # (n, >=7) vehicles: position m, quaternion (x, y, z, w)
    w: NDArray[np.float64],  # (n, 4) rotor speeds rad/s
    c: NDArray[np.float64],  # (D_LEN,) constants, see D_*
    boxes: NDArray[np.float64],  # (k, 7) boxes: position m, quaternion (x, y, z, w)
    box_half: NDArray[np.float64],  # (k, 3) m, boxes' half extents along their own axes
    force: NDArray[np.float64],  # (n, 3) N world force on the vehicles (in/out, added to)
    box_force: NDArray[np.float64],  # (k, 3) N world force on the boxes (in/out, added to)
) -> None:
    """Add every vehicle's wake force on every vehicle and box below it (all pairs, one pass)."""
    n, k = state.shape[0], boxes.shape[0]
    kf, r, arm, q, lamh, cut, cfg = c[D_KF], c[D_R], c[D_ARM], c[D_Q], c[D_LAMH], c[D_CUT], c[D_CFG]
    ring = r / math.sqrt(2.0)
    e = np.empty(3)
    rot = np.empty((n, 3, 3))
    for i in range(n):
        rot[i] = _rotation(state[i, 3:7])
    for j in range(n):
        thrust = kf * (w[j, 0] * w[j, 0] + w[j, 1] * w[j, 1] + w[j, 2] * w[j, 2] + w[j, 3] * w[j, 3])
        if not thrust > 0.0:  # also a non-finite state
            continue
        e[0], e[1], e[2] = rot[j, 0, 2], rot[j, 1, 2], rot[j, 2, 2]
        o = state[j, :3]
        for i in range(n):
            if i == j:
                continue
            dx, dy, dz = state[i, 0] - o[0], state[i, 1] - o[1], state[i, 2] - o[2]
            z = -(dx * e[0] + dy * e[1] + dz * e[2])
            if not z > 0.0:
                continue
            uc, b = _centre(z, thrust, c)
            rx, ry, rz = dx + z * e[0], dy + z * e[1], dz + z * e[2]
            reach = cut * b + arm + r
            if rx * rx + ry * ry + rz * rz > reach * reach:
                continue
            R = rot[i]
            axial = e[0] * R[0, 2] + e[1] * R[1, 2] + e[2] * R[2, 2]  # the flow's share along i's thrust axis
            if not axial > 0.0:
                continue
            loss = 0.0
            for m in range(4):
                ang = cfg + m * 0.5 * math.pi
                bx, by = arm * math.cos(ang), arm * math.sin(ang)
                v = 0.0
                for t in range(4):
                    a2 = t * 0.5 * math.pi
                    lx, ly = bx + ring * math.cos(a2), by + ring * math.sin(a2)
                    px = state[i, 0] + R[0, 0] * lx + R[0, 1] * ly
                    py = state[i, 1] + R[1, 0] * lx + R[1, 1] * ly
                    pz = state[i, 2] + R[2, 0] * lx + R[2, 1] * ly
                    v += _flow(px, py, pz, o, e, uc, b)
                wi = w[i, m]
                vh = lamh * abs(wi) * r  # the rotor's hover induced velocity at its speed now
                if vh > 0.0:
                    loss += kf * wi * wi * _rotor_loss(0.25 * v * axial / vh, q)
            force[i, 0] -= loss * R[0, 2]
            force[i, 1] -= loss * R[1, 2]
            force[i, 2] -= loss * R[2, 2]
        for m in range(k):
            Rb = _rotation(boxes[m, 3:7])
            # the face whose outward normal points most nearly up, its half sides along the other two axes
            up, best = 0, abs(Rb[2, 0])
            for a in range(1, 3):
                if abs(Rb[2, a]) > best:
                    up, best = a, abs(Rb[2, a])
            sgn = 1.0 if Rb[2, up] > 0.0 else -1.0
            u1, u2 = (up + 1) % 3, (up + 2) % 3
            cx = boxes[m, 0] + sgn * box_half[m, up] * Rb[0, up]
            cy = boxes[m, 1] + sgn * box_half[m, up] * Rb[1, up]
            cz = boxes[m, 2] + sgn * box_half[m, up] * Rb[2, up]
            dx, dy, dz = cx - o[0], cy - o[1], cz - o[2]
            z = -(dx * e[0] + dy * e[1] + dz * e[2])
            if not z > 0.0:
                continue
            uc, b = _centre(z, thrust, c)
            rx, ry, rz = dx + z * e[0], dy + z * e[1], dz + z * e[2]
            h1, h2 = box_half[m, u1], box_half[m, u2]
            reach = cut * b + math.sqrt(h1 * h1 + h2 * h2)
            if rx * rx + ry * ry + rz * rz > reach * reach:
                continue
            v2 = 0.0
            for g1 in range(3):
                for g2 in range(3):
                    a1, a2 = GAUSS_X[g1] * h1, GAUSS_X[g2] * h2
                    px = cx + a1 * Rb[0, u1] + a2 * Rb[0, u2]
                    py = cy + a1 * Rb[1, u1] + a2 * Rb[1, u2]
                    pz = cz + a1 * Rb[2, u1] + a2 * Rb[2, u2]
                    v = _flow(px, py, pz, o, e, uc, b)
                    v2 += 0.25 * GAUSS_W[g1] * GAUSS_W[g2] * v * v
            drag = 0.5 * RHO_AIR * BOX_DRAG * (4.0 * h1 * h2) * v2
            box_force[m, 0] -= drag * e[0]
            box_force[m, 1] -= drag * e[1]
            box_force[m, 2] -= drag * e[2]


class Downwash:
    """The wakes of a swarm of one airframe, added to the world forces once per physics step.

    Args:
        params: the airframe's wake constants.
    """

    def __init__(self, params: DownwashParams) -> None:
        self.params = params
        self.const = params.const()
        self.last: NDArray[np.float64] = np.zeros(0)  # N, (n,) downward force on each vehicle at the last call
        self._no_boxes = np.zeros((0, 7)), np.zeros((0, 3)), np.zeros((0, 3))

    def add_to(
        self,
        state: NDArray[np.float64],
        rotor_speeds: NDArray[np.float64],
        force: NDArray[np.float64],
        boxes: NDArray[np.float64] | None = None,
        box_half: NDArray[np.float64] | None = None,
        box_force: NDArray[np.float64] | None = None,
    ) -> None:
        """Add the wakes' forces to ``force`` (n, 3) N, world frame, from ``state`` (n, 13) and rotor speeds
        (n, 4) rad/s, and to ``box_force`` (k, 3) N for boxes of poses ``boxes`` (k, 7) and half extents
        ``box_half`` (k, 3) m; ``last`` keeps the downward force each vehicle got (N)."""
        if boxes is None or box_half is None or box_force is None:
            boxes, box_half, box_force = self._no_boxes
        before = force[:, 2].copy()
        wake_forces(state, rotor_speeds, self.const, boxes, box_half, force, box_force)
        self.last = before - force[:, 2]
