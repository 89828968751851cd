"""The paper's ORCA: velocity obstacles, ORCA half-spaces and the linear programs, as the paper writes them.

van den Berg, Guy, Lin and Manocha, "Reciprocal n-body collision avoidance" (ISRR 2009), with the
solver of its RVO2-3D library:

* **Velocity obstacle.** For agents A and B (relative position p = p_B - p_A, combined shape) the
  VO truncated at the time horizon tau is the set of relative velocities v = v_A - v_B that make
  them touch within tau. ``sphere_u`` computes it for spheres (a cone cut off by a sphere of
  radius R / tau around p / tau; RVO2-3D), ``box_u`` exactly for axis-aligned boxes (the
  Minkowski box, eliminating the time by Fourier-Motzkin).
* **ORCA half-space.** u is the smallest change of v that takes it out of the VO, n the outward
  normal at v + u; agent A takes ``responsibility`` (0.5: reciprocal) of it:
  ``ORCA_A = {v : n . (v - (v_A + responsibility u)) >= 0}``, B the mirrored half.
  Shapes that already overlap separate over ``recovery_time`` (RVO2 uses the time step).
* **Linear program.** The new velocity is the one closest to the preferred velocity inside every
  half-space, the hard constraints (the vehicle's per-axis velocity limits, which RVO2 treats as
  it treats obstacle lines: never traded away) and the speed sphere: Seidel's incremental
  algorithm without the shuffle (``lp1``, ``lp2``, ``lp3``). When the half-spaces have no
  common velocity, the 4-D problem "minimise the largest violation" (``lp4``, on bisector
  planes), then the velocity closest to the preferred one among the least-violating ones.

One convention the paper leaves open: a relative velocity exactly on the line of centres of two
spheres has no defined nearest side of the cone; the way out is then taken to the right
(``right_of``), antisymmetric, so the two agents turn to opposite sides.

Everything here is compiled (``njit``) and knows nothing of the extension rules (``rules.py``),
which ``kernel.py`` composes with it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.orca.cache import njit
from pybullet_swarm.planning.orca.vec import Vec, add, axis, cross, dot, row, scale, set_row

# numerical tolerances of the geometry and of the LPs
PARALLEL_EPS = 1e-14  # squared length of a cross product below which two unit vectors count as parallel
PLANE_TOL = 1e-12  # m/s, a velocity this far outside a half-space still satisfies it
NEAR_ZERO = 1e-12  # m/s (or m), a length below which a vector has no usable direction
DENORMAL = 1e-300  # anything below this is zero in floating point
VERTICAL_LINE2 = 1e-6  # |d x z|^2 below which a unit direction d counts as vertical (within 0.06 deg)
FAR = 1e300  # stands for "infinitely far" in a search for the nearest
PROJECTION_SPEED = 1e3  # m/s, speed sphere of the projection onto a box VO: large enough to never bind
FALLBACK_SLACK = 1e-9  # m/s, the least-violation velocity is re-solved with the planes moved out by this more
SPEED_SPHERE_SLACK = 1e-9  # relative: the default speed sphere encloses the velocity-limit box by this much
DEFAULT_SPEED_SPHERE = 1.0  # m/s, speed sphere when there are no velocity limits and no max_speed
BOX_ROWS = 7  # rows of a box VO in s = 1/t: a lower and an upper face per axis, then s >= 1/tau
BOX_PLANES = 24  # at most this many planes bound a box VO (pairs of those rows)

#: the core's settings as the kernels read them (one record)
SETTINGS = np.dtype(
    [
        ("margin", np.float64),  # m, added on every side of each shape
        ("inv_tau", np.float64),  # 1/s, inverse of the time horizon
        ("inv_rec", np.float64),  # 1/s, inverse of the recovery time of overlapping shapes
        ("responsibility", np.float64),  # share of each pair's u an agent takes (0.5: reciprocal)
        ("max_speed", np.float64),  # m/s, radius of the LP's speed sphere
    ],
    align=True,
)


# ----------------------------------------------------------------------------- velocity obstacles
@njit
def right_of(d: Vec) -> Vec:
    """Unit vector to the right of unit direction ``d`` (z up): ``d x z``, or ``d x x`` when d is vertical.

    Antisymmetric (``right(-d) = -right(d)``), so two agents facing each other pick opposite sides.
    """
    c = cross(d, (0.0, 0.0, 1.0))
    n2 = dot(c, c)
    if n2 < VERTICAL_LINE2:
        c = cross(d, (1.0, 0.0, 0.0))
        n2 = dot(c, c)
    return scale(c, 1.0 / math.sqrt(n2))


@njit
def sphere_u(p: Vec, v: Vec, R: float, inv_tau: float, inv_rec: float) -> tuple[Vec, Vec]:
    """Outward normal n and change u of relative velocity ``v`` for two spheres (combined radius R m).

    ``p`` m is the second agent's position relative to the first, ``v`` m/s the first's velocity
    relative to the second's; ``inv_tau`` 1/s the inverse time horizon, ``inv_rec`` 1/s the inverse
    recovery time of overlapping spheres.
    """
    d2 = dot(p, p)
    R2 = R * R
    if d2 > R2:
        w = add(v, p, -inv_tau)  # from the centre of the cut-off sphere to v
        w2 = dot(w, w)
        wp = dot(w, p)
        if wp < 0.0 and wp * wp > R2 * w2:
            # closest to the cut-off sphere (radius R / tau around p / tau)
            wl = math.sqrt(w2)
            n = scale(w, 1.0 / wl)
            return n, scale(n, R * inv_tau - wl)
        # closest to the cone's side: in the plane of p and v, the side ray at angle asin(R / d)
        # from p; n = (-R p/d + leg e) / d with e the unit part of v perpendicular to p, and the
        # signed distance of v from that side is (R b - leg |p x v|) / d^2 with b = p . v
        d = math.sqrt(d2)
        ph = scale(p, 1.0 / d)
        b = dot(p, v)
        cr = cross(p, v)
        crn = math.sqrt(dot(cr, cr))
        leg = math.sqrt(d2 - R2)
        vv = math.sqrt(dot(v, v))
        if crn > NEAR_ZERO * d * vv and crn > DENORMAL:
            e = scale(add(v, p, -b / d2), d / crn)
        else:  # v on the line of centres: keep right
            e = right_of(ph)
        n = add(scale(ph, -R / d), e, leg / d)
        return n, scale(n, (R * b - leg * crn) / d2)
    # already overlapping: separate over the recovery time
    w = add(v, p, -inv_rec)
    wl = math.sqrt(dot(w, w))
    if wl > NEAR_ZERO:
        n = scale(w, 1.0 / wl)
    elif d2 > NEAR_ZERO * NEAR_ZERO:
        n = scale(p, -1.0 / math.sqrt(d2))
    else:
        n = (-1.0, 0.0, 0.0)
    return n, scale(n, R * inv_rec - wl)


@njit
def box_gap(c: Vec, H: Vec) -> tuple[float, int]:
    """How far apart two axis-aligned boxes are, m (the largest per-axis gap; negative: they overlap), and the
    axis of that gap (the first, on a tie); ``c``: the centre offset, ``H``: the summed half extents."""
    g0, g1, g2 = abs(c[0]) - H[0], abs(c[1]) - H[1], abs(c[2]) - H[2]
    if g0 >= g1 and g0 >= g2:
        return g0, 0
    if g1 >= g2:
        return g1, 1
    return g2, 2


@njit
def box_u(c: Vec, H: Vec, v: Vec, inv_tau: float, inv_rec: float, bare: Vec) -> tuple[Vec, Vec]:
    """Outward normal n and change u of relative velocity ``v`` for two axis-aligned boxes.

    ``c`` m is the centre of the second box relative to the first, ``H`` m the half extents of
    their Minkowski sum, ``v`` m/s the first's velocity relative to the second's.

    Boxes apart have the VO {v : t v in B for some 0 < t <= tau}, B = [c - H, c + H] (``box_vo``).
    Overlapping boxes open the gap over the recovery time along the axis of least overlap; with
    ``bare`` m (the half extents of the Minkowski sum without margins and growths; negative: off,
    ``MARGIN_OVERLAP``) along the least overlap of the axes on which the bare shapes are apart, when
    there are any: the recovery leaves the other axes free, and only those axes keep the pair apart.
    """
    pen = -FAR
    k_pen = 0
    cost = FAR
    apart = False
    if bare[0] >= 0.0:
        for k in range(3):
            apart = apart or abs(c[k]) > bare[k]
    for k in range(3):
        g = abs(c[k]) - H[k]
        pen = max(pen, g)
        # separation still needed along k; not weighted: when two shapes overlap only a little
        # vertically (one just above the other) a sideways way out leaves them free to close
        # vertically, so the least overlap wins whatever its axis
        if -g < cost and (not apart or abs(c[k]) > bare[k]):
            cost = -g
            k_pen = k
    if pen > 0.0:
        return box_vo(c, H, v, inv_tau)
    # overlapping now: open the gap along the axis of least overlap over the recovery time
    s = axis(k_pen, 1.0 if c[k_pen] >= 0.0 else -1.0)
    gap = abs(c[k_pen]) - H[k_pen]
    return scale(s, -1.0), scale(s, gap * inv_rec - dot(v, s))


@njit
def box_vo(c: Vec, H: Vec, v: Vec, inv_tau: float) -> tuple[Vec, Vec]:
    """(n, u) of the box VO of two boxes that do not overlap (``box_u``'s arguments).

    With s = 1 / t the VO reads "some s >= 1/tau satisfies s (c_k - H_k) <= v_k <= s (c_k + H_k)
    for every axis k": each row ``a s <= g . v + h`` bounds s from above (a > 0) or below (a < 0),
    and s exists iff every lower bound is below every upper bound. Each (lower, upper) pair is one
    linear inequality F(v) = n . v + d >= 0; the VO is their intersection, and the outer side of
    each of these planes is free of the VO. Inside the VO, u leads to the plane nearest v (the
    paper's nearest point); outside, to the VO's nearest point.
    """
    # rows a s <= g . v + h: lower and upper faces of each axis, then s >= 1/tau
    ra = np.empty(BOX_ROWS)
    rg = np.zeros((BOX_ROWS, 3))
    rh = np.zeros(BOX_ROWS)
    for k in range(3):
        ra[2 * k] = c[k] - H[k]  # s (c - H) <= v_k
        rg[2 * k, k] = 1.0
        ra[2 * k + 1] = -(c[k] + H[k])  # -s (c + H) <= -v_k
        rg[2 * k + 1, k] = -1.0
    ra[BOX_ROWS - 1] = -1.0  # -s <= -1/tau
    rh[BOX_ROWS - 1] = -inv_tau
    best = FAR
    best_f = 0.0
    bn = (0.0, 0.0, 0.0)
    FN = np.empty((BOX_PLANES, 3))  # the VO's planes, for the projection of an outside v
    FP = np.empty((BOX_PLANES, 3))
    nf = 0
    for p in range(BOX_ROWS):
        if ra[p] > 0.0:
            continue
        gp = row(rg, p)
        for q in range(-1, BOX_ROWS):
            if q < 0:
                if ra[p] != 0.0:
                    continue
                n = gp  # a row without s: g . v + h >= 0 itself
                f = dot(gp, v) + rh[p]
            else:
                if ra[q] <= 0.0 or ra[p] == 0.0:
                    continue
                # lower bound (g_p . v + h_p) / a_p <= upper bound (g_q . v + h_q) / a_q
                n = add(scale(gp, ra[q]), row(rg, q), -ra[p])
                f = dot(n, v) + ra[q] * rh[p] - ra[p] * rh[q]
            nn = math.sqrt(dot(n, n))
            if nn < NEAR_ZERO:
                continue
            set_row(FN, nf, scale(n, 1.0 / nn))
            set_row(FP, nf, add(v, n, -f / (nn * nn)))  # the point of the plane nearest v
            nf += 1
            if f / nn < best:
                best = f / nn
                best_f = f / nn
                bn = scale(n, 1.0 / nn)
    out = scale(bn, -1.0)  # outward: the direction in which F decreases
    if best_f < 0.0:
        # outside: the point of the VO polytope closest to v, by the incremental LP
        fail, w = lp3(FN, FP, nf, PROJECTION_SPEED, v, False)
        if fail >= nf:
            u = add(w, v, -1.0)
            ul = math.sqrt(dot(u, u))
            if ul > NEAR_ZERO:
                return scale(u, -1.0 / ul), u
    return out, scale(out, best_f)


# ----------------------------------------------------------------------------- incremental LP
@njit
def lp1(
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    count: int,
    d: Vec,
    q: Vec,
    radius: float,
    opt: Vec,
    dir_opt: bool,
) -> tuple[bool, Vec]:
    """Best point on the line q + t d within the sphere and planes [0, count)."""
    dq = dot(q, d)
    disc = dq * dq + radius * radius - dot(q, q)
    if disc < 0.0:
        return False, q
    s = math.sqrt(disc)
    t_lo = -dq - s
    t_hi = -dq + s
    for i in range(count):
        n = row(N, i)
        num = dot(add(row(P, i), q, -1.0), n)
        den = dot(d, n)
        if den * den <= PARALLEL_EPS:  # line parallel to plane i: all in or all out
            if num > PLANE_TOL:
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
        t = t_hi if dot(opt, d) > 0.0 else t_lo
    else:
        t = min(max(dot(d, add(opt, q, -1.0)), t_lo), t_hi)
    return True, add(q, d, t)


@njit
def lp2(
    N: NDArray[np.float64], P: NDArray[np.float64], k: int, radius: float, opt: Vec, dir_opt: bool
) -> tuple[bool, Vec]:
    """Best point on plane k within the sphere and planes [0, k)."""
    n = row(N, k)
    pk = row(P, k)
    dist = dot(pk, n)
    r2 = radius * radius
    if dist * dist > r2:
        return False, opt
    disc_r2 = r2 - dist * dist  # squared radius of the sphere's section by the plane
    centre = scale(n, dist)
    if dir_opt:
        proj = add(opt, n, -dot(opt, n))
        p2 = dot(proj, proj)
        res = centre if p2 <= PARALLEL_EPS else add(centre, proj, math.sqrt(disc_r2 / p2))
    else:
        res = add(opt, n, dot(add(pk, opt, -1.0), n))
        if dot(res, res) > r2:
            off = add(res, centre, -1.0)
            res = add(centre, off, math.sqrt(disc_r2 / dot(off, off)))
    for i in range(k):
        ni = row(N, i)
        pi = row(P, i)
        if dot(ni, add(pi, res, -1.0)) > PLANE_TOL:
            cr = cross(ni, n)
            c2 = dot(cr, cr)
            if c2 <= PARALLEL_EPS:  # parallel and plane i excludes plane k entirely
                return False, res
            d = scale(cr, 1.0 / math.sqrt(c2))
            ln = cross(d, n)  # in plane k, perpendicular to the intersection line
            q = add(pk, ln, dot(add(pi, pk, -1.0), ni) / dot(ln, ni))
            ok, res = lp1(N, P, i, d, q, radius, opt, dir_opt)
            if not ok:
                return False, res
    return True, res


@njit
def lp3(
    N: NDArray[np.float64], P: NDArray[np.float64], m: int, radius: float, opt: Vec, dir_opt: bool
) -> tuple[int, Vec]:
    """Velocity closest to ``opt`` (or farthest along unit ``opt`` with ``dir_opt``) in the sphere and planes [0, m).

    Returns (index of the first plane that made the problem infeasible or m, velocity).
    """
    if dir_opt:
        res = scale(opt, radius)
    elif dot(opt, opt) > radius * radius:
        res = scale(opt, radius / math.sqrt(dot(opt, opt)))
    else:
        res = opt
    for i in range(m):
        if dot(row(N, i), add(row(P, i), res, -1.0)) > PLANE_TOL:
            ok, new = lp2(N, P, i, radius, opt, dir_opt)
            if not ok:
                return i, res
            res = new
    return m, res


@njit
def lp4(
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    m: int,
    begin: int,
    n_hard: int,
    radius: float,
    res: Vec,
    SN: NDArray[np.float64],
    SP: NDArray[np.float64],
    W: NDArray[np.float64],
    weighted: bool,
) -> Vec:
    """Velocity minimising the largest violation of the soft planes [n_hard, m), keeping the hard ones.

    For each plane i that is violated more than the current worst, the 3-D problem "go as far as
    possible along i's normal while no earlier plane is violated more than i" is solved on the
    bisector planes of i and each earlier soft plane (hard planes are kept as they are). With
    ``weighted`` a plane's violation counts ``W`` times (the bisectors of the weighted violations).
    """
    worst = 0.0
    for i in range(begin, m):
        ni = row(N, i)
        pi = row(P, i)
        wi = W[i] if weighted else 1.0
        if wi * dot(ni, add(pi, res, -1.0)) > worst:
            k = 0
            for j in range(i):
                nj = row(N, j)
                pj = row(P, j)
                if j < n_hard:
                    set_row(SN, k, nj)
                    set_row(SP, k, pj)
                    k += 1
                    continue
                if weighted:
                    # W[j] nj.(pj - v) <= wi ni.(pi - v): (W[j] nj - wi ni).v >= W[j] nj.pj - wi ni.pi
                    nn = add(scale(nj, W[j]), ni, -wi)
                    n2 = dot(nn, nn)
                    if n2 <= PARALLEL_EPS * wi * wi:
                        continue  # the same plane at the same weight: never the worse of the two
                    nl = math.sqrt(n2)
                    off = (W[j] * dot(nj, pj) - wi * dot(ni, pi)) / nl
                    nn = scale(nn, 1.0 / nl)
                    set_row(SN, k, nn)
                    set_row(SP, k, scale(nn, off))
                    k += 1
                    continue
                cr = cross(nj, ni)
                if dot(cr, cr) <= PARALLEL_EPS:
                    if dot(ni, nj) > 0.0:  # same direction: never the worse of the two
                        continue
                    pt = scale(add(pi, pj, 1.0), 0.5)
                else:
                    ln = cross(cr, ni)
                    pt = add(pi, ln, dot(add(pj, pi, -1.0), nj) / dot(ln, nj))
                nn = add(nj, ni, -1.0)
                set_row(SN, k, scale(nn, 1.0 / math.sqrt(dot(nn, nn))))
                set_row(SP, k, pt)
                k += 1
            fail, new = lp3(SN, SP, k, radius, ni, True)
            if fail >= k:  # (failure "should not happen"; keep the previous velocity)
                res = new
            worst = wi * dot(ni, add(pi, res, -1.0))
    return res


@njit
def solve(
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    m: int,
    n_hard: int,
    radius: float,
    pref: Vec,
    SN: NDArray[np.float64],
    SP: NDArray[np.float64],
    W: NDArray[np.float64],
    weighted: bool,
) -> tuple[bool, Vec]:
    """One agent's LP over the hard planes [0, n_hard) and the ORCA planes [n_hard, m); returns (feasible, velocity).

    ``SN``, ``SP`` are (m, 3) scratch arrays; with ``weighted``, where the planes have no common
    velocity, the violation of plane i counts ``W[i]`` times (``W`` (m,) > 0).
    """
    fail, res = lp3(N, P, m, radius, pref, False)
    if fail >= m:
        return True, res
    res = lp4(N, P, m, fail, n_hard, radius, res, SN, SP, W, weighted)
    # among the least-violating velocities, the one closest to the preferred velocity:
    # shift the soft planes by the smallest achievable violation and solve the LP again
    worst = 0.0
    for i in range(n_hard, m):
        worst = max(worst, (W[i] if weighted else 1.0) * dot(row(N, i), add(row(P, i), res, -1.0)))
    for i in range(m):
        ni = row(N, i)
        set_row(SN, i, ni)
        shift = (worst / W[i] if weighted else worst) + FALLBACK_SLACK
        set_row(SP, i, add(row(P, i), ni, -shift if i >= n_hard else 0.0))
    fail2, res2 = lp3(SN, SP, m, radius, pref, False)
    if fail2 >= m:
        res = res2
    return False, res


@njit
def bound_planes(
    lo: NDArray[np.float64], hi: NDArray[np.float64], i: int, N: NDArray[np.float64], P: NDArray[np.float64]
) -> int:
    """Write the half-spaces lo[i, k] <= v_k <= hi[i, k] (finite ones) into N, P; returns their count."""
    k = 0
    for a in range(3):
        if math.isfinite(hi[i, a]):
            set_row(N, k, axis(a, -1.0))
            set_row(P, k, axis(a, hi[i, a]))
            k += 1
        if math.isfinite(lo[i, a]):
            set_row(N, k, axis(a, 1.0))
            set_row(P, k, axis(a, lo[i, a]))
            k += 1
    return k


@njit
def violates(N: NDArray[np.float64], P: NDArray[np.float64], m: int, v: Vec) -> bool:
    """True when ``v`` lies outside one of the half-spaces [0, m) (by more than ``PLANE_TOL``)."""
    for k in range(m):
        if dot(row(N, k), add(row(P, k), v, -1.0)) > PLANE_TOL:
            return True
    return False


# ----------------------------------------------------------------------------- array API
def vec3(a: Any) -> Vec:
    """A 3-vector as a tuple of floats."""
    v = np.asarray(a, dtype=float).reshape(3)
    return (float(v[0]), float(v[1]), float(v[2]))


def limits(v_max: NDArray[np.float64] | None) -> NDArray[np.float64]:
    """Per-axis velocity limits (3,) m/s (infinite without limits)."""
    if v_max is None:
        return np.full(3, np.inf)
    return np.broadcast_to(np.asarray(v_max, dtype=float), (3,)).copy()


def speed_sphere(vm: NDArray[np.float64], max_speed: float | None) -> float:
    """m/s, radius of the LP's speed sphere: ``max_speed``, else the corner of the limit box, else 1 m/s."""
    if max_speed is not None:
        return float(max_speed)
    if np.all(np.isfinite(vm)):
        return float(np.linalg.norm(vm)) * (1.0 + SPEED_SPHERE_SLACK)
    return DEFAULT_SPEED_SPHERE


def orca_plane(
    rel_position: NDArray[np.float64],
    rel_velocity: NDArray[np.float64],
    velocity: NDArray[np.float64],
    *,
    time_horizon: float,
    recovery_time: float,
    combined_radius: float | None = None,
    half_extents: NDArray[np.float64] | None = None,
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
        responsibility: share of the avoidance the agent takes (0.5: reciprocal).

    Returns:
        (normal (3,) unit, point (3,) m/s).
    """
    if (combined_radius is None) == (half_extents is None):
        raise ValueError("give exactly one of combined_radius and half_extents")
    p, v = vec3(rel_position), vec3(rel_velocity)
    if combined_radius is not None:
        n, u = sphere_u(p, v, float(combined_radius), 1.0 / time_horizon, 1.0 / recovery_time)
    else:
        n, u = box_u(p, vec3(half_extents), v, 1.0 / time_horizon, 1.0 / recovery_time, (-1.0, -1.0, -1.0))
    return np.array(n), np.asarray(velocity, dtype=float).reshape(3) + responsibility * np.array(u)


def solve_velocity(
    normals: NDArray[np.float64],
    points: NDArray[np.float64],
    preferred: NDArray[np.float64],
    *,
    v_max: NDArray[np.float64] | None = None,
    max_speed: float | None = None,
    weights: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], bool]:
    """Velocity closest to ``preferred`` inside the half-spaces, the per-axis box and the speed sphere.

    Args:
        normals: (m, 3) unit normals of the half-spaces ``normal . (v - point) >= 0``.
        points: (m, 3) m/s, a point on each plane.
        preferred: (3,) m/s.
        v_max: (3,) m/s per-axis limit (hard), or None.
        max_speed: m/s, radius of the speed sphere (default: |v_max|, or 1 m/s without limits).
        weights: (m,) > 0, when the half-spaces have no common velocity, half-space i's violation counts
            this many times (default: all alike, the paper's fallback).

    Returns:
        (velocity (3,) m/s, feasible). When infeasible: among the velocities whose largest
        violation of the half-spaces is smallest (the box still holds), the closest to ``preferred``.
    """
    normals = np.ascontiguousarray(normals, dtype=float).reshape(-1, 3)
    points = np.ascontiguousarray(points, dtype=float).reshape(-1, 3)
    vm = limits(v_max)
    m = normals.shape[0] + 6
    N, P = np.empty((m, 3)), np.empty((m, 3))
    n_hard = bound_planes(-vm[None, :], vm[None, :], 0, N, P)
    N[n_hard : n_hard + len(normals)] = normals
    P[n_hard : n_hard + len(normals)] = points
    W = np.ones(m)
    if weights is not None:
        w = np.asarray(weights, dtype=float).reshape(-1)
        if w.shape != (len(normals),) or not np.all(np.isfinite(w)) or not np.all(w > 0.0):
            raise ValueError(f"weights: expected {len(normals)} positive finite numbers, got {weights!r}")
        W[n_hard : n_hard + len(normals)] = w
    feasible, res = solve(
        N,
        P,
        n_hard + len(normals),
        n_hard,
        speed_sphere(vm, max_speed),
        vec3(preferred),
        np.empty((m, 3)),
        np.empty((m, 3)),
        W,
        weights is not None,
    )
    return np.array(res), bool(feasible)
