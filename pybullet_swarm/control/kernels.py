"""Compiled per-tick kernels of the cascade: position loop, attitude loop + mixer + motors.

These loops over agents run once per control tick (position) and once per physics tick
(attitude); fusing them into one compiled call per tick keeps the per-drone Python work at
zero (see ``scripts/bench.py``). Arrays follow the conventions of ``pybullet_swarm.types``:
states (n, 13) = position m, quaternion (x, y, z, w), world velocity m/s,
world angular velocity rad/s.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.vehicle.dynamics import motor_update_row

STATUS_OK = 0
STATUS_FLIPPED = 1
STATUS_NONFINITE = 2
#: m/s; faster than this, a state counts as diverged (Bullet itself clamps at 100 m/s).
MAX_SPEED = 50.0


@numba.njit(cache=True, inline="always")
def _quat_to_R(pose: NDArray[np.float64], i: int, R: NDArray[np.float64]) -> None:
    x, y, z, w = pose[i, 3], pose[i, 4], pose[i, 5], pose[i, 6]
    R[0, 0] = 1 - 2 * (y * y + z * z)
    R[0, 1] = 2 * (x * y - z * w)
    R[0, 2] = 2 * (x * z + y * w)
    R[1, 0] = 2 * (x * y + z * w)
    R[1, 1] = 1 - 2 * (x * x + z * z)
    R[1, 2] = 2 * (y * z - x * w)
    R[2, 0] = 2 * (x * z - y * w)
    R[2, 1] = 2 * (y * z + x * w)
    R[2, 2] = 1 - 2 * (x * x + y * y)


@numba.njit(cache=True)
def position_tick(
    state: NDArray[np.float64],  # (n, 13) position, quaternion, velocity, angular velocity
    p_ref: NDArray[np.float64],  # (n, 3) m
    v_ref: NDArray[np.float64],  # (n, 3) m/s
    a_ref: NDArray[np.float64],  # (n, 3) m/s^2
    yaw_ref: NDArray[np.float64],  # (n,) rad
    yaw_rate_ref: NDArray[np.float64],  # (n,) rad/s
    gains: NDArray[np.float64],  # (3, 3) rows x, y, z; cols kp, kd, ki
    integ: NDArray[np.float64],  # (n, 3) m s, integral of the position error (in/out)
    int_max: NDArray[np.float64],  # (3,) m/s^2, bound on |ki * integral| per axis
    scal: NDArray[np.float64],  # (4,) period s, gravity m/s^2, tan(max tilt), max specific thrust m/s^2
    ctrl: NDArray[np.float64],  # (n, CTRL_COLS) out: desired attitude and specific thrust (C_RDES, C_THRUST)
) -> None:
    """PID position loop with anti-windup: references and state -> desired attitude and thrust."""
    dt, g, max_tilt_tan, max_acc = scal[0], scal[1], scal[2], scal[3]
    R = np.empty((3, 3))
    a = np.empty(3)
    e = np.empty(3)
    for i in range(state.shape[0]):
        _quat_to_R(state, i, R)
        for k in range(3):
            e[k] = state[i, k] - p_ref[i, k]
            a[k] = (
                a_ref[i, k]
                - gains[k, 0] * e[k]
                - gains[k, 1] * (state[i, 7 + k] - v_ref[i, k])
                - gains[k, 2] * integ[i, k]
            )
        fx, fy, fz = a[0], a[1], a[2] + g
        sat_xy = False
        sat_z = False
        if fz < 0.2 * g:
            fz = 0.2 * g
            sat_z = True
        h = math.sqrt(fx * fx + fy * fy)
        hmax = fz * max_tilt_tan
        if h > hmax:
            fx *= hmax / h
            fy *= hmax / h
            sat_xy = True
        norm = math.sqrt(fx * fx + fy * fy + fz * fz)
        if norm > max_acc:
            s = max_acc / norm
            fx *= s
            fy *= s
            fz *= s
            norm = max_acc
            sat_z = True
            sat_xy = True
        # Conditional integration: freeze an axis whose command is saturated, then bound it.
        for k in range(3):
            if (k < 2 and sat_xy) or (k == 2 and sat_z):
                continue
            integ[i, k] += e[k] * dt
            if gains[k, 2] > 0.0:
                lim = int_max[k] / gains[k, 2]
                if integ[i, k] > lim:
                    integ[i, k] = lim
                elif integ[i, k] < -lim:
                    integ[i, k] = -lim
        zx, zy, zz = fx / norm, fy / norm, fz / norm
        cy, sy = math.cos(yaw_ref[i]), math.sin(yaw_ref[i])
        # y_d = z_d x x_c, normalised; x_d = y_d x z_d
        yx = zy * 0.0 - zz * sy
        yy = zz * cy - zx * 0.0
        yz = zx * sy - zy * cy
        yn = math.sqrt(yx * yx + yy * yy + yz * yz)
        yx /= yn
        yy /= yn
        yz /= yn
        xx = yy * zz - yz * zy
        xy = yz * zx - yx * zz
        xz = yx * zy - yy * zx
        ctrl[i, C_RDES + 0], ctrl[i, C_RDES + 3], ctrl[i, C_RDES + 6] = xx, xy, xz
        ctrl[i, C_RDES + 1], ctrl[i, C_RDES + 4], ctrl[i, C_RDES + 7] = yx, yy, yz
        ctrl[i, C_RDES + 2], ctrl[i, C_RDES + 5], ctrl[i, C_RDES + 8] = zx, zy, zz
        t = fx * R[0, 2] + fy * R[1, 2] + fz * R[2, 2]
        ctrl[i, C_THRUST] = t if t > 0.0 else 0.0
        ctrl[i, C_YAWRATE] = yaw_rate_ref[i]


# Column layout of the per-agent controller array ``ctrl`` (n, CTRL_COLS) shared by the kernels;
# ``CascadeController`` exposes named views of it.
C_RDES = 0  # 9: desired attitude, body -> world, row-major
C_THRUST = 9  # 1: commanded specific thrust, m/s^2
C_YAWRATE = 10  # 1: yaw-rate reference, rad/s
C_INTEG = 11  # 3: integral of the attitude error, rad s
C_W = 14  # 4: rotor speeds (motor state), rad/s
C_WCMD = 18  # 4: rotor speed commands, rad/s
C_RATES = 22  # 3: body rates, rad/s
C_MASS = 25  # 1: mass the thrust is computed for (airframe + payload), kg
CTRL_COLS = 26

# Layout of the constant array ``const`` of ``physics_tick``.
K_GAINS = 0  # 9: attitude gains (3, 3) rows roll, pitch, yaw; cols kp [1/s^2], kd [1/s], ki [1/s^3]
K_INTMAX = 9  # 3: bound on |ki * integral| per axis, rad/s^2
K_INERTIA = 12  # 3: kg m^2
K_MIXER = 15  # 16: (4, 4) w^2 -> [T, tau]
K_MIXINV = 31  # 16: (4, 4) [T, tau] -> w^2
K_WMAX = 47  # rad/s
K_ALPHA = 48  # 1 - exp(-dt / tau_motor)
K_DT = 49  # s, physics period
K_DRAG = 50  # N/(m/s), linear drag (0: none)
K_GROUND_R = 51  # m, rotor radius for ground effect (0: none)
K_CLOSED = 52  # 1: run the attitude loop, 0: hold the rotor commands (open loop)
CONST_LEN = 53  # (each agent's mass, airframe + payload, is ctrl[:, C_MASS])


@numba.njit(cache=True)
def physics_tick(
    state: NDArray[np.float64],  # (n, 13) position, quaternion, velocity, angular velocity (world)
    ctrl: NDArray[np.float64],  # (n, CTRL_COLS) controller state, see C_* above (in/out)
    force: NDArray[np.float64],  # (n, 3) out: world force, N
    torque: NDArray[np.float64],  # (n, 3) out: world torque, N m
    status: NDArray[np.int64],  # (n,) out: STATUS_*
    const: NDArray[np.float64],  # (CONST_LEN,) see K_* above
) -> int:
    """Attitude loop, mixer, motor lag and rotor wrench for every agent, one physics step.

    Returns the worst status over agents (0 when every agent is upright and finite).
    """
    gains = const[K_GAINS : K_GAINS + 9].reshape(3, 3)
    int_max = const[K_INTMAX : K_INTMAX + 3]
    mixer = const[K_MIXER : K_MIXER + 16].reshape(4, 4)
    mixer_inv = const[K_MIXINV : K_MIXINV + 16].reshape(4, 4)
    w_max = const[K_WMAX]
    alpha = const[K_ALPHA]
    dt = const[K_DT]
    drag = const[K_DRAG]
    ground_radius = const[K_GROUND_R]
    closed_loop = const[K_CLOSED] > 0.5
    wmax2 = w_max * w_max
    jx, jy, jz = const[K_INERTIA], const[K_INERTIA + 1], const[K_INERTIA + 2]
    w = ctrl[:, C_W : C_W + 4]  # rad/s, motor state
    w_cmd = ctrl[:, C_WCMD : C_WCMD + 4]  # rad/s, motor commands
    worst = 0
    R = np.empty((3, 3))
    for i in range(state.shape[0]):
        bad = False
        for k in range(13):
            if not math.isfinite(state[i, k]):
                bad = True
        for k in range(3):
            if abs(state[i, k]) > 1e4:
                bad = True
        if state[i, 7] ** 2 + state[i, 8] ** 2 + state[i, 9] ** 2 > MAX_SPEED**2:
            bad = True
        if bad:
            status[i] = STATUS_NONFINITE
            worst = STATUS_NONFINITE
            for k in range(3):
                force[i, k] = 0.0
                torque[i, k] = 0.0
            continue
        _quat_to_R(state, i, R)
        if R[2, 2] < 0.0:
            status[i] = STATUS_FLIPPED
            if worst < STATUS_FLIPPED:
                worst = STATUS_FLIPPED
        else:
            status[i] = STATUS_OK
        wx, wy, wz = state[i, 10], state[i, 11], state[i, 12]
        p = R[0, 0] * wx + R[1, 0] * wy + R[2, 0] * wz
        q = R[0, 1] * wx + R[1, 1] * wy + R[2, 1] * wz
        r = R[0, 2] * wx + R[1, 2] * wy + R[2, 2] * wz
        ctrl[i, C_RATES] = p
        ctrl[i, C_RATES + 1] = q
        ctrl[i, C_RATES + 2] = r
        if closed_loop:
            # Attitude error e_R = 1/2 vee(R_d^T R - R^T R_d), from M = R_d^T R.
            m01 = ctrl[i, C_RDES + 0] * R[0, 1] + ctrl[i, C_RDES + 3] * R[1, 1] + ctrl[i, C_RDES + 6] * R[2, 1]
            m02 = ctrl[i, C_RDES + 0] * R[0, 2] + ctrl[i, C_RDES + 3] * R[1, 2] + ctrl[i, C_RDES + 6] * R[2, 2]
            m10 = ctrl[i, C_RDES + 1] * R[0, 0] + ctrl[i, C_RDES + 4] * R[1, 0] + ctrl[i, C_RDES + 7] * R[2, 0]
            m12 = ctrl[i, C_RDES + 1] * R[0, 2] + ctrl[i, C_RDES + 4] * R[1, 2] + ctrl[i, C_RDES + 7] * R[2, 2]
            m20 = ctrl[i, C_RDES + 2] * R[0, 0] + ctrl[i, C_RDES + 5] * R[1, 0] + ctrl[i, C_RDES + 8] * R[2, 0]
            m21 = ctrl[i, C_RDES + 2] * R[0, 1] + ctrl[i, C_RDES + 5] * R[1, 1] + ctrl[i, C_RDES + 8] * R[2, 1]
            e0 = 0.5 * (m21 - m12)
            e1 = 0.5 * (m02 - m20)
            e2 = 0.5 * (m10 - m01)
            a0 = -gains[0, 0] * e0 - gains[0, 1] * p - gains[0, 2] * ctrl[i, C_INTEG]
            a1 = -gains[1, 0] * e1 - gains[1, 1] * q - gains[1, 2] * ctrl[i, C_INTEG + 1]
            a2 = -gains[2, 0] * e2 - gains[2, 1] * (r - ctrl[i, C_YAWRATE]) - gains[2, 2] * ctrl[i, C_INTEG + 2]
            ctrl[i, C_INTEG] += e0 * dt
            ctrl[i, C_INTEG + 1] += e1 * dt
            ctrl[i, C_INTEG + 2] += e2 * dt
            for k in range(3):
                if gains[k, 2] > 0.0:
                    lim = int_max[k] / gains[k, 2]
                    if ctrl[i, C_INTEG + k] > lim:
                        ctrl[i, C_INTEG + k] = lim
                    elif ctrl[i, C_INTEG + k] < -lim:
                        ctrl[i, C_INTEG + k] = -lim
            u0 = ctrl[i, C_MASS] * ctrl[i, C_THRUST]
            u1 = jx * a0 + (jz - jy) * q * r
            u2 = jy * a1 + (jx - jz) * r * p
            u3 = jz * a2 + (jy - jx) * p * q
            # Thrust, roll and pitch first; yaw gets the authority that is left (scale s in [0, 1]).
            s = 1.0
            for k in range(4):
                base = mixer_inv[k, 0] * u0 + mixer_inv[k, 1] * u1 + mixer_inv[k, 2] * u2
                yawp = mixer_inv[k, 3] * u3
                if yawp > 0.0 and base + yawp > wmax2:
                    s = min(s, max((wmax2 - base) / yawp, 0.0))
                elif yawp < 0.0 and base + yawp < 0.0:
                    s = min(s, max(-base / yawp, 0.0))
            for k in range(4):
                v = mixer_inv[k, 0] * u0 + mixer_inv[k, 1] * u1 + mixer_inv[k, 2] * u2 + s * mixer_inv[k, 3] * u3
                if v < 0.0:
                    v = 0.0
                elif v > wmax2:
                    v = wmax2
                ctrl[i, C_WCMD + k] = math.sqrt(v)
        motor_update_row(w, i, w_cmd[i], alpha, w_max)
        thrust = 0.0
        tx = 0.0
        ty = 0.0
        tz = 0.0
        for k in range(4):
            w2 = ctrl[i, C_W + k] * ctrl[i, C_W + k]
            thrust += mixer[0, k] * w2
            tx += mixer[1, k] * w2
            ty += mixer[2, k] * w2
            tz += mixer[3, k] * w2
        if ground_radius > 0.0:
            h = state[i, 2]
            if h < 1e-3:
                h = 1e-3
            ratio = ground_radius / (4.0 * h)
            den = 1.0 - ratio * ratio
            if den < 0.5:
                den = 0.5
            thrust /= den
        for k in range(3):
            force[i, k] = R[k, 2] * thrust - drag * state[i, 7 + k]
            torque[i, k] = R[k, 0] * tx + R[k, 1] * ty + R[k, 2] * tz
    return worst


@numba.njit(cache=True)
def braking_speed(rest: float, am: float, dt: float) -> float:
    """m/s, the largest speed u from which braking by am dt a tick (the last tick by what is left, positions
    integrating the mean of old and new speed) covers at most ``rest`` m beyond u dt / 2 (this tick's share).

    From u = K c + r (c = am dt, 0 <= r < c) braking covers (u^2 - r^2) / (2 am) + r dt / 2, so the condition
    is linear in u on each branch K: u (K + 1) dt - K (K + 1) c dt / 2 <= rest. The continuous bound
    sqrt(h^2 + 2 am rest) - h (h = c / 2) leaves out the last tick's r (c - r) / (2 am) and is never below
    the answer: it picks the branch.
    """
    if rest <= 0.0:
        return 0.0
    c = am * dt
    h = 0.5 * c
    upper = math.sqrt(h * h + 2.0 * am * rest) - h
    k = math.floor(upper / c)
    while True:
        u = (rest + 0.5 * k * (k + 1) * c * dt) / ((k + 1) * dt)
        if u >= k * c or k == 0:
            return u if u < upper else upper
        k -= 1


@numba.njit(cache=True)
def shape_references(
    target: NDArray[np.float64],  # (n, 3) m target position, or m/s target velocity
    velocity_mode: NDArray[np.bool_],  # (n,) True: target is a velocity
    p_ref: NDArray[np.float64],  # (n, 3) m (in/out)
    v_ref: NDArray[np.float64],  # (n, 3) m/s (in/out)
    a_ref: NDArray[np.float64],  # (n, 3) m/s^2 (out)
    v_max: NDArray[np.float64],  # (3,) m/s per axis
    a_max: NDArray[np.float64],  # (3,) m/s^2 per axis
    dt: float,
) -> None:
    """Move references towards targets within per-axis velocity and acceleration limits.

    Position targets follow the discrete braking curve: the speed towards the target after this tick
    is the largest from which braking at a_max, a_max dt per tick, still stops at the target, counting
    the distance this tick covers (positions integrate the mean of the old and new velocity), capped
    at v_max; so each axis arrives without overshoot. (The continuous curve v = sqrt(2 a_max |e|)
    left out this tick's distance and overshot every target by about 3 mm at 0.15 m/s and 48 Hz, of a
    5 mm grasp gap; ``braking_speed``.) Velocity targets are clipped to
    v_max. The reference velocity changes by at most a_max dt per tick.
    """
    for i in range(p_ref.shape[0]):
        for k in range(3):
            vm = v_max[k]
            am = a_max[k]
            if velocity_mode[i]:
                vd = target[i, k]
                if vd > vm:
                    vd = vm
                elif vd < -vm:
                    vd = -vm
            else:
                e = target[i, k] - p_ref[i, k]
                ae = abs(e)
                toward = v_ref[i, k] if e >= 0.0 else -v_ref[i, k]  # m/s, the old speed towards the target
                mag = braking_speed(ae - 0.5 * toward * dt, am, dt)
                if mag > vm:
                    mag = vm
                vd = mag if e >= 0.0 else -mag
            dv = vd - v_ref[i, k]
            lim = am * dt
            if dv > lim:
                dv = lim
            elif dv < -lim:
                dv = -lim
            v_old = v_ref[i, k]
            v_new = v_old + dv
            v_ref[i, k] = v_new
            a_ref[i, k] = dv / dt
            p_ref[i, k] += 0.5 * (v_old + v_new) * dt


@numba.njit(cache=True)
def prefilter_references(
    p_ref: NDArray[np.float64],  # (n, 3) m, shaped position references
    v_ref: NDArray[np.float64],  # (n, 3) m/s, shaped velocity references
    At: NDArray[np.float64],  # (3, m, m) per axis, transposed discrete state matrix (zero-padded)
    B: NDArray[np.float64],  # (3, m)
    C: NDArray[np.float64],  # (3, m)
    D: NDArray[np.float64],  # (3,)
    x_unit: NDArray[np.float64],  # (3, m) steady state for a unit input
    x: NDArray[np.float64],  # (2, n, 3, m) filter states of positions and velocities (in/out)
    primed: bool,  # False: start in steady state at these references
    p_out: NDArray[np.float64],  # (n, 3) m, out
    v_out: NDArray[np.float64],  # (n, 3) m/s, out
) -> None:
    """One tick of the reference prefilter (``CascadeController``) for all agents and axes."""
    m = B.shape[1]
    tmp = np.empty(m)
    for s in range(2):
        u_all = p_ref if s == 0 else v_ref
        out = p_out if s == 0 else v_out
        for i in range(u_all.shape[0]):
            for k in range(3):
                u = u_all[i, k]
                xs = x[s, i, k]
                if not primed:
                    for j in range(m):
                        xs[j] = u * x_unit[k, j]
                y = D[k] * u
                for j in range(m):
                    y += C[k, j] * xs[j]
                out[i, k] = y
                for j in range(m):
                    acc = u * B[k, j]
                    for q in range(m):
                        acc += xs[q] * At[k, q, j]
                    tmp[j] = acc
                for j in range(m):
                    xs[j] = tmp[j]
