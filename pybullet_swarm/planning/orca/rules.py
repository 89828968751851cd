"""The extension rules on top of the paper's ORCA, each named, documented in one line and switched alone.

Each is a ``Rule`` whose value is its switch in ``OrcaParams`` (all on by default; ``preset: paper``
switches every one off, leaving the paper's ORCA); ``RULE_DOCS`` gives each its line, which is also
the switch's description, and ``REQUIRES`` the rule each patch acts through. The functions below
that carry out a rule name it first in their docstring. The compiled kernel reads the switches and
the rules' parameters from one ``RULES`` record. The package notes order the rules by stage.
"""

from __future__ import annotations

import enum
import math

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.orca.cache import njit
from pybullet_swarm.planning.orca.core import right_of
from pybullet_swarm.planning.orca.vec import Vec, add, dot, row, scale


class Rule(str, enum.Enum):
    """An extension of the paper's ORCA; the value is its switch in ``OrcaParams``."""

    LAG_MARGIN = "lag_margin"
    UNCERTAINTY_MARGIN = "uncertainty_margin"
    CLIPPED_REFERENCE = "clipped_reference"
    COLUMN_RULE = "column_rule"
    MINIMAL_INTERVENTION = "minimal_intervention"
    PASSTHROUGH = "passthrough"
    DEADLOCK_RESOLUTION = "deadlock_resolution"
    WAKE_COLUMN = "wake_column"
    WAKE_SHARE_BY_APPROACH = "wake_share_by_approach"
    HEADWAY = "headway"
    WAKE_SHARE_ON_COURSE = "wake_share_on_course"
    MARGIN_OVERLAP = "margin_overlap"
    PASSTHROUGH_TURNS = "passthrough_turns"
    PINNED_SHARE = "pinned_share"
    GAP_WEIGHTED_FALLBACK = "gap_weighted_fallback"

    @property
    def doc(self) -> str:
        """What the rule does, in one line."""
        return RULE_DOCS[self]


RULE_DOCS: dict[Rule, str] = {
    Rule.LAG_MARGIN: "a pair's shapes grow by lag_margin_s times its closing speed: airframes follow a new "
    "velocity late and overshoot it",
    Rule.UNCERTAINTY_MARGIN: "flying on estimates, shapes grow by uncertainty_sigmas standard deviations of a "
    "pair's relative position error",
    Rule.CLIPPED_REFERENCE: "ORCA linearises about the sensed velocity clipped to the velocity limits: overshoots "
    "are not motion to answer",
    Rule.COLUMN_RULE: "below floor_height an agent within column_radius of its target (horizontally) is only "
    "slowed or lifted, never moved sideways",
    Rule.MINIMAL_INTERVENTION: "an agent whose own command violates none of its half-spaces keeps the command "
    "(off: every agent flies the LP's velocity)",
    Rule.PASSTHROUGH: "a POSITION/HOLD command within capture_radius passes unchanged when the agent's swept box "
    "stays clear of every neighbour's",
    Rule.DEADLOCK_RESOLUTION: "a stalled agent steps aside, to the side the one in its way leaves free, and waits "
    "for one sitting on its goal",
    Rule.WAKE_COLUMN: "against other agents each agent's box reaches wake_depth further down: nobody flies in "
    "another's rotor wake (downwash)",
    Rule.WAKE_SHARE_BY_APPROACH: "a wake conflict is resolved by the agent moving into it, in proportion to "
    "the pair's approach speeds (off: the upper one)",
    Rule.HEADWAY: "lag_margin also counts either agent's own speed towards the other (headway_s): the one ahead "
    "may stop without warning",
    Rule.WAKE_SHARE_ON_COURSE: "a wake pair's unequal shares apply on a collision course only; off it each keeps half "
    "the freedom",
    Rule.MARGIN_OVERLAP: "overlapping boxes recover along the least overlap of the axes on which the bare shapes "
    "are apart",
    Rule.PASSTHROUGH_TURNS: "passthrough to a waypoint (a target touching nothing) needs clearance from what each "
    "neighbour can reach by turning",
    Rule.PINNED_SHARE: "against a neighbour that its bounds pin on the axis the pair's way out mostly runs along, "
    "an agent takes the whole way out",
    Rule.GAP_WEIGHTED_FALLBACK: "with no common velocity, a plane's violation counts 1 / its pair's gap a lag later "
    "times: the nearest is closed on last",
}

#: rule -> the rule it patches: it acts only through that one, and is refused on while that one is off
REQUIRES: dict[Rule, Rule] = {
    Rule.HEADWAY: Rule.LAG_MARGIN,
    Rule.PASSTHROUGH_TURNS: Rule.PASSTHROUGH,
    Rule.WAKE_SHARE_BY_APPROACH: Rule.WAKE_COLUMN,
    Rule.WAKE_SHARE_ON_COURSE: Rule.WAKE_COLUMN,
}

#: the rules' switches and parameters as the kernels read them (one record)
RULES = np.dtype(
    [(r.value, np.bool_) for r in Rule]
    + [
        ("lag_margin_s", np.float64),  # s, shapes grow by this times the closing speed
        ("headway_s", np.float64),  # s, (HEADWAY) the time headway of a pair flying the same way, one behind
        ("time_horizon", np.float64),  # s, how far ahead a neighbour counts as in the way
        ("right_bias", np.float64),  # fraction of the preferred speed added sideways to a stalled agent
        ("stuck_fraction", np.float64),  # progress below this fraction of the preferred speed is a stall
        ("inv_tau_obstacle", np.float64),  # 1/s, inverse time horizon of static obstacles
        ("goal_reach", np.float64),  # m, an obstacle this close to the agent's shape at its target is the target's
        ("wake_depth", np.float64),  # m, how far below each agent's box its wake is kept clear of others
        ("gap_floor", np.float64),  # m, (GAP_WEIGHTED_FALLBACK) pairs nearer than this weigh alike
    ],
    align=True,
)

APPROACH_SPEED = 0.02  # m/s, a pair closing in slower than this is at rest (WAKE_SHARE_BY_APPROACH)
SIDE_OFFSET = 0.01  # m, a neighbour ahead further than this to one side has already chosen its side
HORIZONTAL_MIN2 = 1e-6  # squared horizontal part of a unit direction below which it counts as vertical
BESIDE_MIN2 = 1e-4  # m^2, a neighbour horizontally closer than 1 cm is right above or below
MIN_PREFERRED_SPEED = 1e-3  # m/s, an agent that prefers to move slower than this is at rest: never stalled
PIN_TOL = 1e-9  # m/s, velocity bounds narrower than this on an axis pin the agent on it (PINNED_SHARE)
GOAL_OVERLAP = 0.005  # m, a part of an agent at its target reaching deeper into an obstacle is inside it


# ----------------------------------------------------------------------------- margins and the way out
@njit
def gap_weight(gap: float, floor: float) -> float:
    """GAP_WEIGHTED_FALLBACK: the weight of a plane whose pair's bare shapes will be ``gap`` (m) apart a lag
    (``lag_margin_s``) later at their closing speed, 1/m; pairs nearer than ``floor`` (m, > 0; overlapping ones
    too) weigh alike, as if ``floor`` apart.

    Violating a plane by dv (m/s) closes the pair's gap dv faster than ORCA allows; weighing it by
    1/gap makes the fallback maximise the shortest time in which any such extra closing eats up its
    pair's gap (rather than the paper's, which spreads one violation over near and far alike). The
    gap a lag later, not the present one: with the present gap an agent squeezed in a row flees the
    nearer neighbour into the other, back and forth.
    """
    return 1.0 / max(gap, floor)


@njit
def lag_growth(on: bool, lag_margin_s: float, closing_speed: float) -> float:
    """LAG_MARGIN: m a pair's shapes grow by at ``closing_speed`` m/s (per axis for boxes, radially for spheres)."""
    return lag_margin_s * closing_speed if on else 0.0


@njit
def approach_growth(
    on: bool, lag_margin_s: float, headway: bool, headway_s: float, d: float, v_self: float, v_other: float
) -> float:
    """LAG_MARGIN's growth along one direction, m: ``lag_margin_s`` x the closing speed |v_self - v_other|;
    with ``HEADWAY`` that speed is at least either agent's own speed towards the other (``d``: the other's
    side of this one, its sign alone counts), and a pair flying the same way, one behind the other, grows
    by (``headway_s`` - ``lag_margin_s``) x the speed they share besides. ORCA assumes neighbours keep their
    velocity; a follower at the same speed closes in at its own speed the moment the one ahead stops for
    its target, and answers a lag later. A line of followers damps such a stop down the line only when
    their spacing is a time headway of more than twice that lag (string stability of a platoon under a
    constant time-headway policy): a follower at the speed of the one ahead keeps ``headway_s`` x that
    speed; one closing on an agent at rest, ``lag_margin_s`` x its speed, as with no line to damp."""
    if not on:
        return 0.0
    s = abs(v_self - v_other)
    if not headway:
        return lag_margin_s * s
    sign = 1.0 if d >= 0.0 else -1.0
    g = lag_margin_s * max(s, v_self * sign, -v_other * sign)
    if v_self * v_other > 0.0 and headway_s > lag_margin_s:
        g += (headway_s - lag_margin_s) * min(abs(v_self), abs(v_other))
    return g


@njit
def wake_growth(on: bool, wake_depth: float) -> float:
    """WAKE_COLUMN: m the vertical half extent of a pair's Minkowski box grows by.

    Each agent's box reaches ``wake_depth`` further down, against other agents only: its rotor
    wake (``vehicle/downwash.py``, a turbulent jet whose centreline velocity falls as 1 / z) pushes
    down whoever flies in it, with a force that falls slowly with depth (quad150: 29 % of the
    weight 0.1 m below, 17 % 1 m below), and a vehicle pushed down near the ground, a box or the
    structure strikes it. Growing both boxes downwards by D leaves the pair's relative
    centre where it was and grows the Minkowski box's vertical half extent by D: neither agent
    may be within D under the other while they overlap horizontally.
    """
    return wake_depth if on else 0.0


@njit
def wake_share(
    share: float,
    dz: float,
    reach: float,
    resp: float,
    by_approach: bool,
    towards: float,
    away: float,
    on_course: bool = True,
) -> float:
    """WAKE_COLUMN: share of a pair's u this agent takes, when the other's shape is ``dz`` m above its own
    (centres) and the two touch vertically within ``reach`` m (half heights and margins, no wake).

    A pair whose shapes are apart vertically is in conflict only through the upper one's wake. Only
    the upper one can keep its wake off the other: it takes the whole share, the lower one none.
    Shared, the lower agent would be pushed ahead of the upper one for as long as their paths agree
    (a carrier herded back across the arena by an agent flying home above it). With ``by_approach``
    (``WAKE_SHARE_BY_APPROACH``) the pair's share goes to whichever of the two moves into the
    conflict, in proportion to their speeds towards each other (``towards``: this agent's m/s
    towards the other, ``away``: the other's towards this one), the upper one's whole share only
    when neither does: an agent flying into a wake yields as one flying its wake over another does
    (upper-takes-all, a lower agent closing in pushed the upper one ahead of it, into a third).
    Both agents see the same numbers, so the shares still add up. ``on_course`` False
    (``WAKE_SHARE_ON_COURSE``: the relative velocity lies outside the VO, u leads into it): u is then
    the freedom the pair has left, not avoidance to do, and each keeps ``share`` of it; the upper one
    taking all of it froze the lower one along the pair's normal (it could neither climb away from
    a release nor undo a drift that ORCA's own plane kept going).
    """
    if abs(dz) < reach or not on_course:
        return share
    if by_approach:
        a, b = max(towards, 0.0), max(away, 0.0)
        if a + b > APPROACH_SPEED:
            return 2.0 * resp * a / (a + b)
    return 2.0 * resp if dz < 0.0 else 0.0


def uncertainty_growth(sigmas: float, position_std: float) -> float:
    """UNCERTAINTY_MARGIN: m each shape grows by when sensed positions err by ``position_std`` m per axis.

    A pair's relative position errs by sqrt(2) times that; each of the two shapes takes half of it.
    """
    return sigmas * math.sqrt(2.0) * position_std / 2.0


def reference_velocities(
    velocities: NDArray[np.float64], v_max: NDArray[np.float64] | None, on: bool
) -> NDArray[np.float64]:
    """CLIPPED_REFERENCE: the velocities (n, 3) m/s ORCA linearises about, from the sensed ones."""
    if not on or v_max is None:
        return velocities
    return np.clip(velocities, -v_max, v_max)


@njit
def pinned_share(
    on: bool, u: Vec, lo: NDArray[np.float64], hi: NDArray[np.float64], i: int, j: int, r: float, resp: float
) -> float:
    """PINNED_SHARE: the share of the pair's ``u`` agent i takes against neighbour j: the whole when j's velocity
    bounds forbid it any velocity along -``u`` on the horizontal axis along which ``u`` mostly runs (``COLUMN_RULE``:
    on a leg over a box or the structure it may only slow down, never move sideways away) and i's allow it velocity
    along ``u`` there, else ``r``: a pinned neighbour cannot take its half."""
    if not on:
        return r
    a = 0 if abs(u[0]) >= abs(u[1]) else 1
    if u[a] == 0.0:
        return r
    if u[a] > 0.0:  # j would have to move along -axis a, i along +axis a
        pinned, free = lo[j, a] >= -PIN_TOL, hi[i, a] > PIN_TOL
    else:
        pinned, free = hi[j, a] <= PIN_TOL, lo[i, a] < -PIN_TOL
    return 2.0 * resp if pinned and free else r


# ----------------------------------------------------------------------------- hard bounds
def velocity_bounds(
    positions: NDArray[np.float64],
    intended: NDArray[np.float64],
    v_max: NDArray[np.float64] | None,
    *,
    floor_height: float,
    goals: NDArray[np.float64] | None = None,
    has_goal: NDArray[np.bool_] | None = None,
    column: float = 0.0,
    beside: NDArray[np.bool_] | None = None,
    column_tick: float | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """COLUMN_RULE: hard per-axis bounds (lower (n, 3), upper (n, 3)) m/s of each agent's velocity.

    The velocity limits bound everything. And (``column`` > 0) an agent low down (below ``floor_height``)
    on a vertical leg to or from its target (horizontally within ``column`` of it: descending to grasp or
    place, climbing away) is over a box, the structure or the ground, where a sideways dodge tilts the
    airframe into it: avoidance may only slow it down or lift it, not move it sideways. ``beside`` (n,)
    limits the column rule to the agents it marks (``obstacles_beside``: a box, the structure or the
    ground within reach); None: every agent on a leg. The ground itself is a static obstacle
    (``kernel.orca_velocities``, ``ground``), not a bound.

    Args:
        positions: (n, 3) m, sensed.
        intended: (n, 3) m/s, the velocity each agent's command asks for (``commanded_velocities``).
        v_max: (3,) m/s per-axis limit, or None.
        floor_height: m, the column rule holds agents below it.
        goals: (n, 3) m, position targets; ``has_goal`` (n,) says which hold one.
        column: m, horizontal radius of a vertical leg (0: no column rule).
        beside: (n,) bool, the agents the column rule may hold, or None (all).
        column_tick: s, given, the column rule lets through no more sideways speed than reaches the target's
            column in this time: the layer's velocity is held for a planner tick, while the shaped command's
            speed over a few millimetres (``sqrt(2 a_max |e|)``) is meant for one shaper tick.
    """
    n = len(positions)
    vm = np.full(3, np.inf) if v_max is None else np.broadcast_to(np.asarray(v_max, dtype=float), (3,)).copy()
    lo, hi = np.tile(-vm, (n, 1)), np.tile(vm, (n, 1))
    if goals is not None and has_goal is not None and column > 0.0:
        e = goals - positions
        leg = has_goal & (np.hypot(e[:, 0], e[:, 1]) <= column) & (positions[:, 2] < floor_height)
        if beside is not None:
            leg &= beside
        side = intended[leg, :2]
        if column_tick is not None:
            reach = np.abs(e[leg, :2]) / column_tick
            side = np.clip(side, -reach, reach)
        lo[leg, :2] = np.minimum(side, 0.0)
        hi[leg, :2] = np.maximum(side, 0.0)
    return lo, hi


def obstacles_beside(
    positions: NDArray[np.float64],
    centres: NDArray[np.float64],
    halves: NDArray[np.float64],
    obstacle_centres: NDArray[np.float64],
    obstacle_halves: NDArray[np.float64],
    reach: float,
) -> NDArray[np.bool_]:
    """(n,) bool: agents with a static obstacle within ``reach`` m of their shape horizontally, not wholly above it,
    or with the ground within ``reach`` m under it.

    The column rule's premise: a sideways dodge tilts the airframe (or swings its load) into a box or the
    structure beside or under it, or drags a load still resting on the ground. Each agent's shape is its
    union box (``centres`` offsets (n, 3) m from ``positions``, ``halves`` (n, 3) m); obstacles are
    axis-aligned boxes (m, 3) / (m, 3) m; the ground is z = 0.
    """
    c = positions + centres
    low = c[:, 2] - halves[:, 2] < reach
    if len(obstacle_centres) == 0 or len(positions) == 0:
        return np.asarray(low)
    d = np.abs(c[:, None, :2] - obstacle_centres[None, :, :2])
    near = np.all(d < halves[:, None, :2] + obstacle_halves[None, :, :2] + reach, axis=2)
    top = c[:, 2] + halves[:, 2]
    near &= (obstacle_centres[None, :, 2] - obstacle_halves[None, :, 2]) < top[:, None]
    return np.asarray(near.any(axis=1) | low)


# ----------------------------------------------------------------------------- stalls
@njit
def overlap(
    pa: Vec,
    pb: Vec,
    ra: float,
    rb: float,
    ca: Vec,
    cb: Vec,
    ha: Vec,
    hb: Vec,
    boxes: bool,
    grow: float,
    wake: float = 0.0,
) -> bool:
    """True when shape a at pa and shape b at pb come closer than ``grow`` m (boxes: ``wake`` m more vertically)."""
    if boxes:
        for k in range(3):
            if abs((pb[k] + cb[k]) - (pa[k] + ca[k])) >= ha[k] + hb[k] + grow + (wake if k == 2 else 0.0):
                return False
        return True
    d = add(pb, pa, -1.0)
    return dot(d, d) < (ra + rb + grow) ** 2


@njit
def stalled_by(
    i: int,
    pos: NDArray[np.float64],
    pref: Vec,
    sp: float,
    radius: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    boxes: bool,
    nbr: NDArray[np.int64],
    goal: NDArray[np.float64],
    has_goal: bool,
    margin2: float,
    tau: float,
    wake: float,
) -> int:
    """DEADLOCK_RESOLUTION: who holds up stalled agent i.

    Returns the nearest neighbour ahead (reachable at speed ``sp`` m/s over ``tau`` s, shapes grown
    by ``margin2`` m, and vertically by ``wake`` m: ``WAKE_COLUMN``) that is in the way and does
    not sit on i's goal (its wake column included), or -1. A neighbour on the goal is waited for:
    circling one that is about to leave would not help.
    """
    n = pos.shape[0]
    pi = row(pos, i)
    dh = scale(pref, 1.0 / sp)
    for c in range(nbr.shape[1]):  # nearest first
        j = nbr[i, c]
        if j < 0 or j >= n or j == i:
            continue
        rel = add(row(pos, j), pi, -1.0)
        if dot(rel, dh) <= 0.0:
            continue
        pj = row(pos, j)
        ci, cj, hi, hj = row(centre, i), row(centre, j), row(half, i), row(half, j)
        if not overlap(pi, pj, radius[i], radius[j], ci, cj, hi, hj, boxes, margin2 + sp * tau, wake):
            continue
        if has_goal and overlap(row(goal, i), pj, radius[i], radius[j], ci, cj, hi, hj, boxes, margin2, wake):
            continue  # the neighbour occupies the goal: wait, do not circle it
        return j
    return -1


@njit
def sidestep(d: Vec, rel: Vec) -> Vec:
    """DEADLOCK_RESOLUTION: horizontal unit direction across unit direction ``d``, to pass a neighbour at ``rel`` m.

    The side a neighbour already a little to one side (more than 1 cm) leaves free, at any bearing,
    rather than crossing in front of it; to the right (``right_of``) when it is dead ahead: when
    everyone keeps right, a crowd turns into a roundabout. Both agents of a pair see mirrored
    numbers and so pick opposite sides. Travelling vertically: horizontally away from the neighbour.
    """
    h2 = d[0] * d[0] + d[1] * d[1]
    if h2 > HORIZONTAL_MIN2:  # across the horizontal direction of travel
        hl = math.sqrt(h2)
        across = (-d[1] / hl, d[0] / hl, 0.0)  # left of d
        side = dot(rel, across)
        if abs(side) > SIDE_OFFSET:
            return scale(across, -1.0 if side > 0.0 else 1.0)
        return right_of(d)
    r2 = rel[0] * rel[0] + rel[1] * rel[1]  # vertical travel: horizontally away
    if r2 > BESIDE_MIN2:
        rl = math.sqrt(r2)
        return (-rel[0] / rl, -rel[1] / rl, 0.0)
    return right_of(d)


# ----------------------------------------------------------------------------- passthrough
@njit
def clear_paths(
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
    oc: NDArray[np.float64],
    oh: NDArray[np.float64],
    parts: NDArray[np.float64],
    reach: float,
    wake: float,
    turn: NDArray[np.float64],
) -> None:
    """PASSTHROUGH: for each candidate, True when the box it sweeps to its goal stays ``margin`` m clear of
    every neighbour's box swept along the neighbour's velocity over ``lookahead`` s, and of every static
    obstacle (``oc``, ``oh``: centres and half extents (K, 3) m) but its target's own (``own_target``
    with ``parts`` and ``reach`` m). With ``WAKE_COLUMN`` (``wake`` m) both boxes of a pair reach that
    much further down. ``turn`` (n, 3) m (``PASSTHROUGH_TURNS``): for candidate i each neighbour's swept box
    also grows by row i on every side of each axis, how far a change of its velocity can take it within
    ``lookahead`` (0 for a target that needs millimetres, see ``targets_touching``)."""
    n = pos.shape[0]
    for i in range(n):
        out[i] = False
        if not candidate[i]:
            continue
        if not clear_of_obstacles(i, pos, goal, centre, half, oc, oh, parts, margin, reach):
            continue
        ok = True
        for c in range(nbr.shape[1]):
            j = nbr[i, c]
            if j < 0 or j >= n or j == i:
                continue
            apart = False
            for a in range(3):
                down = wake if a == 2 else 0.0
                lo_i = min(pos[i, a], goal[i, a]) + centre[i, a] - half[i, a] - down
                hi_i = max(pos[i, a], goal[i, a]) + centre[i, a] + half[i, a]
                ahead = vel[j, a] * lookahead
                lo_j = pos[j, a] + centre[j, a] - half[j, a] - down - margin - turn[i, a] + min(ahead, 0.0)
                hi_j = pos[j, a] + centre[j, a] + half[j, a] + margin + turn[i, a] + max(ahead, 0.0)
                if hi_i <= lo_j or hi_j <= lo_i:
                    apart = True
                    break
            if not apart:
                ok = False
                break
        out[i] = ok


@njit
def targets_touching(
    goal: NDArray[np.float64],
    parts: NDArray[np.float64],
    candidate: NDArray[np.bool_],
    oc: NDArray[np.float64],
    oh: NDArray[np.float64],
    reach: float,
    out: NDArray[np.bool_],
) -> None:
    """PASSTHROUGH_TURNS: for each candidate, True when at its target (``goal``) its airframe or load (``parts``)
    comes within ``reach`` m of the ground or of an obstacle (``oc``, ``oh``) without reaching into it
    (``own_target``): a grasp point over a box, a drop point on the ground, on a slot's support or beside a
    neighbour, which need millimetres. Elsewhere (a waypoint over a slot at cruise height) they do not."""
    for i in range(goal.shape[0]):
        out[i] = False
        if not candidate[i]:
            continue
        for k in range(2):
            b = 6 * k
            if parts[i, b + 3] > 0.0 and goal[i, 2] + parts[i, b + 2] - parts[i, b + 5] <= reach:
                out[i] = True  # on (or just over) the ground
        o = 0
        while not out[i] and o < oc.shape[0]:
            out[i] = own_target(i, o, goal, goal, parts, oc, oh, reach)
            o += 1


# ----------------------------------------------------------------------------- static obstacles
@njit
def clear_of_obstacles(
    i: int,
    pos: NDArray[np.float64],
    goal: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    oc: NDArray[np.float64],
    oh: NDArray[np.float64],
    parts: NDArray[np.float64],
    margin: float,
    reach: float,
) -> bool:
    """PASSTHROUGH, against the static obstacles: True when agent i's box swept to its goal stays ``margin`` m clear of
    every obstacle but its target's own (``own_target`` within ``reach`` m)."""
    goal_rel = add(row(goal, i), row(pos, i), -1.0)
    for o in range(oc.shape[0]):
        c = (
            oc[o, 0] - pos[i, 0] - centre[i, 0],
            oc[o, 1] - pos[i, 1] - centre[i, 1],
            oc[o, 2] - pos[i, 2] - centre[i, 2],
        )
        H = (oh[o, 0] + half[i, 0], oh[o, 1] + half[i, 1], oh[o, 2] + half[i, 2])
        if own_target(i, o, pos, goal, parts, oc, oh, reach):
            continue
        apart = False
        for a in range(3):
            # the swept box runs from the shape now (0) to the shape at the goal (goal_rel)
            lo = min(0.0, goal_rel[a]) - H[a] - margin
            hi = max(0.0, goal_rel[a]) + H[a] + margin
            if c[a] <= lo or c[a] >= hi:
                apart = True
                break
        if not apart:
            return False
    return True


@njit
def obstacle_shape(
    i: int,
    pos: NDArray[np.float64],
    radius: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    boxes: bool,
    oc: NDArray[np.float64],
    oh: NDArray[np.float64],
    o: int,
) -> tuple[Vec, Vec]:
    """Static obstacles (the paper's): (centre m of obstacle o relative to agent i's shape, half extents m of their Minkowski box).

    An agent modelled as a sphere counts as the cube around it. No margin is added.
    """
    if boxes:
        c = (
            oc[o, 0] - pos[i, 0] - centre[i, 0],
            oc[o, 1] - pos[i, 1] - centre[i, 1],
            oc[o, 2] - pos[i, 2] - centre[i, 2],
        )
        return c, (oh[o, 0] + half[i, 0], oh[o, 1] + half[i, 1], oh[o, 2] + half[i, 2])
    c = (oc[o, 0] - pos[i, 0], oc[o, 1] - pos[i, 1], oc[o, 2] - pos[i, 2])
    return c, (oh[o, 0] + radius[i], oh[o, 1] + radius[i], oh[o, 2] + radius[i])


@njit
def own_target(
    i: int,
    o: int,
    pos: NDArray[np.float64],
    goal: NDArray[np.float64],
    parts: NDArray[np.float64],
    oc: NDArray[np.float64],
    oh: NDArray[np.float64],
    reach: float,
) -> bool:
    """Static obstacles (the paper's, with ``goal_reach``): True when obstacle o is agent i's target's own: a part of the agent (airframe or
    load, ``parts``) at its target comes within ``reach`` m of it, and none reaches into it deeper
    than ``GOAL_OVERLAP``.

    Such an obstacle is the box under a grasp point, the slot's support and neighbours beside the
    load at a drop point, the box just let go: the agent must come within its grasp or placement
    distance of it, which the obstacle's velocity obstacle (grown by the safety margin) would
    forbid, so it is not avoided. A target inside an obstacle (an airframe that would stand in a
    taller neighbour of its slot) cannot be reached without touching it: that obstacle stays.

    Args:
        parts: (n, 12) per agent the centre offset (3,) m and half extents (3,) m of its airframe,
            then of its load (half extents 0: no load), see ``kernel.shape_parts``.
    """
    near = False
    for k in range(2):
        b = 6 * k
        if parts[i, b + 3] <= 0.0:
            continue
        depth = 1e300
        within = True
        for a in range(3):
            d = abs(oc[o, a] - goal[i, a] - parts[i, b + a])
            sep = parts[i, b + 3 + a] + oh[o, a]
            depth = min(depth, sep - d)
            if d >= sep + reach:
                within = False
        if depth > GOAL_OVERLAP:
            return False
        near = near or within
    return near


@njit
def ray_entry(c: Vec, H: Vec, d: Vec, length: float) -> float:
    """Static obstacles (the paper's): distance m along unit ``d`` from the origin at which the ray enters the box
    [c - H, c + H] within ``length`` m (0 when it starts inside), or -1 when it misses."""
    lo, hi = 0.0, length
    for k in range(3):
        if abs(d[k]) < 1e-12:
            if abs(c[k]) >= H[k]:
                return -1.0
            continue
        a = (c[k] - H[k]) / d[k]
        b = (c[k] + H[k]) / d[k]
        lo = max(lo, min(a, b))
        hi = min(hi, max(a, b))
        if lo > hi:
            return -1.0
    return lo


@njit
def obstacle_in_way(
    i: int,
    pos: NDArray[np.float64],
    radius: NDArray[np.float64],
    centre: NDArray[np.float64],
    half: NDArray[np.float64],
    boxes: bool,
    oc: NDArray[np.float64],
    oh: NDArray[np.float64],
    goal: NDArray[np.float64],
    has_goal: bool,
    parts: NDArray[np.float64],
    d: Vec,
    length: float,
    margin: float,
    reach: float,
) -> tuple[bool, Vec]:
    """DEADLOCK_RESOLUTION, against the static obstacles: the way past the nearest obstacle that holds up stalled agent i.

    The obstacle is the nearest one (shapes grown by ``margin`` m, the target's own left out, see
    ``own_target``) that the agent's shape would enter within ``length`` m along its unit
    preferred direction ``d``. Returns (found, unit direction of the bias): across ``d`` away from the
    obstacle's centre (right when it lies dead ahead).
    Unlike ``sidestep``'s choice for a neighbour, the side does not turn with the bearing: an agent
    sliding along the face of a wide obstacle keeps going the way it started.
    """
    best = -1
    best_t = 1e300
    for o in range(oc.shape[0]):
        if has_goal and own_target(i, o, pos, goal, parts, oc, oh, reach):
            continue
        c, H = obstacle_shape(i, pos, radius, centre, half, boxes, oc, oh, o)
        t = ray_entry(c, (H[0] + margin, H[1] + margin, H[2] + margin), d, length)
        if 0.0 <= t < best_t:
            best, best_t = o, t
    if best < 0:
        return False, (0.0, 0.0, 0.0)
    c, _ = obstacle_shape(i, pos, radius, centre, half, boxes, oc, oh, best)
    h2 = d[0] * d[0] + d[1] * d[1]
    if h2 <= HORIZONTAL_MIN2:  # vertical travel: horizontally away
        return True, sidestep(d, c)
    hl = math.sqrt(h2)
    ax, ay = -d[1] / hl, d[0] / hl  # left of d, horizontal
    side = ax * c[0] + ay * c[1]
    if abs(side) > SIDE_OFFSET:
        s = -1.0 if side > 0.0 else 1.0
        return True, (s * ax, s * ay, 0.0)
    return True, right_of(d)
