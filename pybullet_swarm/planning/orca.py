"""Optimal reciprocal collision avoidance (ORCA) in 3-D: a safety layer between any planner and the controller.

For every sensed neighbour an agent builds one half-space of velocities, the ORCA plane of van
den Berg, Guy, Lin and Manocha, "Reciprocal n-body collision avoidance" (ISRR 2009): ``u`` is the
smallest change of the relative velocity that takes it out of the velocity obstacle (VO)
truncated at the time horizon, and each agent of the pair takes half of it. The new velocity is
the one closest to the preferred velocity inside all ORCA planes and the hard bounds (velocity
limits, see below); when no velocity satisfies every ORCA plane it is the velocity whose worst
violation is smallest and, among those, the closest to the preferred velocity. If every agent
applies it, no pair comes closer than its shapes allow within the horizon, for the kinematic
model the LP assumes.

Solver. The LP is solved exactly with the incremental structure of the RVO2-3D library (Seidel's
algorithm without the shuffle): planes are added one at a time and the optimum moves only when
a new plane cuts it off; then a 2-D problem on that plane (and inside it 1-D problems on the
intersection lines) gives the new optimum. The infeasible case is the 4-D problem "minimise the
largest violation", solved the same way on bisector planes. All agents are solved in one
compiled (numba) call per planner tick; neighbours come from a k-d tree.

Agent shapes (``shape``):

* ``box`` (default): an agent is the world-axis bounding box of its airframe at its sensed
  attitude, with the box it carries (hanging ``grasp_height`` below) when it carries one. The VO
  of two boxes is computed exactly: it is the set of relative velocities v with ``t v`` inside
  their Minkowski box for some ``t <= tau``; eliminating t (Fourier-Motzkin) leaves at most a
  dozen linear inequalities. Inside the VO, u leads to the nearest of their planes; outside, to
  the VO's nearest point (the polytope's point closest to v, by the same incremental LP). Boxes
  matter here: the construction task grasps and places side by side at a 20 cm pitch, which
  15 cm airframes clear by 5 cm but no sphere around a 15 cm square (radius 10.6 cm) allows.
* ``sphere``: the classic model, radius = the airframe's enclosing radius (the sphere around
  airframe and hanging box when carrying); the VO is RVO2-3D's truncated cone.

Design decisions (numbers are ``OrcaParams`` defaults):

* Hard bounds. The per-axis velocity limits are six half-spaces that come first and are never
  traded away by the least-violation fallback; the speed sphere (radius |v_max|) only bounds the
  problem, so the reference shaper, which clips each axis, receives exactly the velocity the LP
  certified. ORCA knows neither the ground nor boxes and structure, so two more rules are hard
  bounds (``velocity_bounds``): below ``floor_height`` avoidance never pushes an agent down, and
  an agent low down on a vertical leg to or from its target (within ``column_radius``
  horizontally: grasping, placing, climbing away) is never moved sideways, only slowed or lifted:
  a sideways dodge there tilts the airframe into the box under it.
* Margins. Each shape grows by ``safety_margin`` (1.5 cm: two airframes side by side at the 20 cm
  pitch keep 2 cm of slack), and a pair's Minkowski box by ``lag_margin_s`` times their closing
  speed on each axis: the cascade takes about 0.3 s to follow a new velocity and overshoots it by
  up to 100 % (measured: a 0.15 m/s step peaks at 0.24 m/s, a reversal at 0.32 m/s), which the
  one-step kinematic model of ORCA does not know about. Flying on estimates, shapes also grow
  by ``uncertainty_sigmas`` standard deviations of a pair's relative position error.
* Reference velocity (``v_opt``): the sensed velocity of every agent, clipped to the limits
  (the overshoots above are not motion to answer). Each pair's (n, u) is computed once in index
  order and negated for the other agent, so both halves match to the last bit, from sensed state
  only: no agent reads another's command.
* Minimal intervention. An agent whose command would not violate any of its planes (the
  velocity its command gives it through the shaper, ``commanded_velocities``) keeps its command
  unchanged: with nobody near, the layer is invisible. Otherwise it gets a VELOCITY command, the
  LP's velocity closest to the preferred velocity: ``(target - p) / arrive_time`` per axis,
  clipped to the limit, for a POSITION command (a smooth approach that slows down on arrival),
  the command itself for VELOCITY, zero for HOLD.
* Exact position control near the target (passthrough). Grasp and release need millimetres: a
  POSITION (or HOLD) command within ``capture_radius`` of the agent passes unchanged when the box
  the agent sweeps on its way there stays ``clearance_margin`` clear of every neighbour's box
  swept along that neighbour's velocity for ``clearance_lookahead``.
* Overlap. Shapes that already overlap (margins included: a dense start grid, lag) open the gap
  along the axis of least overlap over ``recovery_time``, so the demand stays within the limits
  (unweighted: an agent just above a climbing neighbour is lifted, not sent sideways while it
  sinks into it).
* Choice of the way out. Vertical changes count ``vertical_cost`` times horizontal ones when the
  nearest way out of a box VO is chosen (any choice is safe; this one is symmetric). The default
  0.75 favours passing over: a 2 cm thin airframe clears a neighbour vertically a few cm above
  its top, where a sideways dodge needs the width of two airframes (measured on
  ``construction.yaml``, stigmergy, seeds 0..49: median completion 128.6 s with 3.0 and no
  climbing over, 117.7 s with both, no contact either way). The simulator models no downwash;
  a study of airframes that suffer from it raises ``vertical_cost`` (or ``safety_margin``).
* Climbing over (``climb_over``). Near the ground nobody is pushed down (hard bounds above), so a
  reciprocal half of a vertical way out could not be taken by the lower agent: its plane would
  contradict its bound, and the pair would not separate. So when a pair is on a collision course
  (inside its VO), the way out is within 45 deg of vertical and the lower agent is in level
  flight (climbing or sinking slower than 2 cm/s), the upper agent takes the pair's whole share
  and the lower one keeps its velocity: an empty agent hops over a carrier and its hanging box,
  which flies on undisturbed. Both agents see the same sensed numbers, so the shares still add
  up. A stalled agent (see Deadlocks) higher than the one in its way climbs past it rather than
  stepping sideways. A lower agent that is climbing or descending (lifting a box, descending to
  a slot) keeps the reciprocal half: its vertical leg is not frozen under a neighbour.
* Deadlocks. A symmetric head-on (relative velocity exactly on the line of centres) has no
  defined sphere-VO normal; it is taken to the right (``d x z``, or ``d x x`` for a vertical line),
  antisymmetric, so both keep right. An agent stalled (progress below ``stuck_fraction`` of its
  preferred speed) by a neighbour ahead that does not sit on its goal adds ``right_bias`` times
  its preferred speed sideways and solves again: to the right, so that a crowd turns into a
  roundabout, except when the neighbour is nearly straight ahead but already a little to one
  side, then to the side it leaves free (``_sidestep``); both agents see mirrored numbers and
  pass each other. When the biased velocity is still held (the bias can exactly cancel the
  preferred velocity along the one axis a box VO leaves free), the agent asks for the sideways
  step alone. A neighbour sitting on the goal itself is waited for (circling it would not
  help), except by an agent descending straight onto it: the one below can only leave upwards,
  through the waiting agent, so that one makes way straight up (two agents on vertical legs
  over a slot may not move sideways).

Public pieces: ``orca_plane`` (one half-space), ``solve_velocity`` (one LP), ``orca_velocities``
(all agents, plain arrays), ``OrcaLayer`` (the ``--avoidance orca`` layer).
"""

from __future__ import annotations

import enum
import math
import time
from typing import Any, ClassVar

import numba
import numpy as np
from numpy.typing import NDArray
from pydantic import Field
from scipy.spatial import cKDTree

from pybullet_swarm.planning.base import AvoidanceSetup, Command, CommandKind, TaskView
from pybullet_swarm.planning.params import Params
from pybullet_swarm.types import Perception

#: flags returned per agent by ``orca_velocities``
FLAG_INFEASIBLE = 1  # the ORCA planes had no common velocity: least-violating velocity used
FLAG_BIASED = 2  # stalled by a neighbour ahead: the sideways bias was applied
FLAG_FREE = 4  # the commanded velocity satisfies every plane: nothing was changed
FLAG_CLIMB = 8  # took a pair's whole share of a vertical way out (climbing over, see below)

_EPS = 1e-14  # squared length below which two unit normals count as parallel
_TOL = 1e-12  # m/s, a velocity this far outside a plane still satisfies it

# indices of the scalar settings passed to the kernels in one array
_C_MARGIN, _C_LAG, _C_INV_TAU, _C_INV_REC, _C_RESP, _C_WZ, _C_MAX_SPEED, _C_TAU, _C_BIAS, _C_STUCK, _C_CLIMB = range(11)

_VERTICAL_COS2 = 0.5  # squared cosine: a direction (a way out, a descent) within 45 deg of vertical counts as vertical
_LEVEL = 0.02  # m/s, an agent climbing or sinking slower than this is in level flight


class Shape(enum.Enum):
    """How agents are modelled for avoidance."""

    BOX = "box"  # attitude-aware bounding boxes of airframe and load (exact VO of boxes)
    SPHERE = "sphere"  # enclosing spheres (the classic ORCA model)


# ----------------------------------------------------------------------------- vector helpers
@numba.njit(cache=True)
def _dot(a: tuple[float, float, float], b: tuple[float, float, float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@numba.njit(cache=True)
def _cross(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@numba.njit(cache=True)
def _add(a: tuple[float, float, float], b: tuple[float, float, float], s: float) -> tuple[float, float, float]:
    """a + s b."""
    return (a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2])


@numba.njit(cache=True)
def _scale(a: tuple[float, float, float], s: float) -> tuple[float, float, float]:
    return (a[0] * s, a[1] * s, a[2] * s)


@numba.njit(cache=True)
def _row(A: NDArray[np.float64], i: int) -> tuple[float, float, float]:
    return (A[i, 0], A[i, 1], A[i, 2])


@numba.njit(cache=True)
def _set_row(A: NDArray[np.float64], i: int, a: tuple[float, float, float]) -> None:
    A[i, 0] = a[0]
    A[i, 1] = a[1]
    A[i, 2] = a[2]


@numba.njit(cache=True)
def _axis(k: int, s: float) -> tuple[float, float, float]:
    """s times the unit vector of axis k."""
    if k == 0:
        return (s, 0.0, 0.0)
    if k == 1:
        return (0.0, s, 0.0)
    return (0.0, 0.0, s)


@numba.njit(cache=True)
def _right_of(d: tuple[float, float, float]) -> tuple[float, float, float]:
    """Unit vector to the right of unit direction ``d`` (z up): ``d x z``, or ``d x x`` when d is vertical.

    Antisymmetric (``right(-d) = -right(d)``), so two agents facing each other pick opposite sides.
    """
    c = _cross(d, (0.0, 0.0, 1.0))
    n2 = _dot(c, c)
    if n2 < 1e-6:
        c = _cross(d, (1.0, 0.0, 0.0))
        n2 = _dot(c, c)
    return _scale(c, 1.0 / math.sqrt(n2))


# ----------------------------------------------------------------------------- velocity obstacles
@numba.njit(cache=True)
def _sphere_u(
    p: tuple[float, float, float], v: tuple[float, float, float], R: float, inv_tau: float, inv_rec: float
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Outward normal n and change u of relative velocity ``v`` for two spheres (combined radius R m).

    ``p`` m is the second agent's position relative to the first, ``v`` m/s the first's velocity
    relative to the second's.
    """
    d2 = _dot(p, p)
    R2 = R * R
    if d2 > R2:
        w = _add(v, p, -inv_tau)  # from the centre of the cut-off sphere to v
        w2 = _dot(w, w)
        wp = _dot(w, p)
        if wp < 0.0 and wp * wp > R2 * w2:
            # closest to the cut-off sphere (radius R / tau around p / tau)
            wl = math.sqrt(w2)
            n = _scale(w, 1.0 / wl)
            return n, _scale(n, R * inv_tau - wl)
        # closest to the cone's side: in the plane of p and v, the side ray at angle asin(R / d)
        # from p; n = (-R p/d + leg e) / d with e the unit part of v perpendicular to p, and the
        # signed distance of v from that side is (R b - leg |p x v|) / d^2 with b = p . v
        d = math.sqrt(d2)
        ph = _scale(p, 1.0 / d)
        b = _dot(p, v)
        cr = _cross(p, v)
        crn = math.sqrt(_dot(cr, cr))
        leg = math.sqrt(d2 - R2)
        vv = math.sqrt(_dot(v, v))
        if crn > 1e-12 * d * vv and crn > 1e-300:
            e = _scale(_add(v, p, -b / d2), d / crn)
        else:  # v on the line of centres: keep right
            e = _right_of(ph)
        n = _add(_scale(ph, -R / d), e, leg / d)
        return n, _scale(n, (R * b - leg * crn) / d2)
    # already overlapping: separate over the recovery time
    w = _add(v, p, -inv_rec)
    wl = math.sqrt(_dot(w, w))
    if wl > 1e-12:
        n = _scale(w, 1.0 / wl)
    elif d2 > 1e-24:
        n = _scale(p, -1.0 / math.sqrt(d2))
    else:
        n = (-1.0, 0.0, 0.0)
    return n, _scale(n, R * inv_rec - wl)


@numba.njit(cache=True)
def _box_u(
    c: tuple[float, float, float],
    H: tuple[float, float, float],
    v: tuple[float, float, float],
    inv_tau: float,
    inv_rec: float,
    wz: float,
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Outward normal n and change u of relative velocity ``v`` for two axis-aligned boxes.

    ``c`` m is the centre of the second box relative to the first, ``H`` m the half extents of
    their Minkowski sum, ``v`` m/s the first's velocity relative to the second's.

    The VO is {v : t v in B for some 0 < t <= tau}, B = [c - H, c + H]. With s = 1 / t it reads
    "some s >= 1/tau satisfies s (c_k - H_k) <= v_k <= s (c_k + H_k) for every axis k": each row
    ``a s <= g . v + h`` bounds s from above (a > 0) or below (a < 0), and s exists iff every lower
    bound is below every upper bound. Each (lower, upper) pair is one linear inequality
    F(v) = n . v + d >= 0; the VO is their intersection, and the outer side of each of these planes
    is free of the VO. Inside the VO, u leads to the plane nearest v, measured with vertical
    changes costing ``wz`` times horizontal ones; outside, to the VO's nearest point.
    """
    pen = -1e300
    k_pen = 0
    cost = 1e300
    for k in range(3):
        g = abs(c[k]) - H[k]
        pen = max(pen, g)
        # separation still needed along k; not weighted: when two shapes overlap only a little
        # vertically (one just above the other) a sideways way out leaves them free to close
        # vertically, so the least overlap wins whatever its axis
        ck = -g
        if ck < cost:
            cost = ck
            k_pen = k
    if pen <= 0.0:
        # overlapping now: open the gap along the axis of least overlap over the recovery time
        s = _axis(k_pen, 1.0 if c[k_pen] >= 0.0 else -1.0)
        gap = abs(c[k_pen]) - H[k_pen]
        return _scale(s, -1.0), _scale(s, gap * inv_rec - _dot(v, s))
    # rows a s <= g . v + h: lower and upper faces of each axis, then s >= 1/tau
    ra = np.empty(7)
    rg = np.zeros((7, 3))
    rh = np.zeros(7)
    for k in range(3):
        ra[2 * k] = c[k] - H[k]  # s (c - H) <= v_k
        rg[2 * k, k] = 1.0
        ra[2 * k + 1] = -(c[k] + H[k])  # -s (c + H) <= -v_k
        rg[2 * k + 1, k] = -1.0
    ra[6] = -1.0  # -s <= -1/tau
    rh[6] = -inv_tau
    best = 1e300
    best_f = 0.0
    bn = (0.0, 0.0, 0.0)
    iw = 1.0 / wz
    FN = np.empty((24, 3))  # the VO's planes, for the projection of an outside v
    FP = np.empty((24, 3))
    nf = 0
    for p in range(7):
        if ra[p] > 0.0:
            continue
        gp = _row(rg, p)
        for q in range(-1, 7):
            if q < 0:
                if ra[p] != 0.0:
                    continue
                n = gp  # a row without s: g . v + h >= 0 itself
                f = _dot(gp, v) + rh[p]
            else:
                if ra[q] <= 0.0 or ra[p] == 0.0:
                    continue
                # lower bound (g_p . v + h_p) / a_p <= upper bound (g_q . v + h_q) / a_q
                n = _add(_scale(gp, ra[q]), _row(rg, q), -ra[p])
                f = _dot(n, v) + ra[q] * rh[p] - ra[p] * rh[q]
            nn = math.sqrt(_dot(n, n))
            nw = math.sqrt(n[0] * n[0] + n[1] * n[1] + (n[2] * iw) ** 2)
            if nw < 1e-12:
                continue
            _set_row(FN, nf, _scale(n, 1.0 / nn))
            _set_row(FP, nf, _add(v, n, -f / (nn * nn)))  # the point of the plane nearest v
            nf += 1
            if f / nw < best:
                best = f / nw
                best_f = f / nn
                bn = _scale(n, 1.0 / nn)
    out = _scale(bn, -1.0)  # outward: the direction in which F decreases
    if best_f < 0.0:
        # outside: the point of the VO polytope closest to v, by the incremental LP
        fail, w = _lp3(FN, FP, nf, 1e3, v, False)
        if fail >= nf:
            u = _add(w, v, -1.0)
            ul = math.sqrt(_dot(u, u))
            if ul > 1e-12:
                return _scale(u, -1.0 / ul), u
    return out, _scale(out, best_f)


@numba.njit(cache=True)
def _pair_u(
    a: int,
    b: int,
    pos: NDArray[np.float64],
    vel: NDArray[np.float64],
    radius: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    boxes: bool,
    cfg: NDArray[np.float64],
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(n, u) of agent a against agent b; agent b uses (-n, -u)."""
    v = _add(_row(vel, a), _row(vel, b), -1.0)
    m2, lag = 2.0 * cfg[_C_MARGIN], cfg[_C_LAG]
    if boxes:
        c = _add(_add(_row(pos, b), _row(centre, b), 1.0), _add(_row(pos, a), _row(centre, a), 1.0), -1.0)
        H = (
            half[a, 0] + half[b, 0] + m2 + lag * abs(v[0]),
            half[a, 1] + half[b, 1] + m2 + lag * abs(v[1]),
            half[a, 2] + half[b, 2] + m2 + lag * abs(v[2]),
        )
        return _box_u(c, H, v, cfg[_C_INV_TAU], cfg[_C_INV_REC], cfg[_C_WZ])
    p = _add(_row(pos, b), _row(pos, a), -1.0)
    R = radius[a] + radius[b] + m2 + lag * math.sqrt(_dot(v, v))
    return _sphere_u(p, v, R, cfg[_C_INV_TAU], cfg[_C_INV_REC])


# ----------------------------------------------------------------------------- incremental LP
@numba.njit(cache=True)
def _lp1(
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    count: int,
    d: tuple[float, float, float],
    q: tuple[float, float, float],
    radius: float,
    opt: tuple[float, float, float],
    dir_opt: bool,
) -> tuple[bool, tuple[float, float, float]]:
    """Best point on the line q + t d within the sphere and planes [0, count)."""
    dq = _dot(q, d)
    disc = dq * dq + radius * radius - _dot(q, q)
    if disc < 0.0:
        return False, q
    s = math.sqrt(disc)
    t_lo = -dq - s
    t_hi = -dq + s
    for i in range(count):
        n = _row(N, i)
        num = _dot(_add(_row(P, i), q, -1.0), n)
        den = _dot(d, n)
        if den * den <= _EPS:  # line parallel to plane i: all in or all out
            if num > _TOL:
                return False, q
            continue
        t = num / den
        if den > 0.0:
            t_lo = max(t_lo, t)
        else:
            t_hi = min(t_hi, t)
        if t_lo > t_hi:
            return False, q
    if dir_opt:
        t = t_hi if _dot(opt, d) > 0.0 else t_lo
    else:
        t = min(max(_dot(d, _add(opt, q, -1.0)), t_lo), t_hi)
    return True, _add(q, d, t)


@numba.njit(cache=True)
def _lp2(
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    k: int,
    radius: float,
    opt: tuple[float, float, float],
    dir_opt: bool,
) -> tuple[bool, tuple[float, float, float]]:
    """Best point on plane k within the sphere and planes [0, k)."""
    n = _row(N, k)
    pk = _row(P, k)
    dist = _dot(pk, n)
    r2 = radius * radius
    if dist * dist > r2:
        return False, opt
    disc_r2 = r2 - dist * dist  # squared radius of the sphere's section by the plane
    centre = _scale(n, dist)
    if dir_opt:
        proj = _add(opt, n, -_dot(opt, n))
        p2 = _dot(proj, proj)
        res = centre if p2 <= _EPS else _add(centre, proj, math.sqrt(disc_r2 / p2))
    else:
        res = _add(opt, n, _dot(_add(pk, opt, -1.0), n))
        if _dot(res, res) > r2:
            off = _add(res, centre, -1.0)
            res = _add(centre, off, math.sqrt(disc_r2 / _dot(off, off)))
    for i in range(k):
        ni = _row(N, i)
        pi = _row(P, i)
        if _dot(ni, _add(pi, res, -1.0)) > _TOL:
            cr = _cross(ni, n)
            c2 = _dot(cr, cr)
            if c2 <= _EPS:  # parallel and plane i excludes plane k entirely
                return False, res
            d = _scale(cr, 1.0 / math.sqrt(c2))
            ln = _cross(d, n)  # in plane k, perpendicular to the intersection line
            q = _add(pk, ln, _dot(_add(pi, pk, -1.0), ni) / _dot(ln, ni))
            ok, res = _lp1(N, P, i, d, q, radius, opt, dir_opt)
            if not ok:
                return False, res
    return True, res


@numba.njit(cache=True)
def _lp3(
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    m: int,
    radius: float,
    opt: tuple[float, float, float],
    dir_opt: bool,
) -> tuple[int, tuple[float, float, float]]:
    """Velocity closest to ``opt`` (or farthest along unit ``opt`` with ``dir_opt``) in the sphere and planes [0, m).

    Returns (index of the first plane that made the problem infeasible or m, velocity).
    """
    if dir_opt:
        res = _scale(opt, radius)
    elif _dot(opt, opt) > radius * radius:
        res = _scale(opt, radius / math.sqrt(_dot(opt, opt)))
    else:
        res = opt
    for i in range(m):
        if _dot(_row(N, i), _add(_row(P, i), res, -1.0)) > _TOL:
            ok, new = _lp2(N, P, i, radius, opt, dir_opt)
            if not ok:
                return i, res
            res = new
    return m, res


@numba.njit(cache=True)
def _lp4(
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    m: int,
    begin: int,
    n_hard: int,
    radius: float,
    res: tuple[float, float, float],
    SN: NDArray[np.float64],
    SP: NDArray[np.float64],
) -> tuple[float, float, float]:
    """Velocity minimising the largest violation of the soft planes [n_hard, m), keeping the hard ones.

    For each plane i that is violated more than the current worst, the 3-D problem "go as far as
    possible along i's normal while no earlier plane is violated more than i" is solved on the
    bisector planes of i and each earlier soft plane (hard planes are kept as they are).
    """
    worst = 0.0
    for i in range(begin, m):
        ni = _row(N, i)
        pi = _row(P, i)
        if _dot(ni, _add(pi, res, -1.0)) > worst:
            k = 0
            for j in range(i):
                nj = _row(N, j)
                pj = _row(P, j)
                if j < n_hard:
                    _set_row(SN, k, nj)
                    _set_row(SP, k, pj)
                    k += 1
                    continue
                cr = _cross(nj, ni)
                if _dot(cr, cr) <= _EPS:
                    if _dot(ni, nj) > 0.0:  # same direction: never the worse of the two
                        continue
                    pt = _scale(_add(pi, pj, 1.0), 0.5)
                else:
                    ln = _cross(cr, ni)
                    pt = _add(pi, ln, _dot(_add(pj, pi, -1.0), nj) / _dot(ln, nj))
                nn = _add(nj, ni, -1.0)
                _set_row(SN, k, _scale(nn, 1.0 / math.sqrt(_dot(nn, nn))))
                _set_row(SP, k, pt)
                k += 1
            fail, new = _lp3(SN, SP, k, radius, ni, True)
            if fail >= k:  # (failure "should not happen"; keep the previous velocity)
                res = new
            worst = _dot(ni, _add(pi, res, -1.0))
    return res


@numba.njit(cache=True)
def _solve(
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    m: int,
    n_hard: int,
    radius: float,
    pref: tuple[float, float, float],
    SN: NDArray[np.float64],
    SP: NDArray[np.float64],
) -> tuple[bool, tuple[float, float, float]]:
    """Solve one agent's LP; returns (feasible, velocity)."""
    fail, res = _lp3(N, P, m, radius, pref, False)
    if fail >= m:
        return True, res
    res = _lp4(N, P, m, fail, n_hard, radius, res, SN, SP)
    # among the least-violating velocities, the one closest to the preferred velocity:
    # shift the soft planes by the smallest achievable violation and solve the LP again
    worst = 0.0
    for i in range(n_hard, m):
        worst = max(worst, _dot(_row(N, i), _add(_row(P, i), res, -1.0)))
    for i in range(m):
        ni = _row(N, i)
        _set_row(SN, i, ni)
        _set_row(SP, i, _add(_row(P, i), ni, -(worst + 1e-9) if i >= n_hard else 0.0))
    fail2, res2 = _lp3(SN, SP, m, radius, pref, False)
    if fail2 >= m:
        res = res2
    return False, res


@numba.njit(cache=True)
def _bound_planes(
    lo: NDArray[np.float64], hi: NDArray[np.float64], i: int, N: NDArray[np.float64], P: NDArray[np.float64]
) -> int:
    """Write the half-spaces lo[i, k] <= v_k <= hi[i, k] (finite ones) into N, P; returns their count."""
    k = 0
    for a in range(3):
        if math.isfinite(hi[i, a]):
            _set_row(N, k, _axis(a, -1.0))
            _set_row(P, k, _axis(a, hi[i, a]))
            k += 1
        if math.isfinite(lo[i, a]):
            _set_row(N, k, _axis(a, 1.0))
            _set_row(P, k, _axis(a, lo[i, a]))
            k += 1
    return k


@numba.njit(cache=True)
def _agent_planes(
    i: int,
    pos: NDArray[np.float64],
    vel: NDArray[np.float64],
    radius: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    boxes: bool,
    nbr: NDArray[np.int64],
    cfg: NDArray[np.float64],
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    k: int,
) -> tuple[int, bool]:
    """Append agent i's ORCA planes (one per neighbour in row i of ``nbr``) after row k; returns the new
    count and whether agent i climbs over a neighbour (takes a pair's whole share).

    A pair's (n, u) is computed once in index order and negated for the other agent, so both
    halves match to the last bit.
    """
    n = pos.shape[0]
    vi = _row(vel, i)
    resp = cfg[_C_RESP]
    climb = cfg[_C_CLIMB] > 0.0
    climbs = False
    for c in range(nbr.shape[1]):
        j = nbr[i, c]
        if j < 0 or j >= n or j == i:
            continue
        if i < j:
            nrm, u = _pair_u(i, j, pos, vel, radius, centre, half, boxes, cfg)
        else:
            nrm, u = _pair_u(j, i, pos, vel, radius, centre, half, boxes, cfg)
            nrm = _scale(nrm, -1.0)
            u = _scale(u, -1.0)
        r = resp
        if climb and _dot(nrm, u) > 0.0 and nrm[2] * nrm[2] > _VERTICAL_COS2 * _dot(nrm, nrm):
            # on a collision course, the way out vertical, the lower agent in level flight: the upper
            # one takes the pair's whole share (nobody low down is pushed down, see ``velocity_bounds``)
            if abs(vel[j if nrm[2] > 0.0 else i, 2]) <= _LEVEL:
                r = 2.0 * resp if nrm[2] > 0.0 else 0.0
                climbs = climbs or nrm[2] > 0.0
        _set_row(N, k, nrm)
        _set_row(P, k, _add(vi, u, r))
        k += 1
    return k, climbs


@numba.njit(cache=True)
def _overlap(
    pa: tuple[float, float, float],
    pb: tuple[float, float, float],
    ra: float,
    rb: float,
    ca: tuple[float, float, float],
    cb: tuple[float, float, float],
    ha: tuple[float, float, float],
    hb: tuple[float, float, float],
    boxes: bool,
    grow: float,
) -> bool:
    """True when shape a at pa and shape b at pb come closer than ``grow`` m."""
    if boxes:
        for k in range(3):
            if abs((pb[k] + cb[k]) - (pa[k] + ca[k])) >= ha[k] + hb[k] + grow:
                return False
        return True
    d = _add(pb, pa, -1.0)
    return _dot(d, d) < (ra + rb + grow) ** 2


@numba.njit(cache=True)
def _stalled_by(
    i: int,
    pos: NDArray[np.float64],
    pref: tuple[float, float, float],
    sp: float,
    radius: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    boxes: bool,
    nbr: NDArray[np.int64],
    goal: NDArray[np.float64],
    has_goal: bool,
    cfg: NDArray[np.float64],
) -> tuple[int, bool]:
    """The nearest neighbour ahead (reachable over the horizon) that is in the way and does not sit
    on the goal, or -1; and True instead when, descending straight down, the agent first meets a
    neighbour below that sits on its goal: that one can only leave upwards, through this agent."""
    n = pos.shape[0]
    pi = _row(pos, i)
    dh = _scale(pref, 1.0 / sp)
    m2 = 2.0 * cfg[_C_MARGIN]
    for c in range(nbr.shape[1]):  # nearest first
        j = nbr[i, c]
        if j < 0 or j >= n or j == i:
            continue
        rel = _add(_row(pos, j), pi, -1.0)
        if _dot(rel, dh) <= 0.0:
            continue
        pj = _row(pos, j)
        if not _overlap(
            pi,
            pj,
            radius[i],
            radius[j],
            _row(centre, i),
            _row(centre, j),
            _row(half, i),
            _row(half, j),
            boxes,
            m2 + sp * cfg[_C_TAU],
        ):
            continue
        if has_goal and _overlap(
            _row(goal, i),
            pj,
            radius[i],
            radius[j],
            _row(centre, i),
            _row(centre, j),
            _row(half, i),
            _row(half, j),
            boxes,
            m2,
        ):
            if dh[2] < 0.0 and dh[2] * dh[2] > _VERTICAL_COS2 and rel[2] < 0.0:
                return -1, True  # over the goal's occupant: make way upwards
            continue  # the neighbour occupies the goal: wait, do not circle it
        return j, False
    return -1, False


@numba.njit(cache=True)
def _sidestep(d: tuple[float, float, float], rel: tuple[float, float, float]) -> tuple[float, float, float]:
    """Horizontal unit direction across unit direction ``d``, to pass a neighbour at ``rel``.

    To the right (``_right_of``): when everyone keeps right, a crowd turns into a roundabout. The
    exception is a neighbour nearly straight ahead (within 30 deg) but already a little to one
    side (more than 1 cm): then the side it leaves free, rather than crossing in front of it.
    Both agents of a pair see mirrored numbers and so pick opposite sides.
    """
    h2 = d[0] * d[0] + d[1] * d[1]
    if h2 > 1e-6:  # across the horizontal direction of travel
        hl = math.sqrt(h2)
        across = (-d[1] / hl, d[0] / hl, 0.0)  # left of d
        side = _dot(rel, across)
        rh = math.sqrt(rel[0] * rel[0] + rel[1] * rel[1])
        if 0.01 < abs(side) < 0.5 * rh:
            return _scale(across, -1.0 if side > 0.0 else 1.0)
        return _right_of(d)
    r2 = rel[0] * rel[0] + rel[1] * rel[1]  # vertical travel: horizontally away
    if r2 > 1e-4:
        rl = math.sqrt(r2)
        return (-rel[0] / rl, -rel[1] / rl, 0.0)
    return _right_of(d)


@numba.njit(cache=True)
def _orca_batch(
    pos: NDArray[np.float64],
    vel: NDArray[np.float64],
    pref: NDArray[np.float64],
    v_cmd: NDArray[np.float64],
    radius: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    boxes: bool,
    nbr: NDArray[np.int64],
    goal: NDArray[np.float64],
    has_goal: NDArray[np.bool_],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    cfg: NDArray[np.float64],
    out: NDArray[np.float64],
    flags: NDArray[np.int64],
) -> None:
    """Safe velocities of all agents (see ``orca_velocities``)."""
    n = pos.shape[0]
    m_max = nbr.shape[1] + 6
    N = np.empty((m_max, 3))
    P = np.empty((m_max, 3))
    SN = np.empty((m_max, 3))
    SP = np.empty((m_max, 3))
    max_speed, right_bias, stuck = cfg[_C_MAX_SPEED], cfg[_C_BIAS], cfg[_C_STUCK]
    climb_past = cfg[_C_CLIMB] > 0.0
    for i in range(n):
        n_hard = _bound_planes(lo, hi, i, N, P)
        m, climbs = _agent_planes(i, pos, vel, radius, centre, half, boxes, nbr, cfg, N, P, n_hard)
        up = FLAG_CLIMB if climbs else 0
        vc = _row(v_cmd, i)
        free = _dot(vc, vc) <= max_speed * max_speed
        for k in range(m):
            if _dot(_row(N, k), _add(_row(P, k), vc, -1.0)) > _TOL:
                free = False
                break
        if free:  # nothing to avoid: the planner's command stands
            _set_row(out, i, vc)
            flags[i] = FLAG_FREE | up
            continue
        pr = _row(pref, i)
        feasible, res = _solve(N, P, m, n_hard, max_speed, pr, SN, SP)
        f = 0 if feasible else FLAG_INFEASIBLE
        sp = math.sqrt(_dot(pr, pr))
        if right_bias > 0.0 and sp > 1e-3 and _dot(res, pr) < stuck * sp * sp:
            j, make_way = _stalled_by(i, pos, pr, sp, radius, centre, half, boxes, nbr, goal, has_goal[i], cfg)
            if make_way:
                feasible, res = _solve(N, P, m, n_hard, max_speed, (0.0, 0.0, sp), SN, SP)
                f = FLAG_BIASED | (0 if feasible else FLAG_INFEASIBLE)
            elif j >= 0:
                if climb_past and pos[i, 2] > pos[j, 2]:
                    side = (0.0, 0.0, 1.0)  # above the one in the way: over it
                else:
                    side = _sidestep(_scale(pr, 1.0 / sp), _add(_row(pos, j), _row(pos, i), -1.0))
                feasible, res = _solve(N, P, m, n_hard, max_speed, _add(pr, side, right_bias * sp), SN, SP)
                if _dot(res, res) < stuck * stuck * sp * sp:
                    # still held: the bias cancelled what the neighbours' planes left free (a box VO
                    # leaves the axis across the blocking face free; the bias can exactly cancel the
                    # preferred velocity along it): ask for the sideways step alone
                    feasible, res = _solve(N, P, m, n_hard, max_speed, _scale(side, sp), SN, SP)
                f = FLAG_BIASED | (0 if feasible else FLAG_INFEASIBLE)
        _set_row(out, i, res)
        flags[i] = f | up


@numba.njit(cache=True)
def _clear_paths(
    pos: NDArray[np.float64],
    goal: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    vel: NDArray[np.float64],
    nbr: NDArray[np.int64],
    candidate: NDArray[np.bool_],
    margin: float,
    lookahead: float,
    out: NDArray[np.bool_],
) -> None:
    """For each candidate, True when the box it sweeps to its goal stays ``margin`` clear of every
    neighbour's box swept along the neighbour's velocity over ``lookahead`` s."""
    n = pos.shape[0]
    for i in range(n):
        out[i] = False
        if not candidate[i]:
            continue
        ok = True
        for c in range(nbr.shape[1]):
            j = nbr[i, c]
            if j < 0 or j >= n or j == i:
                continue
            apart = False
            for a in range(3):
                lo_i = min(pos[i, a], goal[i, a]) + centre[i, a] - half[i, a]
                hi_i = max(pos[i, a], goal[i, a]) + centre[i, a] + half[i, a]
                ahead = vel[j, a] * lookahead
                lo_j = pos[j, a] + centre[j, a] - half[j, a] - margin + min(ahead, 0.0)
                hi_j = pos[j, a] + centre[j, a] + half[j, a] + margin + max(ahead, 0.0)
                if hi_i <= lo_j or hi_j <= lo_i:
                    apart = True
                    break
            if not apart:
                ok = False
                break
        out[i] = ok


# ----------------------------------------------------------------------------- array API
def _vec3(a: Any) -> tuple[float, float, float]:
    v = np.asarray(a, dtype=float).reshape(3)
    return (float(v[0]), float(v[1]), float(v[2]))


def _limits(v_max: NDArray[np.float64] | None) -> NDArray[np.float64]:
    if v_max is None:
        return np.full(3, np.inf)
    return np.broadcast_to(np.asarray(v_max, dtype=float), (3,)).copy()


def _sphere_radius(vm: NDArray[np.float64], max_speed: float | None) -> float:
    if max_speed is not None:
        return float(max_speed)
    if np.all(np.isfinite(vm)):
        return float(np.linalg.norm(vm)) * (1.0 + 1e-9)
    return 1.0


def orca_plane(
    rel_position: NDArray[np.float64],
    rel_velocity: NDArray[np.float64],
    velocity: NDArray[np.float64],
    *,
    time_horizon: float,
    recovery_time: float,
    combined_radius: float | None = None,
    half_extents: NDArray[np.float64] | None = None,
    vertical_cost: float = 1.0,
    responsibility: float = 0.5,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One ORCA half-space ``{v : normal . (v - point) >= 0}`` of an agent against one neighbour.

    Give either ``combined_radius`` (spheres) or ``half_extents`` (boxes).

    Args:
        rel_position: (3,) m, neighbour centre minus agent centre.
        rel_velocity: (3,) m/s, agent velocity minus neighbour velocity.
        velocity: (3,) m/s, the agent's current velocity.
        time_horizon: s, collisions later than this are ignored.
        recovery_time: s, overlapping shapes separate over this time.
        combined_radius: m, sum of both sphere radii (margins included).
        half_extents: (3,) m, half extents of the Minkowski sum of both boxes (margins included).
        vertical_cost: boxes only: weight of vertical velocity changes when choosing the way out.
        responsibility: share of the avoidance the agent takes (0.5: reciprocal).

    Returns:
        (normal (3,) unit, point (3,) m/s).
    """
    if (combined_radius is None) == (half_extents is None):
        raise ValueError("give exactly one of combined_radius and half_extents")
    p, v = _vec3(rel_position), _vec3(rel_velocity)
    if combined_radius is not None:
        n, u = _sphere_u(p, v, float(combined_radius), 1.0 / time_horizon, 1.0 / recovery_time)
    else:
        n, u = _box_u(p, _vec3(half_extents), v, 1.0 / time_horizon, 1.0 / recovery_time, float(vertical_cost))
    return np.array(n), np.asarray(velocity, dtype=float).reshape(3) + responsibility * np.array(u)


def solve_velocity(
    normals: NDArray[np.float64],
    points: NDArray[np.float64],
    preferred: NDArray[np.float64],
    *,
    v_max: NDArray[np.float64] | None = None,
    max_speed: float | None = None,
) -> tuple[NDArray[np.float64], bool]:
    """Velocity closest to ``preferred`` inside the half-spaces, the per-axis box and the speed sphere.

    Args:
        normals: (m, 3) unit normals of the half-spaces ``normal . (v - point) >= 0``.
        points: (m, 3) m/s, a point on each plane.
        preferred: (3,) m/s.
        v_max: (3,) m/s per-axis limit (hard), or None.
        max_speed: m/s, radius of the speed sphere (default: |v_max|, or 1 m/s without limits).

    Returns:
        (velocity (3,) m/s, feasible). When infeasible: among the velocities whose largest
        violation of the half-spaces is smallest (the box still holds), the closest to ``preferred``.
    """
    normals = np.ascontiguousarray(normals, dtype=float).reshape(-1, 3)
    points = np.ascontiguousarray(points, dtype=float).reshape(-1, 3)
    vm = _limits(v_max)
    m = normals.shape[0] + 6
    N, P = np.empty((m, 3)), np.empty((m, 3))
    n_hard = _bound_planes(-vm[None, :], vm[None, :], 0, N, P)
    N[n_hard : n_hard + len(normals)] = normals
    P[n_hard : n_hard + len(normals)] = points
    feasible, res = _solve(
        N,
        P,
        n_hard + len(normals),
        n_hard,
        _sphere_radius(vm, max_speed),
        _vec3(preferred),
        np.empty((m, 3)),
        np.empty((m, 3)),
    )
    return np.array(res), bool(feasible)


def neighbour_table(positions: NDArray[np.float64], sensing_radius: float, max_neighbours: int) -> NDArray[np.int64]:
    """Up to ``max_neighbours`` nearest other agents within ``sensing_radius`` of each agent (k-d tree).

    Args:
        positions: (n, 3) m.

    Returns:
        (n, k) agent indices, nearest first, padded with -1 (k = min(max_neighbours, n - 1) + 1).
    """
    n = positions.shape[0]
    if n < 2:
        return np.full((n, 1), -1, dtype=np.int64)
    k = min(max_neighbours, n - 1) + 1
    _, idx = cKDTree(positions).query(positions, k=k, distance_upper_bound=sensing_radius)
    idx = np.asarray(idx, dtype=np.int64).reshape(n, k)
    idx[idx >= n] = -1
    idx[idx == np.arange(n)[:, None]] = -1
    return idx


def orca_velocities(
    positions: NDArray[np.float64],
    velocities: NDArray[np.float64],
    preferred: NDArray[np.float64],
    *,
    params: OrcaParams,
    sensing_radius: float,
    v_max: NDArray[np.float64] | None,
    radii: NDArray[np.float64] | None = None,
    boxes: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    goals: NDArray[np.float64] | None = None,
    has_goal: NDArray[np.bool_] | None = None,
    bounds: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    commanded: NDArray[np.float64] | None = None,
    neighbours: NDArray[np.int64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Collision-avoiding velocities of all agents from sensed state (one compiled call).

    Args:
        positions: (n, 3) m, sensed.
        velocities: (n, 3) m/s, the velocities ORCA linearises about (sensed, clipped to the limits).
        preferred: (n, 3) m/s, each agent's preferred velocity.
        params: layer parameters (``params.shape`` says which of ``radii`` / ``boxes`` is used;
            ``params.margin`` is added to either).
        sensing_radius: m, only neighbours within it are considered.
        v_max: (3,) m/s per-axis limit, or None.
        radii: (n,) m, sphere radius of each agent (needed for ``Shape.SPHERE``).
        boxes: (centre offsets (n, 3) m, half extents (n, 3) m) of each agent's bounding box (see
            ``bounding_boxes``; needed for ``Shape.BOX``).
        goals: (n, 3) m, position targets (only used to tell "a neighbour on my goal" from "in my way").
        has_goal: (n,) True where ``goals`` holds a target.
        bounds: (lower (n, 3), upper (n, 3)) m/s, hard per-axis bounds of each agent's velocity
            (default: the velocity limits; see ``velocity_bounds``).
        commanded: (n, 3) m/s, the velocity each agent's own command would give it (default:
            ``preferred``). An agent whose commanded velocity satisfies all its planes is left
            alone (flag ``FLAG_FREE``, returned velocity = commanded); the others get the LP's
            velocity closest to ``preferred``.
        neighbours: (n, k) neighbour table from ``neighbour_table`` (computed when None).

    Returns:
        (velocities (n, 3) m/s, flags (n,) of ``FLAG_INFEASIBLE | FLAG_BIASED | FLAG_FREE | FLAG_CLIMB``).
    """
    pos = np.ascontiguousarray(positions, dtype=float)
    n = pos.shape[0]
    vm = _limits(v_max)
    use_boxes = params.shape is Shape.BOX
    if use_boxes:
        if boxes is None:
            raise ValueError("shape 'box' needs boxes=(centres, half_extents)")
        centre, half = (np.ascontiguousarray(b, dtype=float).reshape(n, 3) for b in boxes)
        radius = np.linalg.norm(half, axis=1)
    else:
        if radii is None:
            raise ValueError("shape 'sphere' needs radii")
        radius = np.ascontiguousarray(radii, dtype=float).reshape(n)
        centre = half = np.zeros((n, 3))
    if neighbours is None:
        neighbours = neighbour_table(pos, sensing_radius, params.max_neighbours)
    goals = np.zeros((n, 3)) if goals is None else np.ascontiguousarray(goals, dtype=float)
    has_goal = np.zeros(n, dtype=np.bool_) if has_goal is None else np.ascontiguousarray(has_goal, dtype=np.bool_)
    if bounds is None:
        lo, hi = np.tile(-vm, (n, 1)), np.tile(vm, (n, 1))
    else:
        lo, hi = (np.ascontiguousarray(b, dtype=float).reshape(n, 3) for b in bounds)
    pref = np.ascontiguousarray(preferred, dtype=float)
    v_cmd = pref if commanded is None else np.ascontiguousarray(commanded, dtype=float)
    p = params
    cfg = np.array(
        [
            p.margin,
            p.lag_margin_s,
            1.0 / p.time_horizon,
            1.0 / p.recovery_time,
            p.responsibility,
            p.vertical_cost,
            _sphere_radius(vm, p.max_speed),
            p.time_horizon,
            p.right_bias,
            p.stuck_fraction,
            1.0 if p.climb_over else 0.0,
        ]
    )
    out = np.empty((n, 3))
    flags = np.zeros(n, dtype=np.int64)
    _orca_batch(
        pos,
        np.ascontiguousarray(velocities, dtype=float),
        pref,
        v_cmd,
        radius,
        centre,
        half,
        use_boxes,
        np.ascontiguousarray(neighbours, dtype=np.int64),
        goals,
        has_goal,
        lo,
        hi,
        cfg,
        out,
        flags,
    )
    return out, flags


def preferred_velocities(
    kinds: NDArray[np.int64],
    vectors: NDArray[np.float64],
    positions: NDArray[np.float64],
    *,
    arrive_time: float,
    v_max: NDArray[np.float64] | None,
    max_speed: float | None = None,
) -> NDArray[np.float64]:
    """Preferred velocity of each agent from its command (what avoidance stays closest to).

    A POSITION target e away is approached at ``e / arrive_time`` per axis, clipped to the
    velocity limit: a smooth approach that slows down on arrival and does not overshoot with the
    airframe lagging its reference; VELOCITY commands are their own preferred velocity; HOLD
    prefers rest.

    Args:
        kinds: (n,) ``CommandKind`` values.
        vectors: (n, 3) command vectors (m for POSITION, m/s for VELOCITY).
        positions: (n, 3) m, sensed.
        arrive_time: s, time constant of the approach.
        v_max: (3,) m/s per-axis limit, or None.
        max_speed: m/s, cap on the speed (optional).

    Returns:
        (n, 3) m/s.
    """
    kinds = np.asarray(kinds)
    vectors = np.asarray(vectors, dtype=float)
    pref = np.zeros_like(vectors)
    pos_cmd = kinds == int(CommandKind.POSITION)
    pref[pos_cmd] = (vectors[pos_cmd] - positions[pos_cmd]) / arrive_time
    vel_cmd = kinds == int(CommandKind.VELOCITY)
    pref[vel_cmd] = vectors[vel_cmd]
    if v_max is not None:
        np.clip(pref, -v_max, v_max, out=pref)
    if max_speed is not None:
        s = np.linalg.norm(pref, axis=1)
        over = s > max_speed
        pref[over] *= (max_speed / s[over])[:, None]
    return pref


def commanded_velocities(
    kinds: NDArray[np.int64],
    vectors: NDArray[np.float64],
    positions: NDArray[np.float64],
    *,
    v_max: NDArray[np.float64] | None,
    a_max: NDArray[np.float64],
    dt: float,
) -> NDArray[np.float64]:
    """Velocity (n, 3) m/s each command would give its agent through the reference shaper.

    Position mode of the shaper: per axis the velocity limit, braking at ``a_max``
    (``sqrt(2 a_max |e|)``) and at most ``|e| / dt``; velocity mode: the command clipped; HOLD: 0.

    Args:
        kinds: (n,) ``CommandKind`` values.
        vectors: (n, 3) command vectors.
        positions: (n, 3) m, sensed.
        v_max: (3,) m/s per-axis limit, or None (then position commands are steps: |e| / dt).
        a_max: (3,) m/s^2.
        dt: s, the shaper's tick.
    """
    kinds = np.asarray(kinds)
    vectors = np.asarray(vectors, dtype=float)
    out = np.zeros_like(vectors)
    pos_cmd = kinds == int(CommandKind.POSITION)
    e = vectors[pos_cmd] - positions[pos_cmd]
    speed = np.minimum(np.sqrt(2.0 * np.asarray(a_max, dtype=float) * np.abs(e)), np.abs(e) / dt)
    out[pos_cmd] = np.sign(e) * speed
    vel_cmd = kinds == int(CommandKind.VELOCITY)
    out[vel_cmd] = vectors[vel_cmd]
    if v_max is not None:
        np.clip(out, -v_max, v_max, out=out)
    return out


def velocity_bounds(
    positions: NDArray[np.float64],
    intended: NDArray[np.float64],
    v_max: NDArray[np.float64] | None,
    *,
    floor_height: float,
    time_horizon: float,
    goals: NDArray[np.float64] | None = None,
    has_goal: NDArray[np.bool_] | None = None,
    column: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Hard per-axis bounds (lower (n, 3), upper (n, 3)) m/s of the velocity avoidance may give each agent.

    ORCA knows neither the ground nor what stands on it. So it may push an agent down only above
    ``floor_height``, by at most its height above it per horizon; below, never faster down than
    the agent intends to go itself. And an agent low down on a vertical leg to or from its
    target (horizontally within ``column`` of it: descending to grasp or place, climbing away) is
    over a box or the structure, where a sideways dodge tilts the airframe into it: avoidance may
    only slow it down or lift it, not move it sideways. The velocity limits bound everything.

    Args:
        positions: (n, 3) m, sensed.
        intended: (n, 3) m/s, the velocity each agent's command asks for (``commanded_velocities``).
        v_max: (3,) m/s per-axis limit, or None.
        floor_height: m.
        time_horizon: s.
        goals: (n, 3) m, position targets; ``has_goal`` (n,) says which hold one.
        column: m, horizontal radius of a vertical leg (0: no such rule).
    """
    n = len(positions)
    vm = _limits(v_max)
    lo, hi = np.tile(-vm, (n, 1)), np.tile(vm, (n, 1))
    sink = np.maximum(positions[:, 2] - floor_height, 0.0) / time_horizon
    lo[:, 2] = np.maximum(lo[:, 2], np.minimum(intended[:, 2], -sink))
    if goals is not None and has_goal is not None and column > 0.0:
        e = goals - positions
        leg = has_goal & (np.hypot(e[:, 0], e[:, 1]) <= column) & (positions[:, 2] < floor_height)
        lo[leg, :2] = np.minimum(intended[leg, :2], 0.0)
        hi[leg, :2] = np.maximum(intended[leg, :2], 0.0)
    return lo, hi


def bounding_boxes(
    quaternions: NDArray[np.float64],
    half_extent: NDArray[np.float64],
    carrying: NDArray[np.bool_],
    box_size: float,
    box_drop: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """World-axis bounding boxes of airframes (and hanging boxes) from sensed attitudes.

    Args:
        quaternions: (n, 4) (x, y, z, w).
        half_extent: (3,) m, half the airframe's collision box.
        carrying: (n,) True where an agent holds a box.
        box_size: m, edge of a box.
        box_drop: m, box centre below the agent centre in the body frame.

    Returns:
        (centre offsets (n, 3) m from each agent's position, half extents (n, 3) m).
    """
    x, y, z, w = (quaternions[:, k] for k in range(4))
    R = np.empty((len(quaternions), 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - z * w)
    R[:, 0, 2] = 2 * (x * z + y * w)
    R[:, 1, 0] = 2 * (x * y + z * w)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - x * w)
    R[:, 2, 0] = 2 * (x * z - y * w)
    R[:, 2, 1] = 2 * (y * z + x * w)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    absR = np.abs(R)
    half = absR @ half_extent  # (n, 3)
    lo, hi = -half, half.copy()
    if np.any(carrying):
        c = -box_drop * R[:, :, 2]  # box centre offset, world frame
        hb = absR @ np.full(3, 0.5 * box_size)
        lo = np.where(carrying[:, None], np.minimum(lo, c - hb), lo)
        hi = np.where(carrying[:, None], np.maximum(hi, c + hb), hi)
    return np.ascontiguousarray(0.5 * (lo + hi)), np.ascontiguousarray(0.5 * (hi - lo))


# ----------------------------------------------------------------------------- parameters
class OrcaParams(Params):
    """Parameters of the ORCA layer (scenario field ``avoidance_params``); see the module notes."""

    shape: Shape = Field(
        Shape.BOX, strict=False, description="box (attitude-aware bounding boxes of airframe and load) or sphere"
    )
    time_horizon: float = Field(1.5, gt=0.0, le=60.0, description="s, collisions predicted later than this are ignored")
    safety_margin: float | None = Field(
        None,
        ge=0.0,
        le=1.0,
        description="m, added on every side of each shape (null: 0.015 for boxes, 0.03 for spheres)",
    )
    lag_margin_s: float = Field(
        0.4, ge=0.0, le=10.0, description="s, a pair's shapes also grow by this times their closing speed"
    )
    vertical_cost: float = Field(
        0.75,
        gt=0.0,
        le=100.0,
        description="boxes: weight of a vertical change of velocity against a horizontal one "
        "(< 1 favours passing over)",
    )
    max_neighbours: int = Field(10, ge=1, le=100, description="the nearest this many sensed neighbours give planes")
    recovery_time: float = Field(0.5, gt=0.0, le=60.0, description="s, shapes that already overlap separate over this")
    responsibility: float = Field(
        0.5, gt=0.0, le=1.0, description="share of each pair's avoidance an agent takes (0.5: reciprocal)"
    )
    arrive_time: float = Field(
        0.5, gt=0.0, le=60.0, description="s, POSITION targets are approached at distance / arrive_time per axis"
    )
    capture_radius: float = Field(
        0.05,
        ge=0.0,
        le=10.0,
        description="m, within this of a POSITION/HOLD target the command passes through when the clearance test holds",
    )
    clearance_margin: float = Field(0.02, ge=0.0, le=1.0, description="m, box clearance the passthrough requires")
    clearance_lookahead: float = Field(
        0.3, ge=0.0, le=10.0, description="s, a neighbour's box is swept along its velocity for this long"
    )
    floor_height: float = Field(0.5, ge=0.0, le=100.0, description="m, below this avoidance never pushes an agent down")
    column_radius: float = Field(
        0.03,
        ge=0.0,
        le=10.0,
        description="m, below floor_height an agent this close to its target (horizontally) "
        "is never moved sideways (0: off)",
    )
    right_bias: float = Field(
        0.5, ge=0.0, le=10.0, description="fraction of the preferred speed added sideways to a stalled agent"
    )
    stuck_fraction: float = Field(
        0.25, ge=0.0, lt=1.0, description="progress below this fraction of the preferred speed counts as stalled"
    )
    max_speed: float | None = Field(
        None,
        gt=0.0,
        le=100.0,
        description="m/s, radius of the speed sphere (null: the corner of the velocity-"
        "limit box, or 1 m/s without limits)",
    )
    uncertainty_sigmas: float = Field(
        2.0,
        ge=0.0,
        le=10.0,
        description="flying on estimates, shapes grow by this many standard deviations "
        "of a pair's relative position error",
    )
    climb_over: bool = Field(
        True,
        description="the upper agent of a pair takes the whole of a vertical way out when the lower one flies level",
    )

    @property
    def margin(self) -> float:
        """m, the safety margin in use."""
        if self.safety_margin is not None:
            return float(self.safety_margin)
        return 0.015 if self.shape is Shape.BOX else 0.03


# ----------------------------------------------------------------------------- the layer
def _warm_up() -> None:
    """Compile (or load from the cache) the kernels now, so that no planner tick pays for it."""
    pos = np.array([[0.0, 0.0, 1.0], [0.5, 0.0, 1.0]])
    z3 = np.zeros((2, 3))
    nbr = neighbour_table(pos, 1.0, 4)
    for shape in Shape:
        orca_velocities(
            pos,
            z3,
            z3,
            params=OrcaParams(shape=shape),
            sensing_radius=1.0,
            v_max=np.full(3, 1.0),
            radii=np.full(2, 0.1),
            boxes=(z3, np.full((2, 3), 0.05)),
            bounds=(z3 - 1.0, z3 + 1.0),
            neighbours=nbr,
        )
    _clear_paths(
        pos, pos, z3, np.full((2, 3), 0.05), z3, nbr, np.ones(2, dtype=np.bool_), 0.0, 0.0, np.zeros(2, dtype=np.bool_)
    )


class OrcaLayer:
    """The ``--avoidance orca`` layer: turns every planner's commands into safe ones.

    Each planner tick, per agent: the nearest neighbours within the sensing radius (from the swarm's
    perception snapshot), shapes from sensed attitude and load, one LP; a
    command is kept when it is safe as it is (or a precise final approach is clear), else replaced
    by a VELOCITY command with the same ``action`` and ``yaw``.

    Args:
        setup: what the layer is told before the run (vehicle, limits, rates, sensing radius, task layout).
        params: validated ``OrcaParams`` (scenario ``avoidance_params``; default: the defaults).
    """

    Params: ClassVar[type[OrcaParams]] = OrcaParams
    needs_range_sensors: ClassVar[bool] = False

    def __init__(self, setup: AvoidanceSetup, params: OrcaParams | None = None) -> None:
        self.params = params if params is not None else OrcaParams()
        info = setup.info
        std = float(info.extra.get("position_std", 0.0))  # m, per-axis, flying on estimates
        if std > 0.0:
            grow = self.params.uncertainty_sigmas * math.sqrt(2.0) * std / 2.0
            self.params = self.params.model_copy(update={"safety_margin": self.params.margin + grow})
        self.n = setup.n
        self.v_max = setup.v_max  # (3,) m/s or None
        self.a_max = setup.a_max  # (3,) m/s^2
        self.control_dt = setup.control_dt  # s, the shaper's tick
        self.sensing_radius = setup.sensing_radius
        self.r_agent = float(setup.agent_radius)  # m, airframe enclosing radius
        self.half_extent = 0.5 * np.asarray(setup.collision_size, dtype=float)  # (3,) m
        self.box_size = float(info.box_size)  # m, 0 when the task has no boxes
        self.box_drop = float(info.grasp_height)  # m, box centre below agent
        # sphere around the agent centre enclosing airframe and hanging box
        self.r_carry = max(
            self.r_agent, math.hypot(math.sqrt(2.0) * 0.5 * self.box_size, self.box_drop + 0.5 * self.box_size)
        )
        _warm_up()
        self._ticks = 0
        self._agent_ticks = 0
        self._infeasible = 0
        self._biased = 0
        self._climbing = 0
        self._changed = 0
        self._time_total = 0.0
        self._time_max = 0.0

    def filter(self, commands: list[Command], perception: Perception, task: TaskView) -> list[Command]:
        """Safe commands for this planner tick (``action`` and ``yaw`` of each command are kept)."""
        t0 = time.perf_counter()
        p = self.params
        n = self.n
        pos = np.ascontiguousarray(perception.positions)  # sensed (estimated) own states
        vel = np.ascontiguousarray(perception.velocities)
        carrying = task.carrying >= 0
        kinds = np.fromiter((int(cmd.kind) for cmd in commands), dtype=np.int64, count=n)
        vectors = np.array([cmd.vector for cmd in commands], dtype=float).reshape(n, 3)
        hold = kinds == int(CommandKind.HOLD)
        has_goal = (kinds == int(CommandKind.POSITION)) | hold
        goals = np.where(has_goal[:, None], vectors, pos)
        goals[hold] = pos[hold]
        pref = preferred_velocities(
            kinds, vectors, pos, arrive_time=p.arrive_time, v_max=self.v_max, max_speed=p.max_speed
        )
        v_cmd = commanded_velocities(kinds, vectors, pos, v_max=self.v_max, a_max=self.a_max, dt=self.control_dt)
        nbr = perception.nearest_table(p.max_neighbours)
        centre, half = bounding_boxes(
            np.ascontiguousarray(perception.quaternions), self.half_extent, carrying, self.box_size, self.box_drop
        )
        radii = np.where(carrying, self.r_carry, self.r_agent)
        # bounds around what the command itself asks for (per axis it covers the preferred velocity)
        bounds = velocity_bounds(
            pos,
            v_cmd,
            self.v_max,
            floor_height=p.floor_height,
            time_horizon=p.time_horizon,
            goals=goals,
            has_goal=has_goal,
            column=p.column_radius,
        )
        # the overshoots of the airframes after a turn are not motion ORCA should answer
        v_opt = vel if self.v_max is None else np.clip(vel, -self.v_max, self.v_max)
        safe, flags = orca_velocities(
            pos,
            v_opt,
            pref,
            params=p,
            sensing_radius=self.sensing_radius,
            v_max=self.v_max,
            radii=radii,
            boxes=(centre, half),
            goals=goals,
            has_goal=has_goal,
            bounds=bounds,
            commanded=v_cmd,
            neighbours=nbr,
        )
        near = has_goal & (np.linalg.norm(goals - pos, axis=1) <= p.capture_radius)
        passthrough = np.zeros(n, dtype=np.bool_)
        if near.any():
            _clear_paths(
                pos, goals, centre, half, vel, nbr, near, p.clearance_margin, p.clearance_lookahead, passthrough
            )
        keep = passthrough | ((flags & FLAG_FREE) != 0)
        out = [
            cmd if keep[i] else Command(CommandKind.VELOCITY, safe[i].copy(), cmd.yaw, cmd.action)
            for i, cmd in enumerate(commands)
        ]
        dt = time.perf_counter() - t0
        self._ticks += 1
        self._agent_ticks += n
        self._infeasible += int(np.count_nonzero(flags & FLAG_INFEASIBLE))
        self._biased += int(np.count_nonzero(flags & FLAG_BIASED))
        self._climbing += int(np.count_nonzero(flags & FLAG_CLIMB))
        self._changed += int(n - np.count_nonzero(keep))
        self._time_total += dt
        self._time_max = max(self._time_max, dt)
        return out

    def metrics(self) -> dict[str, Any]:
        """Counters of the run (merged into metrics.json); the ``*_ms`` ones are wall-clock timings."""
        ticks = max(self._ticks, 1)
        return {
            "orca_ticks": self._ticks,
            "orca_changed_fraction": self._changed / max(self._agent_ticks, 1),
            "orca_infeasible_agent_ticks": self._infeasible,
            "orca_biased_agent_ticks": self._biased,
            "orca_climbing_agent_ticks": self._climbing,
            "orca_mean_solve_ms": 1e3 * self._time_total / ticks,
            "orca_max_solve_ms": 1e3 * self._time_max,
        }


from pybullet_swarm.planning.registry import register_avoidance  # noqa: E402

register_avoidance(
    "orca",
    OrcaLayer,
    "optimal reciprocal collision avoidance in 3-D on every planner's commands "
    "(sensed neighbours, attitude-aware boxes or spheres, velocity limits, exact positioning at "
    "targets)",
)
