"""One planner tick of ORCA for all agents: the paper's core composed with the switched-on rules, one compiled call.

Per agent: the hard planes (velocity limits, narrowed by ``COLUMN_RULE``; then,
one plane per static obstacle within reach (the paper's; the ground is one), of which the agent takes the
whole u, as the paper's agents do with obstacles: never traded away by the fallback LP unless the
agent already overlaps the obstacle), one ORCA plane per neighbour (``core``; shapes grown by
``LAG_MARGIN``, the shares moved by the wake rules),
then either the command unchanged (``MINIMAL_INTERVENTION``) or the LP's velocity, which a
stalled agent may solve again with a bias (``DEADLOCK_RESOLUTION``, ``resolve_stall``).

Also here: the arrays the kernel is fed from commands and sensed state (neighbour table,
bounding boxes, preferred and commanded velocities).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from pybullet_swarm.planning.base import CommandKind
from pybullet_swarm.planning.orca import core, rules
from pybullet_swarm.planning.orca.cache import njit
from pybullet_swarm.planning.orca.params import OrcaParams, Shape
from pybullet_swarm.planning.orca.rules import Rule
from pybullet_swarm.planning.orca.vec import Vec, add, dot, row, scale, set_row

#: flags returned per agent by ``orca_velocities``
FLAG_INFEASIBLE = 1  # the ORCA planes had no common velocity: least-violating velocity used (core)
FLAG_BIASED = 2  # stalled: the sideways (or upward) bias was applied (DEADLOCK_RESOLUTION)
FLAG_FREE = 4  # the commanded velocity satisfies every plane: nothing was changed (MINIMAL_INTERVENTION)
FLAG_OBSTACLE = 16  # kept clear of at least one static obstacle within reach

HARD_PLANES = 6  # at most two velocity bounds per axis
GROUND_HALF = 1.0e3  # m, half extents of the slab whose top face is the ground (z = 0)
NO_BARE = (-1.0, -1.0, -1.0)  # box_u without MARGIN_OVERLAP


def core_settings(params: OrcaParams, v_max: NDArray[np.float64] | None) -> NDArray[np.void]:
    """The core's record (``core.SETTINGS``) for ``params`` and the per-axis limits ``v_max`` (3,) m/s."""
    s = np.zeros(1, dtype=core.SETTINGS)
    s["margin"] = params.margin
    s["inv_tau"] = 1.0 / params.time_horizon
    s["inv_rec"] = 1.0 / params.recovery_time
    s["responsibility"] = params.responsibility
    s["max_speed"] = core.speed_sphere(core.limits(v_max), params.max_speed)
    return s


@functools.lru_cache(maxsize=64)
def _settings(params: OrcaParams, v_max: tuple[float, ...] | None) -> tuple[NDArray[np.void], NDArray[np.void]]:
    """Both records of ``params`` (built once per parameter set and limits: a planner tick reuses them)."""
    return core_settings(params, None if v_max is None else np.array(v_max)), rule_settings(params)


def rule_settings(params: OrcaParams) -> NDArray[np.void]:
    """The rules' record (``rules.RULES``): every switch and the parameters the kernel reads."""
    s = np.zeros(1, dtype=rules.RULES)
    for r in Rule:
        s[r.value] = params.on(r)
    s["lag_margin_s"] = params.lag_margin_s
    s["headway_s"] = params.lag_margin_s if params.headway_s is None else params.headway_s
    s["time_horizon"] = params.time_horizon
    s["right_bias"] = params.right_bias
    s["stuck_fraction"] = params.stuck_fraction
    s["inv_tau_obstacle"] = 1.0 / params.obstacle_horizon
    s["goal_reach"] = params.goal_reach
    s["wake_depth"] = params.wake(downwash=False)  # the layer resolves a null depth against the run
    s["gap_floor"] = params.gap_floor
    return s


# ----------------------------------------------------------------------------- the compiled tick
@njit
def box_offset(a: int, b: int, pos: NDArray[np.float64], centre: NDArray[np.float64]) -> Vec:
    """m, the centre of agent b's box relative to agent a's."""
    return add(add(row(pos, b), row(centre, b), 1.0), add(row(pos, a), row(centre, a), 1.0), -1.0)


@njit
def pair_u(
    a: int,
    b: int,
    pos: NDArray[np.float64],
    vel: NDArray[np.float64],
    radius: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    boxes: bool,
    cs: np.record,
    rs: np.record,
) -> tuple[Vec, Vec, float]:
    """(n, u, gap) of agent a against agent b; agent b uses (-n, -u). ``gap`` (m) is how far apart the
    pair's bare shapes will be ``lag_margin_s`` later at their present closing speed (boxes: along the axis
    of the largest per-axis gap; negative: they overlap), for ``GAP_WEIGHTED_FALLBACK``."""
    v = add(row(vel, a), row(vel, b), -1.0)
    m2 = 2.0 * cs.margin
    on, lag, hw, hws = rs.lag_margin, rs.lag_margin_s, rs.headway, rs.headway_s
    if boxes:
        c = box_offset(a, b, pos, centre)
        g = (
            rules.approach_growth(on, lag, hw, hws, c[0], vel[a, 0], vel[b, 0]),
            rules.approach_growth(on, lag, hw, hws, c[1], vel[a, 1], vel[b, 1]),
            rules.approach_growth(on, lag, hw, hws, c[2], vel[a, 2], vel[b, 2]),
        )
        # the shapes that must not overlap: airframes, loads and the wake column (MARGIN_OVERLAP's bare
        # shapes: a pair in another's wake gets out sideways, not by a vertical half metre), then margins
        # and growths
        bare = (
            half[a, 0] + half[b, 0],
            half[a, 1] + half[b, 1],
            half[a, 2] + half[b, 2] + rules.wake_growth(rs.wake_column, rs.wake_depth),
        )
        H = (bare[0] + m2 + g[0], bare[1] + m2 + g[1], bare[2] + m2 + g[2])
        gap, k = core.box_gap(c, bare)
        gap -= lag * (v[k] if c[k] > 0.0 else -v[k])  # a lag later: a pair parting weighs less
        nrm, u = core.box_u(c, H, v, cs.inv_tau, cs.inv_rec, bare if rs.margin_overlap else NO_BARE)
        return nrm, u, gap
    p = add(row(pos, b), row(pos, a), -1.0)
    speed = math.sqrt(dot(v, v))
    grow = rules.lag_growth(on, lag, speed)
    if hw and on:
        d = math.sqrt(dot(p, p))
        if d > 0.0:
            va, vb = dot(row(vel, a), p) / d, dot(row(vel, b), p) / d  # radial speeds, towards b
            grow = max(grow, rules.approach_growth(on, lag, hw, hws, 1.0, va, vb))
    R = radius[a] + radius[b] + m2 + grow
    nrm, u = core.sphere_u(p, v, R, cs.inv_tau, cs.inv_rec)
    d = math.sqrt(dot(p, p))
    closing = dot(v, p) / d if d > 0.0 else 0.0
    return nrm, u, d - radius[a] - radius[b] - lag * closing


@njit
def agent_planes(
    i: int,
    pos: NDArray[np.float64],
    vel: NDArray[np.float64],
    radius: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    boxes: bool,
    nbr: NDArray[np.int64],
    cs: np.record,
    rs: np.record,
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    W: NDArray[np.float64],
    k: int,
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
) -> int:
    """Append agent i's ORCA planes (one per neighbour in row i of ``nbr``) after row k; returns the new
    count. ``W`` gets each plane's weight in the fallback (``GAP_WEIGHTED_FALLBACK``).

    A pair's (n, u) is computed once in index order and negated for the other agent, so both
    halves match to the last bit.
    """
    n = pos.shape[0]
    vi = row(vel, i)
    m2 = 2.0 * cs.margin
    for c in range(nbr.shape[1]):
        j = nbr[i, c]
        if j < 0 or j >= n or j == i:
            continue
        if i < j:
            nrm, u, gap = pair_u(i, j, pos, vel, radius, centre, half, boxes, cs, rs)
        else:
            nrm, u, gap = pair_u(j, i, pos, vel, radius, centre, half, boxes, cs, rs)
            nrm = scale(nrm, -1.0)
            u = scale(u, -1.0)
        r = cs.responsibility
        if boxes and rs.wake_column and rs.wake_depth > 0.0:
            d = add(row(pos, j), row(pos, i), -1.0)
            dn = math.sqrt(dot(d, d))
            towards = dot(vi, d) / dn if dn > 0.0 else 0.0
            away = -dot(row(vel, j), d) / dn if dn > 0.0 else 0.0
            r = rules.wake_share(
                r,
                pos[j, 2] + centre[j, 2] - pos[i, 2] - centre[i, 2],
                half[i, 2] + half[j, 2] + m2,
                cs.responsibility,
                rs.wake_share_by_approach,
                towards,
                away,
                not rs.wake_share_on_course or dot(nrm, u) > 0.0,
            )
        r = rules.pinned_share(rs.pinned_share, u, lo, hi, i, j, r, cs.responsibility)
        set_row(N, k, nrm)
        set_row(P, k, add(vi, u, r))
        W[k] = rules.gap_weight(gap, rs.gap_floor)
        k += 1
    return k


@njit
def obstacle_planes(
    i: int,
    pos: NDArray[np.float64],
    vel: NDArray[np.float64],
    radius: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    boxes: bool,
    oc: NDArray[np.float64],
    oh: NDArray[np.float64],
    goal: NDArray[np.float64],
    has_goal: NDArray[np.bool_],
    parts: NDArray[np.float64],
    cs: np.record,
    rs: np.record,
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    W: NDArray[np.float64],
    k: int,
    n_box: int,
) -> tuple[int, int, bool]:
    """Static obstacles (the paper's): append agent i's planes against the static obstacles (``oc``, ``oh``) after row k;
    returns (the end of the hard planes, the end of all, whether one of the first ``n_box`` (the boxes; the rest:
    the ground) gave a plane).

    The paper's obstacles: the VO of the agent's shape and the obstacle's box (the agent's margin
    only: an obstacle's place is known; shapes grown by ``LAG_MARGIN`` with the agent's own speed)
    truncated at the obstacle horizon, and the agent takes the whole u (the obstacle does not move).
    Left out: obstacles out of reach within the horizon at the speed sphere's radius (no velocity
    the LP may choose enters their VO) and the target's own (``rules.own_target``).
    The planes of obstacles the agent is clear of are hard: zero velocity satisfies all of them and
    the bounds. Those of obstacles it already overlaps (within the margin: knocked against one, or
    just off its target's own) follow them, soft: a recovery plane may contradict the bounds, and
    the fallback LP then moves the agent as far out as the bounds let it, the way it prefers.
    """
    vi = row(vel, i)
    on, lag = rs.lag_margin, rs.lag_margin_s
    reach = cs.max_speed / rs.inv_tau_obstacle  # m, the farthest any velocity of the LP goes within the horizon
    n_hard = k
    near_box = False
    for overlapping in (False, True):
        for o in range(oc.shape[0]):
            c, H0 = rules.obstacle_shape(i, pos, radius, centre, half, boxes, oc, oh, o)
            H = (
                H0[0] + cs.margin + rules.lag_growth(on, lag, abs(vi[0])),
                H0[1] + cs.margin + rules.lag_growth(on, lag, abs(vi[1])),
                H0[2] + cs.margin + rules.lag_growth(on, lag, abs(vi[2])),
            )
            gap, _ = core.box_gap(c, H)
            if gap > reach or (gap <= 0.0) != overlapping:
                continue
            if has_goal[i] and rules.own_target(i, o, pos, goal, parts, oc, oh, cs.margin + rs.goal_reach):
                continue
            nrm, u = core.box_u(c, H, vi, rs.inv_tau_obstacle, cs.inv_rec, H0 if rs.margin_overlap else NO_BARE)
            set_row(N, k, nrm)
            set_row(P, k, add(vi, u, 1.0))
            W[k] = rules.gap_weight(core.box_gap(c, H0)[0], rs.gap_floor)
            k += 1
            near_box = near_box or o < n_box
        if not overlapping:
            n_hard = k
    return n_hard, k, near_box


@njit
def resolve_stall(
    i: int,
    pos: NDArray[np.float64],
    radius: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    boxes: bool,
    nbr: NDArray[np.int64],
    goal: NDArray[np.float64],
    has_goal: NDArray[np.bool_],
    oc: NDArray[np.float64],
    oh: NDArray[np.float64],
    parts: NDArray[np.float64],
    pr: Vec,
    sp: float,
    obstacles_near: bool,
    cs: np.record,
    rs: np.record,
    N: NDArray[np.float64],
    P: NDArray[np.float64],
    SN: NDArray[np.float64],
    SP: NDArray[np.float64],
    W: NDArray[np.float64],
    m: int,
    n_hard: int,
    weighted: bool,
    res: Vec,
    f: int,
) -> tuple[Vec, int]:
    """DEADLOCK_RESOLUTION, the deadlock stage: a new velocity and flags for agent i, stalled (its LP velocity
    ``res`` makes progress below ``stuck_fraction`` of its preferred speed ``sp`` along ``pr``).

    One mechanism: find what holds the agent up (``rules.stalled_by``: the nearest neighbour ahead in its
    way that does not sit on its goal, which is waited for; or, with none, the nearest static obstacle
    ahead), then solve again with the preferred velocity biased by ``right_bias`` x ``sp`` sideways, to
    the side the one in the way leaves free (``rules.sidestep``). When the biased velocity is still held, or takes the agent backwards and hardly sideways (ORCA linearises
    about present velocities: an agent pushed back at the speed of one flying at it keeps retreating),
    the agent asks for the sideways step alone.
    """
    stuck, right_bias = rs.stuck_fraction, rs.right_bias
    wake = rules.wake_growth(rs.wake_column and boxes, rs.wake_depth)
    j = rules.stalled_by(
        i, pos, pr, sp, radius, centre, half, boxes, nbr, goal, has_goal[i], 2.0 * cs.margin, rs.time_horizon, wake
    )
    held = False
    side = (0.0, 0.0, 0.0)
    if j >= 0:
        held = True
        side = rules.sidestep(scale(pr, 1.0 / sp), add(row(pos, j), row(pos, i), -1.0))
    elif obstacles_near:
        held, side = rules.obstacle_in_way(
            i, pos, radius, centre, half, boxes, oc, oh, goal, has_goal[i], parts, scale(pr, 1.0 / sp),
            sp / rs.inv_tau_obstacle, cs.margin, cs.margin + rs.goal_reach,
        )  # fmt: skip
    if not held:
        return res, f
    feasible, out = core.solve(N, P, m, n_hard, cs.max_speed, add(pr, side, right_bias * sp), SN, SP, W, weighted)
    if (dot(out, pr) < 0.0 and dot(out, side) < stuck * sp) or dot(out, out) < stuck * stuck * sp * sp:
        # still held (the bias cancelled what the neighbours' planes left free: a box VO leaves the axis
        # across the blocking face free, and the bias can exactly cancel the preferred velocity along it),
        # or pushed backwards and hardly sideways: ask for the sideways step alone
        feasible, out = core.solve(N, P, m, n_hard, cs.max_speed, scale(side, sp), SN, SP, W, weighted)
    return out, FLAG_BIASED | (0 if feasible else FLAG_INFEASIBLE)


@njit
def orca_batch(
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
    oc: NDArray[np.float64],
    oh: NDArray[np.float64],
    parts: NDArray[np.float64],
    n_box: int,
    core_rec: NDArray[np.void],
    rule_rec: NDArray[np.void],
    out: NDArray[np.float64],
    flags: NDArray[np.int64],
) -> None:
    """Safe velocities of all agents (see ``orca_velocities``; the obstacles after the first ``n_box``: the ground)."""
    cs = core_rec[0]
    rs = rule_rec[0]
    n = pos.shape[0]
    static = oc.shape[0] > 0
    m_max = nbr.shape[1] + HARD_PLANES + (oc.shape[0] if static else 0)
    N = np.empty((m_max, 3))
    P = np.empty((m_max, 3))
    SN = np.empty((m_max, 3))
    SP = np.empty((m_max, 3))
    W = np.ones(m_max)
    weighted = rs.gap_weighted_fallback
    max_speed, stuck = cs.max_speed, rs.stuck_fraction
    stall_on = rs.deadlock_resolution and rs.right_bias > 0.0
    box_c, box_h = oc[:n_box], oh[:n_box]  # what a stalled agent may find in its way: the ground never is
    for i in range(n):
        n_bounds = core.bound_planes(lo, hi, i, N, P)
        n_hard = n_static = n_bounds
        near_box = False
        if static:
            n_hard, n_static, near_box = obstacle_planes(
                i, pos, vel, radius, centre, half, boxes, oc, oh, goal, has_goal, parts, cs, rs, N, P, W, n_bounds,
                n_box,
            )  # fmt: skip
        m = agent_planes(i, pos, vel, radius, centre, half, boxes, nbr, cs, rs, N, P, W, n_static, lo, hi)
        up = FLAG_OBSTACLE if near_box else 0
        vc = row(v_cmd, i)
        if rs.minimal_intervention and dot(vc, vc) <= max_speed * max_speed and not core.violates(N, P, m, vc):
            set_row(out, i, vc)  # nothing to avoid: the planner's command stands
            flags[i] = FLAG_FREE | up
            continue
        pr = row(pref, i)
        feasible, res = core.solve(N, P, m, n_hard, max_speed, pr, SN, SP, W, weighted)
        f = 0 if feasible else FLAG_INFEASIBLE
        sp = math.sqrt(dot(pr, pr))
        if stall_on and sp > rules.MIN_PREFERRED_SPEED and dot(res, pr) < stuck * sp * sp:
            res, f = resolve_stall(
                i, pos, radius, centre, half, boxes, nbr, goal, has_goal, box_c, box_h, parts, pr, sp,
                near_box, cs, rs, N, P, SN, SP, W, m, n_hard, weighted, res, f,
            )  # fmt: skip
        set_row(out, i, res)
        flags[i] = f | up


# ----------------------------------------------------------------------------- array API
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
    obstacles: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    parts: NDArray[np.float64] | None = None,
    ground: bool = False,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Collision-avoiding velocities of all agents from sensed state (one compiled call).

    Args:
        positions: (n, 3) m, sensed.
        velocities: (n, 3) m/s, the velocities ORCA linearises about (see ``rules.reference_velocities``).
        preferred: (n, 3) m/s, each agent's preferred velocity.
        params: layer parameters (``params.shape`` says which of ``radii`` / ``boxes`` is used;
            ``params.margin`` is added to either; the rule switches say which rules act).
        sensing_radius: m, only neighbours within it are considered.
        v_max: (3,) m/s per-axis limit, or None.
        radii: (n,) m, sphere radius of each agent (needed for ``Shape.SPHERE``).
        boxes: (centre offsets (n, 3) m, half extents (n, 3) m) of each agent's bounding box (see
            ``bounding_boxes``; needed for ``Shape.BOX``).
        goals: (n, 3) m, position targets (only used to tell "a neighbour on my goal" from "in my way").
        has_goal: (n,) True where ``goals`` holds a target.
        bounds: (lower (n, 3), upper (n, 3)) m/s, hard per-axis bounds of each agent's velocity
            (default: the velocity limits; see ``rules.velocity_bounds``).
        commanded: (n, 3) m/s, the velocity each agent's own command would give it (default:
            ``preferred``). With ``MINIMAL_INTERVENTION`` an agent whose commanded velocity
            satisfies all its planes is left alone (flag ``FLAG_FREE``, returned velocity =
            commanded); the others get the LP's velocity closest to ``preferred``.
        neighbours: (n, k) neighbour table from ``neighbour_table`` (computed when None).
        obstacles: (centres (K, 3) m, half extents (K, 3) m) of static axis-aligned boxes, avoided
            as the paper avoids obstacles (none when None); an agent's target's own (``rules.own_target``:
            touched by the agent at its goal, ``goals`` and ``has_goal``) is left out for it.
        parts: (n, 12) airframe and load boxes of each agent (``shape_parts``), which tell the
            target's own obstacles (default: each agent's shape as one part).
        ground: the ground (z = 0) is one more static obstacle, avoided the same way (a slab under the
            whole arena, ``GROUND_HALF``): an agent is neither pushed into it nor flies into it within the
            obstacle horizon, unless it is its target's own (a load placed on the ground). It is never
            what holds up a stalled agent (``DEADLOCK_RESOLUTION`` looks at the boxes only) and sets no
            ``FLAG_OBSTACLE``.

    Returns:
        (velocities (n, 3) m/s, flags (n,) of ``FLAG_INFEASIBLE | FLAG_BIASED | FLAG_FREE |
        FLAG_OBSTACLE``).
    """
    pos = np.ascontiguousarray(positions, dtype=float)
    n = pos.shape[0]
    vm = core.limits(v_max)
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
    if obstacles is None:
        oc = oh = np.zeros((0, 3))
    else:
        oc, oh = (np.ascontiguousarray(b, dtype=float).reshape(-1, 3) for b in obstacles)
    n_box = len(oc)
    if ground:
        oc = np.vstack([oc, [[0.0, 0.0, -GROUND_HALF]]])
        oh = np.vstack([oh, np.full((1, 3), GROUND_HALF)])
    if parts is None:
        parts = np.zeros((n, 12))
        parts[:, :3] = centre
        parts[:, 3:6] = half if use_boxes else radius[:, None]
    out = np.empty((n, 3))
    flags = np.zeros(n, dtype=np.int64)
    core_rec, rule_rec = _settings(params, None if v_max is None else tuple(map(float, vm)))
    orca_batch(
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
        oc,
        oh,
        np.ascontiguousarray(parts, dtype=float).reshape(n, 12),
        n_box,
        core_rec,
        rule_rec,
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


def shape_parts(
    quaternions: NDArray[np.float64],
    half_extent: NDArray[np.float64],
    carrying: NDArray[np.bool_],
    box_size: float,
    box_drop: float,
) -> NDArray[np.float64]:
    """World-axis boxes of each airframe and of the box it carries, from sensed attitudes.

    Args:
        quaternions: (n, 4) (x, y, z, w).
        half_extent: (3,) m, half the airframe's collision box.
        carrying: (n,) True where an agent holds a box.
        box_size: m, edge of a box.
        box_drop: m, box centre below the agent centre in the body frame.

    Returns:
        (n, 12): per agent the airframe's centre offset from the agent's position (3,) m (zero) and
        half extents (3,) m, then the load's centre offset and half extents (zero without a load).
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
    out = np.zeros((len(quaternions), 12))
    out[:, 3:6] = absR @ half_extent
    if np.any(carrying):
        out[carrying, 6:9] = -box_drop * R[carrying, :, 2]  # box centre offset, world frame
        out[carrying, 9:12] = absR[carrying] @ np.full(3, 0.5 * box_size)
    return out


def bounding_boxes(
    quaternions: NDArray[np.float64],
    half_extent: NDArray[np.float64],
    carrying: NDArray[np.bool_],
    box_size: float,
    box_drop: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """World-axis bounding boxes of airframes (and hanging boxes) from sensed attitudes (see ``shape_parts``).

    Returns:
        (centre offsets (n, 3) m from each agent's position, half extents (n, 3) m).
    """
    return union_boxes(shape_parts(quaternions, half_extent, carrying, box_size, box_drop))


def union_boxes(parts: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The box around each agent's parts (n, 12) (``shape_parts``): (centre offsets (n, 3) m, half extents (n, 3) m)."""
    half = parts[:, 3:6]
    lo, hi = -half, half.copy()
    load = parts[:, 9] > 0.0
    if np.any(load):
        c, h = parts[:, 6:9], parts[:, 9:12]
        lo = np.where(load[:, None], np.minimum(lo, c - h), lo)
        hi = np.where(load[:, None], np.maximum(hi, c + h), hi)
    return np.ascontiguousarray(0.5 * (lo + hi)), np.ascontiguousarray(0.5 * (hi - lo))
