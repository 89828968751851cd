"""Shortest path: the thesis's centralised baseline for the construction task.

Boxes are assigned in structure order (bottom layer first); each agent climbs to its cruise
altitude, flies in a straight line to its box, descends, grasps, climbs, flies to its slot,
waits until the slot is open, descends, releases and climbs. Other agents are ignored at run
time (this baseline collides, as in the thesis). By default (``wake_lanes``) loaded agents cruise
at ``search_height`` (raised where a carried box would not clear the finished structure,
``cruise_base``) and the others ``lane_gap`` higher; without it agent i cruises at
``search_height + i * altitude_step``, and ``altitude_step: 0`` gives the thesis's single search
height (run it with ``collisions: ghost``, as the thesis detected collisions without simulating
them). The wake rules (``wake_lanes``, ``wake_clear``) act only where the run models downwash
(``TaskInfo.extra["downwash"]``, set by the simulation from ``sim.downwash``): without it the
baseline flies as with them switched off; and ``wake_lanes`` only with an avoidance layer
(``TaskInfo.extra["avoidance"]``): agents sharing a lane need one to keep apart (without it,
lanes gave 99 agent-agent contacts on seeds 0..9 against 30 for the staggered altitudes).
Centralised: it reads the whole ``WorldView``.

Flying on estimates (``TaskInfo.extra["position_std"]``: the per-axis standard deviation of the
agents' own position estimates) the agents know where they are only to that accuracy, while the
baseline sees the boxes. So a held box is servoed onto its drop point by what the baseline sees
of it (the target moves by the box's remaining error), it is let go ``CLEARANCE_SIGMAS``
standard deviations above its slot at least and only after it has stayed within ``release_tol``
for ``RELEASE_DWELL_S``. A slot whose box came to rest off it is served again, with the box
lying in it if there is one.

Extensions of the thesis's baseline (chapter 3.5: "directs the agents to move in a straight line
from the boxes to their desired location, until all boxes have been placed correctly"), each a
switch of ``ShortestPathParams``, on by default, off under ``preset: thesis``:

===========================  =======  ======  ==================================================
switch                       default  thesis  what it does
===========================  =======  ======  ==================================================
``altitude_step``            0.2 m    0       agent i cruises ``i * altitude_step`` above the
                                              search height, so that loaded airframes do not
                                              meet at one cruise altitude (unused with
                                              ``wake_lanes``)
``retry_slots``              true     false   a slot whose box came to rest off it is served
                                              again (with the box lying in it first, if any)
``wait_beside``              true     false   an agent whose slot is not open yet waits aside
                                              from its column (``_wait_aside``), not over it,
                                              while an agent cruising higher still has to come
                                              down to a slot near that column (with an avoidance
                                              layer the waiting agent would block that descent
                                              for ever)
``spaced_descents``          true     false   an agent starts its descent to a box or slot only
                                              when no other agent is on a vertical leg
                                              (descending, placing, lifting or climbing back)
                                              within an airframe's width and
                                              ``DESCENT_SPACING_MARGIN`` of its column (per
                                              axis); it waits beside the column at its cruise
                                              altitude (boxes side by side: airframes over
                                              neighbouring slots 10 cm apart were stacked by the
                                              avoidance layer, none placing, or one came down on
                                              another; waiting over a tower's column, an agent's
                                              wake held one climbing from it down)
``release_over_neighbours``  true     false   a box for a slot with others beside it on its
                                              level is let go above their tops where the task's
                                              guide takes it (``planning/placing.py``): lowered
                                              into a gap of its own width it catches on their
                                              edges and tips its carrier over
``wake_lanes``               true     false   two cruise lanes, one direction each: loaded agents
                                              (lifting, to and down to their slots) cruise
                                              ``LOADED_LANE_MARGIN`` above the cruise base, the
                                              others ``lane_gap`` (0.9 m) higher: more than an
                                              avoidance layer's wake column (0.5 m) and two
                                              airframes with its margins apart
                                              (staggered 0.2 m apart, every pair of cruising
                                              agents was in each other's wake column and the
                                              upper ones dodged sideways, out of the arena);
                                              agents with nothing left to carry fly home and
                                              park ``PARK_GAP`` higher still
``plumb_legs``               true     false   an agent pushed more than ``PLUMB_TOL`` off the
                                              column of its descent goes back to the top of it
                                              (its cruise altitude) before it sinks further (it
                                              reached its box sideways, at grasp height)
``soft_landing``             true     false   a descent to a box or slot stops ``SETTLE_HEIGHT``
                                              above it, then its target creeps down by
                                              ``CREEP_STEP`` a tick until the box (or airframe)
                                              is there; the drop point is ``release_tol`` higher
                                              (at full speed a box overshot onto the box below,
                                              an airframe onto its box); the creep waits for a
                                              lagging airframe (``CREEP_LEAD``) and backs up
                                              when the box is past its point
``held_pass``                true     false   with ``wake_clear``, an agent held short of a
                                              column does not itself hold others up as one
                                              hovering over their target (two held agents,
                                              each over the other's target, waited for ever)
``recentre_box``             true     false   a carrier at rest over its slot whose box hangs
                                              more than ``release_tol`` off its drop point moves
                                              over by what it sees of the box (the offset is
                                              measured in flight, and a tilted airframe put it
                                              7 mm off)
``swap_boxes``               true     false   two agents on their way to boxes exchange them when
                                              that shortens their summed flights by more than
                                              ``SWAP_GAIN`` (in one lane, one flying to a box
                                              beyond the other's met it head-on over the depot,
                                              both held for ever)
``round_parked``             true     false   a carrier on its way to its slot goes round (by a
                                              point ``PARKED_RADIUS`` beside it) another carrier
                                              at rest that its straight path passes within
                                              ``PARKED_CLEARANCE`` (a carrier waiting for its slot
                                              sat on the way of another to a slot below it in the
                                              same column; the avoidance layer held that one
                                              behind it for ever), and round an agent at its
                                              altitude at the top of a vertical leg (flying
                                              through, one pushed an agent starting its descent
                                              1 m along ahead of it)
``wake_clear``               true     false   keeps every agent out of the rotor wake of those
                                              above it (``vehicle/downwash.py``: 5 cm wide, a
                                              quarter of the weight down to 1.3 m below): an
                                              agent in level flight holds ``WAKE_LOOKAHEAD``
                                              short of the column of an agent at another
                                              altitude on a vertical leg or over its goal, and
                                              goes round (``DETOUR_RADIUS``) any other at
                                              another altitude; a descent starts only with no
                                              agent above within ``WAKE_CLEARANCE`` of the
                                              column and no other vertical leg within
                                              ``LEG_SPACING``; waiting points keep
                                              ``LEG_SPACING`` off the columns of boxes, slots
                                              and lower agents
``wait_away``                true     false   an agent waiting aside from a column may also
                                              wait on the arc facing away from where the served
                                              agents come (a slot's: the depot; a box's: the
                                              structure); it takes the arc whose point keeps
                                              farther off the columns and the way from there to
                                              the column (facing the arena's centre, those
                                              waiting for a tower at the far end stood in the
                                              loaded lane between the depot and the tower, and
                                              the carrier whose turn it was could not pass them;
                                              facing away always, those waiting for a wall stood
                                              among its slots' columns beyond it)
``park_clear``               true     false   an agent with nothing left to carry parks at its
                                              start unless that lies within ``WAKE_CLEARANCE`` of
                                              the column of a free box, a slot or an agent below
                                              it; then at a point off them found as a waiting
                                              point is, facing out of the arena (with the start
                                              beside the depot, two parked agents stood over
                                              free boxes, held by the agents under their starts
                                              that waited for those boxes: neither moved again)
===========================  =======  ======  ==================================================

The thesis gives no code for this baseline (its appendices hold the stigmergy planners only), so
chapter 3.5 is all the preset follows. The climb to the cruise altitude before flying, the
straight descent and the wait for an open slot are needs of this platform's physical boxes (the
thesis's passed through each other and through the structure), as is everything above about
flying on estimates (the thesis's agents knew their positions); they stay under the preset.
"""

from __future__ import annotations

import enum
from typing import Any, ClassVar

import numpy as np
from pydantic import Field

from pybullet_swarm.planning.base import Action, Command
from pybullet_swarm.planning.views.construction import ConstructionInfo, ConstructionWorldView
from pybullet_swarm.planning.params import Params, Preset
from pybullet_swarm.planning.placing import release_clearances

CLEARANCE_SIGMAS = 3.0
"""Least release clearance, in standard deviations of an agent's own position estimate."""
RELEASE_DWELL_S = 0.5
"""s: on estimated state, how long a box must have stayed within ``release_tol`` of its drop point."""
SERVO_GAIN = 0.3
"""Fraction of a held box's remaining error added to its carrier's target per planner tick."""
RECENTRE_ARRIVED = 0.003
"""m: ``recentre_box`` moves a carrier's target only once the carrier is horizontally this close to it."""
SERVO_LIMIT = 0.03
"""m: largest correction of a carrier's target by the servo, per axis."""


VERTICAL_CLEARANCE = 0.03
"""m: a carried box stays this far above the finished structure and the depot's boxes."""
ASIDE_RADII = 4.0
"""Agent radii from a column at which agents held up by ``spaced_descents`` wait."""
ASIDE_SPREAD_DEG = 150.0
"""deg: the waiting points of several agents are spread over this arc facing the arena's centre."""
GOLDEN_FRACTION = 0.6180339887498949
"""Agent i waits at the fraction (i x this mod 1) of the arc: neighbouring indices far apart on it."""
SETTLE_HEIGHT = 0.04
"""m: ``soft_landing`` stops a descent this far above its grasp or drop point, then creeps down the rest."""
CREEP_START = 0.01
"""m: ``soft_landing`` starts creeping when the agent is within this of the point ``SETTLE_HEIGHT`` above."""
CREEP_STEP = 0.003
"""m: ``soft_landing`` lowers a creeping target by this much a planner tick (3 cm/s at 10 Hz)."""
CREEP_LEAD = 0.006
"""m: ``soft_landing`` lowers its creeping target only while the airframe is within this above it (two steps):
run ahead of an airframe that lags it, the creep went on down while the box still read high, and the box
came to rest 1.1 cm under its drop point, out of the release tolerance, for good (suite solid_wall, seed 4)."""
CREEP_SPEED = 0.02
"""m/s: ``soft_landing`` starts creeping once the agent has come (nearly) to rest above its point."""
SWAP_GAIN = 0.05
"""m: ``swap_boxes`` exchanges two agents' boxes when their summed flights shorten by more than this."""
PLUMB_TOL = 0.04
"""m: ``plumb_legs`` brings back over its column an agent descending this far off it."""
LOADED_LANE_MARGIN = 0.05
"""m: with ``wake_lanes`` the loaded agents' lane lies this far above the cruise base (3 cm over the finished
structure with a box, a carrier weaving round another agent dipped its box onto it)."""
PARK_GAP = 0.6
"""m: with ``wake_lanes`` agents with nothing left to carry park this far above the empty agents' lane (more than
an avoidance layer's wake column, 0.5 m, and two airframes with its margins; 1.95 m on the thesis task, under the
2 m top of the learning environments' waypoint range)."""
LANE_TOL = 0.05
"""m: an agent farther than this from its cruise altitude is climbing or sinking to it (on a vertical leg)."""
WAKE_CLEARANCE = 0.19
"""m: ``wake_clear`` keeps an agent this far from the column of one below it (per horizontal axis from a vertical
leg, horizontally from one in level flight: two half airframes of ``quad150`` and an avoidance layer's margins,
its boxes then do not overlap horizontally; the rotor wake, 5 cm wide down to 1.3 m below, pushes with less than
0.1 % of the weight there)."""
LEG_SPACING = 0.3
"""m, per horizontal axis: with ``wake_clear`` two vertical legs are at least this far apart (neighbouring
columns 20 cm apart are not served at once: a leg a little higher than its neighbour puts its wake column over
it, and the avoidance layer pushed both sideways, out of the arena), and so far off the columns of boxes,
slots and lower agents agents wait (19 cm off a box's column, a waiting agent kept the avoidance layer from
letting another one to it)."""
WAKE_MIN_DZ = 0.1
"""m: ``wake_clear`` minds agents at least this much lower (or higher); closer vertically, two agents share an
altitude and the avoidance layer keeps them apart."""
WAKE_LOOKAHEAD = 1.0
"""m: how far ahead along its level flight ``wake_clear`` looks for columns of agents below."""
DETOUR_RADIUS = 0.3
"""m: ``wake_clear`` takes an agent round one below it in level flight by a point this far beside it (the
straight leg to it from farther than this passes more than ``WAKE_CLEARANCE`` from that agent)."""
PARKED_SPEED = 0.02
"""m/s: ``round_parked`` counts an agent slower than this as at rest."""
PARKED_CLEARANCE = 0.3
"""m: ``round_parked`` goes round an agent at rest that its straight path would pass nearer than this (the
avoidance layer's boxes, 18 cm per axis for ``quad150``, along the diagonal)."""
PARKED_RADIUS = 0.4
"""m: ``round_parked`` passes an agent at rest by a point this far beside it."""
WAIT_STEP = 0.1
"""m: ``wake_clear`` moves a waiting point this much further out until it lies ``LEG_SPACING`` off every column."""
WAIT_TRIES = 8
"""How many waiting points further out ``wake_clear`` tries; when none lies ``LEG_SPACING`` off every column (a
depot grid at a 20 cm pitch), it keeps the one farthest off them (the first one, a column's width from another
box's column, blocked that box's agent for good: ``tower5`` of the construction suite stalled)."""
DESCENT_SPACING_MARGIN = 0.02
"""m: ``spaced_descents`` keeps two vertical legs an airframe's width and this far apart (per horizontal axis;
the airframe a square in the agent's enclosing circle: 17 cm for ``quad150``, so a 20 cm pitch is not held up)."""


def cruise_base(info: ConstructionInfo) -> float:
    """m, the lowest cruise altitude: the task's ``search_height``, raised where a carried box would not
    clear the finished structure or the depot's boxes (a tall structure)."""
    tops = [
        float(np.max(pts[:, 2])) + 0.5 * info.layout.box_size
        for pts in (info.layout.slots, info.layout.depot)
        if len(pts)
    ]
    clear = max(tops, default=0.0) + info.layout.grasp_height + 0.5 * info.layout.box_size + VERTICAL_CLEARANCE
    return max(float(info.layout.search_height), clear)


class Phase(enum.IntEnum):
    """Where an agent is in its delivery."""

    IDLE = 0
    TO_BOX = 1
    DESCEND_BOX = 2
    LIFT = 3
    TO_SLOT = 4
    DESCEND_SLOT = 5
    CLIMB = 6
    DONE = 7


LOADED_PHASES = (Phase.LIFT, Phase.TO_SLOT, Phase.DESCEND_SLOT)
"""Phases in which an agent carries (or lifts) its box: the lower lane with ``wake_lanes``."""
VERTICAL_PHASES = (Phase.DESCEND_BOX, Phase.LIFT, Phase.DESCEND_SLOT, Phase.CLIMB)
"""Phases of the vertical legs, down to a box or slot and back up."""


class ShortestPathParams(Params):
    """Parameters of the ``shortest_path`` baseline (scenario ``planner.params``); see the module's
    docstring for the extensions and ``preset: thesis``."""

    preset: Preset | None = Field(
        None,
        strict=False,
        description="thesis: every extension off, as the thesis's chapter 3.5 describes "
        "the baseline (explicit values still win)",
    )

    arrive_tol: float = Field(
        0.01, gt=0.0, le=1.0, description="m, horizontal distance at which a waypoint counts as reached"
    )
    release_clearance: float = Field(0.004, ge=0.0, le=0.5, description="m, how far above its slot a box is let go")
    altitude_step: float = Field(
        0.2, ge=0.0, le=10.0, description="m, agent i cruises at search_height + i * altitude_step"
    )
    release_tol: float = Field(
        0.005, gt=0.0, le=0.5, description="m, per-axis error of a held box within which it is let go on estimates"
    )
    retry_slots: bool = Field(True, description="serve again a slot whose box came to rest off it [false]")
    wait_beside: bool = Field(
        True,
        description="wait for a slot beside its column, not over it, while an agent cruising higher "
        "has yet to come down near that column [false]",
    )

    spaced_descents: bool = Field(
        True,
        description="start a descent only when no other agent is on a vertical leg within an airframe's "
        "width (and 2 cm) of the column [false]",
    )

    release_over_neighbours: bool = Field(
        True,
        description="let a box for a slot with boxes beside it go above their tops, where the task's guide "
        "takes it [false]",
    )

    wake_lanes: bool = Field(
        True,
        description="loaded agents cruise at the cruise base, the others lane_gap higher (altitude_step unused) [false]",
    )
    lane_gap: float = Field(
        0.9,
        ge=0.0,
        le=10.0,
        description="m, with wake_lanes: how far the empty agents' lane lies above the loaded agents' (more than an "
        "avoidance layer's wake column and two airframes)",
    )
    plumb_legs: bool = Field(
        True,
        description="an agent pushed off the column of its descent goes back over it before it sinks further [false]",
    )
    soft_landing: bool = Field(
        True,
        description="the last few centimetres down to a box or slot are flown slowly (no overshoot onto the box "
        "below) [false]",
    )
    swap_boxes: bool = Field(
        True,
        description="two agents on their way to boxes exchange them when that shortens their flights [false]",
    )
    round_parked: bool = Field(
        True,
        description="a carrier goes round another carrier at rest on its way to its slot instead of meeting it [false]",
    )
    wake_clear: bool = Field(
        True,
        description="never fly over an agent on a vertical leg below, nor start a descent under another agent, and "
        "wait off the columns of boxes, slots and agents [false]",
    )
    wait_away: bool = Field(
        True,
        description="wait aside from a column on the arc facing away from where the served agents come (the depot, "
        "the structure) when its point keeps farther off the columns and their way than the arc facing the "
        "arena's centre [false]",
    )

    park_clear: bool = Field(
        True,
        description="an agent with nothing left to carry parks off the columns of free boxes, slots and the agents "
        "below it (at its start when that is clear) [false]",
    )
    held_pass: bool = Field(
        True,
        description="with wake_clear, an agent held short of a column does not itself hold up others as one "
        "hovering over their target [false]",
    )
    recentre_box: bool = Field(
        True,
        description="a carrier settled over its slot whose box hangs off its drop point by more than release_tol "
        "horizontally moves over by what it sees of the box [false]",
    )

    PRESETS: ClassVar[dict[Preset, dict[str, Any]]] = {
        Preset.THESIS: {
            "altitude_step": 0.0,
            "retry_slots": False,
            "wait_beside": False,
            "spaced_descents": False,
            "release_over_neighbours": False,
            "wake_lanes": False,
            "plumb_legs": False,
            "swap_boxes": False,
            "soft_landing": False,
            "round_parked": False,
            "wake_clear": False,
            "wait_away": False,
            "park_clear": False,
            "recentre_box": False,
            "held_pass": False,
        }
    }


def _wait_clearance(xy: np.ndarray, off: float, lane: tuple[np.ndarray, np.ndarray]) -> float:
    """m, how well a waiting point ``xy`` (2,) m keeps out of the way (``wait_away``): its distance ``off`` from the
    columns and from the ``lane`` (source, column), up to ``LEG_SPACING``; negative when nearer than
    ``WAKE_CLEARANCE`` (per axis) to the column it waits aside of."""
    own = float(np.max(np.abs(xy - lane[1])))
    if own < WAKE_CLEARANCE:
        return own - WAKE_CLEARANCE
    return min(off, _to_segment(xy, *lane), LEG_SPACING)


def _to_segment(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """m, the distance of point ``q`` (2,) from the segment from ``a`` to ``b`` (2,)."""
    ab = b - a
    t = float(np.clip(np.dot(q - a, ab) / max(float(np.dot(ab, ab)), 1e-12), 0.0, 1.0))
    return float(np.linalg.norm(q - (a + t * ab)))


def _lookahead(p: np.ndarray, target: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Level flight from ``p`` (3,) m towards ``target`` (3,) m: the unit direction (2,) and ``k`` points (k, 2) m
    along the way up to ``WAKE_LOOKAHEAD`` ahead; None when ``target`` is right above or below."""
    step = target[:2] - p[:2]
    dist = float(np.linalg.norm(step))
    if dist < 1e-9:
        return None
    u = step / dist
    return u, p[:2] + np.linspace(0.0, min(dist, WAKE_LOOKAHEAD), k)[:, None] * u


class ShortestPath:
    """Centralised straight-line delivery in structure order.

    Args:
        params: validated ``ShortestPathParams`` (default: the defaults).
    """

    name: ClassVar[str] = "shortest_path"
    centralized: ClassVar[bool] = True
    Params: ClassVar[type[ShortestPathParams]] = ShortestPathParams

    def __init__(self, params: ShortestPathParams | None = None) -> None:
        self.params = params if params is not None else ShortestPathParams()
        self.arrive_tol = self.params.arrive_tol
        self.release_clearance = self.params.release_clearance
        self.altitude_step = self.params.altitude_step
        self.release_tol = self.params.release_tol

    def reset(self, n: int, rng: np.random.Generator, info: ConstructionInfo) -> None:
        """Order the slots bottom layer first and clear the assignments."""
        self.info = info
        self.n = n
        # the wake rules act where the run models downwash (``TaskInfo.extra["downwash"]``, true when unsaid)
        wakes = bool(info.extra.get("downwash", True))
        # a shared lane needs an avoidance layer to keep its agents apart (``extra["avoidance"]``, true when unsaid)
        self.wake_lanes = self.params.wake_lanes and wakes and bool(info.extra.get("avoidance", True))
        self.wake_clear = self.params.wake_clear and wakes
        base = cruise_base(info)
        self.hs = base + self.altitude_step * np.arange(n)  # m, cruise altitude of each agent
        low = base + LOADED_LANE_MARGIN  # m, the loaded agents' lane (wake_lanes)
        self.lanes = (low, low + self.params.lane_gap)  # m, the loaded and the empty agents' lane (wake_lanes)
        self.gh = info.layout.grasp_height
        slots = info.layout.slots
        self.order = list(np.lexsort((slots[:, 1], slots[:, 0], np.round(slots[:, 2], 6))))
        self.phase = np.full(n, Phase.IDLE, dtype=np.int64)
        self.box = np.full(n, -1, dtype=np.int64)
        self.slot = np.full(n, -1, dtype=np.int64)
        self.next_slot = 0
        self.home: np.ndarray | None = None  # m, start positions (parking spots)
        self.park: np.ndarray | None = None  # m, (n, 2) where each agent parks (``park_clear``: off the columns)
        self.offset = np.tile([0.0, 0.0, -info.layout.grasp_height], (n, 1))  # m, held box relative to agent
        self.attach = float(info.layout.attach_threshold)
        sigma = float(info.extra.get("position_std", 0.0))  # m, per-axis std of the agents' own estimates
        self.estimated = sigma > 0.0
        self.clearance = max(self.release_clearance, CLEARANCE_SIGMAS * sigma)  # m
        # (S,) m, release height of each slot's box (over its neighbours' tops with ``release_over_neighbours``)
        self.clearances = release_clearances(info, self.clearance, over_neighbours=self.params.release_over_neighbours)
        self.correction = np.zeros((n, 3))  # m, servo correction of each carrier's target
        self.within_since = np.full(n, np.nan)  # s, since when each held box is within release_tol
        self.last_box = np.full((n, 3), np.nan)  # m, held box position at the previous tick
        self.columns = np.zeros((n, 2))  # m, where each agent's current vertical leg is
        # m, where the agents served at a slot's column come from (the depot) and at a box's (the structure)
        self.depot_xy = np.mean(info.layout.depot[:, :2], axis=0) if len(info.layout.depot) else None
        self.structure_xy = np.mean(info.layout.slots[:, :2], axis=0) if len(info.layout.slots) else None
        self.creep = np.full(n, np.nan)  # m, soft_landing: each agent's creeping target height (nan: not yet)
        self.held = np.zeros(n, dtype=bool)  # wake_clear: held short of a column at its last tick (held_pass)

    def _assign(self, i: int, view: ConstructionWorldView) -> None:
        taken_boxes = set(self.box[self.box >= 0].tolist())
        while self.next_slot < len(self.order) and view.task.state.slot_filled[self.order[self.next_slot]] >= 0:
            self.next_slot += 1
        # a slot passed over earlier that is empty again (its box came to rest off it)
        k = self._retry_slot(view) if self.params.retry_slots else -1
        if k < 0 and self.next_slot >= len(self.order):
            self.phase[i] = Phase.DONE
            return
        free = [
            b
            for b in range(len(view.task.state.object_state))
            if view.task.state.object_state[b] == 0 and b not in taken_boxes
        ]
        if not free:
            self.phase[i] = Phase.DONE
            return
        s = self.order[k if k >= 0 else self.next_slot]
        loose = [b for b in free if self.params.retry_slots and self._in_slot(view.task.state.objects[b], s)]
        if loose:  # the box lying in the slot goes first: nothing is set down onto it
            self.box[i] = loose[0]
        else:
            p = view.positions[i]
            d = [np.linalg.norm(view.task.state.objects[b, :2] - p[:2]) for b in free]
            self.box[i] = free[int(np.argmin(d))]
        self.slot[i] = s
        if k < 0:
            self.next_slot += 1
        self.phase[i] = Phase.TO_BOX

    def _retry_slot(self, view: ConstructionWorldView) -> int:
        """Position in ``order`` of the first empty slot before ``next_slot`` that no agent is serving, or -1."""
        busy = set(self.slot[(self.phase >= Phase.TO_BOX) & (self.phase <= Phase.CLIMB)].tolist())
        for k in range(min(self.next_slot, len(self.order))):
            s = self.order[k]
            if view.task.state.slot_filled[s] < 0 and s not in busy:
                return k
        return -1

    def _in_slot(self, box: np.ndarray, s: int) -> bool:
        """True when a box centred at ``box`` (3,) m lies (partly) in the space of slot ``s``."""
        d = np.abs(box - self.info.layout.slots[s])
        return bool(np.all(d < self.info.layout.box_size))

    def _overflown(self, i: int, s: int) -> bool:
        """True when another agent cruising higher than agent ``i`` (with ``wake_lanes`` or ``wake_clear``: any
        other agent) still has to come down to a slot whose column lies within two agent radii of slot ``s``'s
        (its way down passes agent ``i`` waiting over ``s``; with ``wake_clear`` a lower agent may not fly in under
        it either: on the tower of 5 without avoidance, the carrier of its third box waited for 150 s, held by
        the one waiting over the column for the fifth slot)."""
        busy = (self.phase >= Phase.TO_BOX) & (self.phase <= Phase.DESCEND_SLOT) & (self.slot >= 0)
        busy[i] = False
        # with wake_lanes every loaded agent comes down from the one lane, with wake_clear a lower one may not
        # come in under agent i: all of them count
        higher = np.ones(self.n, dtype=bool) if (self.wake_lanes or self.wake_clear) else self.hs > self.hs[i]
        others = np.flatnonzero(busy & higher)
        if others.size == 0:
            return False
        d = np.linalg.norm(self.info.layout.slots[self.slot[others], :2] - self.info.layout.slots[s, :2], axis=1)
        return bool(np.any(d < 2.0 * self.info.agent_radius))

    def _descents_near(self, i: int, xy: np.ndarray) -> np.ndarray:
        """Agents (indices) other than ``i`` on a vertical leg (down to a box or slot, or back up) whose
        column lies within an airframe's width and ``DESCENT_SPACING_MARGIN`` (per axis) of ``xy`` (2,) m,
        where ``i`` would descend (``spaced_descents``; none without it)."""
        if not self.params.spaced_descents:
            return np.zeros(0, dtype=np.int64)
        vertical = np.isin(self.phase, (Phase.DESCEND_BOX, Phase.LIFT, Phase.DESCEND_SLOT, Phase.CLIMB))
        vertical[i] = False
        others = np.flatnonzero(vertical)
        if others.size == 0:
            return others
        width = np.sqrt(2.0) * self.info.agent_radius  # m, a square airframe in the enclosing circle
        spacing = width + DESCENT_SPACING_MARGIN
        if self.wake_clear:
            spacing = max(spacing, LEG_SPACING)
        d = np.max(np.abs(self.columns[others] - xy[:2]), axis=1)
        return others[d < spacing]

    def _wait_aside(
        self, i: int, view: ConstructionWorldView, above: np.ndarray, source: np.ndarray | None = None
    ) -> Command:
        """Wait at the cruise altitude aside from the column ``above`` (3,) m (``wait_beside``, ``spaced_descents``:
        over it, the waiting agent would block a descent, its wake would push a climbing agent down, or one
        climbing to a higher cruise altitude would pass through it). Agents waiting for one column wait at points
        ``ASIDE_RADII`` agent radii from it, spread by their index over an arc facing the arena's centre (at
        one point, one over another, the upper one's wake pushed the lower one down). With ``wait_away`` and a
        ``source`` (2,) m, where the agents served at that column come from, the arc facing away from it is the
        other choice, and the agent waits on the arc whose point stays farther off both the columns and the way
        from ``source`` to the column (``LEG_SPACING`` suffices; a tie keeps the arena's centre). A point that the
        arena's edge pulls nearer than ``WAKE_CLEARANCE`` to the column itself comes last: an agent waiting there
        stands in the way of the one it waits for (held 14 cm from a slot 25 cm from the edge, a waiting carrier
        kept the slot's carrier off it until the run stalled)."""
        centre = 0.5 * np.asarray(self.info.arena_size, dtype=float)[:2] - above[:2]
        columns = self._columns(i, view) if self.wake_clear else np.zeros((0, 2))
        xy, off = self._wait_point(i, above, centre, columns)
        if self.params.wait_away and source is not None and np.linalg.norm(above[:2] - source[:2]) > 1e-9:
            xy2, off2 = self._wait_point(i, above, above[:2] - source[:2], columns)
            lane = (np.asarray(source[:2], dtype=float), above[:2])
            if _wait_clearance(xy2, off2, lane) > _wait_clearance(xy, off, lane) + 1e-9:
                xy = xy2
        return self._cruise(i, view, np.array([xy[0], xy[1], above[2]]))

    def _wait_point(
        self, i: int, above: np.ndarray, facing: np.ndarray, columns: np.ndarray
    ) -> tuple[np.ndarray, float]:
        """Agent ``i``'s waiting point (2,) m on the arc round the column ``above`` facing ``facing`` (2,), and how
        far (per axis) it keeps off ``columns`` (k, 2) m (inf without any). With columns (``wake_clear``) it goes
        out along its way until off every column, or to the point farthest off them (a dense depot)."""
        base = float(np.arctan2(facing[1], facing[0])) if np.linalg.norm(facing) > 1e-9 else 0.0
        turn = ((i * GOLDEN_FRACTION) % 1.0 - 0.5) * np.radians(ASIDE_SPREAD_DEG)
        r = self.info.agent_radius
        way = np.array([np.cos(base + turn), np.sin(base + turn)])
        size = np.asarray(self.info.arena_size, dtype=float)[:2]  # m
        xy = np.clip(above[:2] + ASIDE_RADII * r * way, r, size - r)
        best = np.inf if not columns.size else -np.inf
        for k in range(WAIT_TRIES if columns.size else 0):
            cand = np.clip(above[:2] + (ASIDE_RADII * r + k * WAIT_STEP) * way, r, size - r)
            off = float(np.min(np.max(np.abs(columns - cand), axis=1)))
            if off > best + 1e-9:  # none off every column: the one farthest off them
                best, xy = off, cand
            if off >= LEG_SPACING:
                break
        return xy, best

    def _park_point(self, i: int, view: ConstructionWorldView) -> np.ndarray:
        """Where agent ``i``, with nothing left to carry, parks (2,) m: above its start; with ``park_clear`` and
        ``wake_clear`` the point it keeps until that comes within ``WAKE_CLEARANCE`` (per axis) of a column it must
        not wait over (free boxes, slots, agents below it), then the start again if that is clear, or else a
        waiting point round the start facing out of the arena (parked over a free box, an agent held the one that
        waited under its start for that box, and that one held it)."""
        home = self.home if self.home is not None else view.positions
        if not (self.params.park_clear and self.wake_clear):
            return np.asarray(home[i, :2], dtype=float)
        if self.park is None:
            self.park = np.array(home[:, :2], dtype=float)
        columns = self._columns(i, view)
        if not columns.size:
            return self.park[i]

        def clear(xy: np.ndarray) -> bool:
            return bool(np.min(np.max(np.abs(columns - xy), axis=1)) >= WAKE_CLEARANCE)

        if not clear(self.park[i]):
            start = np.asarray(home[i, :2], dtype=float)
            if clear(start):
                self.park[i] = start
            else:
                out = start - 0.5 * np.asarray(self.info.arena_size, dtype=float)[:2]
                self.park[i], _ = self._wait_point(i, np.array([start[0], start[1], 0.0]), out, columns)
        return self.park[i]

    def _alt(self, i: int) -> float:
        """m, the cruise altitude of agent ``i`` in its present phase: ``hs[i]``, or with ``wake_lanes`` the
        loaded agents' lane (lifting, to and down to its slot), the empty agents' lane, or for an agent with
        nothing left to carry the lane above (flying home in the empty agents' lane, it herded an agent waiting
        at the top of a column there out of the arena)."""
        if not self.wake_lanes:
            return float(self.hs[i])
        if self.phase[i] == Phase.DONE:
            return self.lanes[1] + PARK_GAP
        return self.lanes[0] if self.phase[i] in LOADED_PHASES else self.lanes[1]

    def _in_column(self, j: int, p: np.ndarray) -> bool:
        """True when agent ``j`` at ``p`` (3,) m is on a vertical leg: down to or up from a box or slot, or
        climbing or sinking to its cruise altitude."""
        return bool(self.phase[j] in VERTICAL_PHASES or abs(p[2] - self._alt(j)) > LANE_TOL)

    def _wake_blocked(self, i: int, view: ConstructionWorldView, target: np.ndarray) -> bool:
        """``wake_clear``: True when agent ``i``, flying level towards ``target`` (3,) m, would within
        ``WAKE_LOOKAHEAD`` come closer than ``WAKE_CLEARANCE`` (per axis), and nearer than it is now, to an agent
        at another altitude that is on a vertical leg (below it, its wake would push that agent down onto its box
        or slot; above it, that agent's wake would push it down: a carrier reaching the top of its slot's column
        under an agent climbing from it sank 12 cm onto the structure) or hovers over ``target`` (with
        ``held_pass``, not one held there itself by this rule: it waits for another column, and two held agents,
        each over the other's target, waited for ever: suite double_wall, seed 1)."""
        if not self.wake_clear:
            return False
        p = view.positions[i]
        way = _lookahead(p, target, 11)
        if way is None:
            return False
        _, ahead = way
        for j in range(self.n):
            q = view.positions[j]
            if j == i or abs(q[2] - p[2]) < WAKE_MIN_DZ:
                continue
            over = np.max(np.abs(target[:2] - q[:2])) < WAKE_CLEARANCE and not (self.params.held_pass and self.held[j])
            if not (self._in_column(j, q) or over):
                continue
            now = float(np.max(np.abs(p[:2] - q[:2])))
            near = float(np.min(np.max(np.abs(ahead - q[:2]), axis=1)))
            if near < WAKE_CLEARANCE <= now and near < now - 1e-3:  # from within, on out: held there, it stays
                return True
        return False

    def _detour(self, i: int, view: ConstructionWorldView, target: np.ndarray) -> np.ndarray:
        """The target (3,) m of agent ``i`` flying level to ``target``, by a point beside the first agent its
        straight path would pass near: with ``wake_clear`` one at another altitude (but one on a vertical leg or
        over its goal, held for) within ``WAKE_CLEARANCE`` (horizontally) over or under it, as a rotor wake, 5 cm
        wide, pushes the lower one down by a quarter of its weight (a loaded agent flying under one waiting in
        the empty agents' lane sank 22 cm, its box onto the depot's); with ``round_parked`` (both carrying)
        one at rest at its altitude within ``PARKED_CLEARANCE``. The point lies ``DETOUR_RADIUS`` (``PARKED_RADIUS``) from that
        agent, square to the path, on the side the path already passes."""
        if not (self.wake_clear or self.params.round_parked):
            return target
        p = view.positions[i]
        way = _lookahead(p, target, 21)
        if way is None:
            return target
        u, ahead = way
        best, w = np.inf, target
        for j in range(self.n):
            q = view.positions[j]
            if j == i or (self._in_column(j, q) and abs(q[2] - p[2]) >= WAKE_MIN_DZ):
                continue  # on a vertical leg at another altitude: held for
            if abs(q[2] - p[2]) >= WAKE_MIN_DZ and self.wake_clear:
                clear, radius = WAKE_CLEARANCE, DETOUR_RADIUS
            elif abs(q[2] - p[2]) < WAKE_MIN_DZ and self._round_parked(i, j, view):
                clear, radius = PARKED_CLEARANCE, PARKED_RADIUS
            else:
                continue  # at its altitude and moving: the avoidance layer's
            if np.max(np.abs(target[:2] - q[:2])) < clear:
                continue  # over, under or by its goal: held for, or the avoidance layer's
            gap = np.linalg.norm(ahead - q[:2], axis=1)  # the wake is round
            if gap.min() >= clear or gap.min() >= gap[0] - 1e-3:
                continue  # clear of it, or already leaving it
            along = float(np.dot(q[:2] - p[:2], u))
            if along < best:
                side = float(u[0] * (p[1] - q[1]) - u[1] * (p[0] - q[0]))  # >0: the path passes left of q
                normal = np.array([-u[1], u[0]]) * (1.0 if side >= 0.0 else -1.0)
                r = self.info.agent_radius
                size = np.asarray(self.info.arena_size, dtype=float)[:2]
                xy = q[:2] + radius * normal
                if np.any(xy < r) or np.any(xy > size - r):  # no room on that side: the other one
                    xy = np.clip(q[:2] - radius * normal, r, size - r)
                best, w = along, np.array([xy[0], xy[1], target[2]])
        return w

    def _round_parked(self, i: int, j: int, view: ConstructionWorldView) -> bool:
        """``round_parked``: True when agent ``i`` carries a box to its slot and agent ``j``, carrying one too,
        hovers at rest (waiting for its slot, or held), or (at ``i``'s altitude) is at the top of a vertical leg.
        Empty agents are left to the avoidance layer: going round each other over the depot, they strayed beside
        a descent and the avoidance layer held it there. A carrier flying to its waiting point beyond a ring
        pushed one starting its descent 1 m along ahead of it, then stood between it and its column."""
        if not (self.params.round_parked and self.phase[i] == Phase.TO_SLOT):
            return False
        if self._in_column(j, view.positions[j]):
            return True
        return bool(self.phase[j] == Phase.TO_SLOT and np.linalg.norm(view.velocities[j]) < PARKED_SPEED)

    def _under_wake(self, i: int, view: ConstructionWorldView, xy: np.ndarray) -> bool:
        """``wake_clear``: True when another agent above agent ``i`` is within ``WAKE_CLEARANCE`` (per axis) of
        the column at ``xy`` (2,) m, where ``i`` would descend (its wake would push ``i`` down)."""
        if not self.wake_clear:
            return False
        others = np.arange(self.n) != i
        above = view.positions[:, 2] > view.positions[i, 2] + WAKE_MIN_DZ
        near = np.max(np.abs(view.positions[:, :2] - xy[:2]), axis=1) < WAKE_CLEARANCE
        return bool(np.any(others & above & near))

    def _columns(self, i: int, view: ConstructionWorldView) -> np.ndarray:
        """(k, 2) m: the columns agent ``i`` must not wait over (``wake_clear``): the free boxes', the slots' and
        those of the other agents below its cruise altitude."""
        free = view.task.state.objects[np.asarray(view.task.state.object_state) == 0, :2]
        low = (np.arange(self.n) != i) & (view.positions[:, 2] < self._alt(i) - LANE_TOL)
        return np.vstack([free, self.info.layout.slots[:, :2], view.positions[low, :2]])

    def _soft(self, i: int, p: np.ndarray, vz: float, target: np.ndarray, gap: float) -> np.ndarray:
        """``soft_landing``: the target (3,) m of agent ``i`` at ``p`` (3,) m, climbing at ``vz`` m/s, descending to
        ``target`` (a grasp or drop point), what it sets down or grasps ``gap`` m above where it must stop:
        ``SETTLE_HEIGHT`` above ``target`` until the agent is within ``CREEP_START`` of that and slower than
        ``CREEP_SPEED``, then a point that comes down from there by ``CREEP_STEP`` a tick while ``gap`` exceeds
        that, while the airframe is within ``CREEP_LEAD`` of it, and that goes back up by ``CREEP_STEP`` a
        tick while the box is more than ``CREEP_STEP`` under its point. Flown at the full vertical speed, a box
        overshot its drop point by 5 mm onto the box below, an
        airframe its grasp point onto its box; and a box hung up to 1 cm lower than measured when it was lifted,
        so it is the box's height that ends the creep. The drop point is also ``release_tol`` higher, so that a
        box settled anywhere within the tolerance clears the one below."""
        if not self.params.soft_landing:
            return target
        pre = float(target[2]) + SETTLE_HEIGHT  # m
        if np.isnan(self.creep[i]):
            if p[2] > pre + CREEP_START or abs(vz) > CREEP_SPEED:
                return np.array([target[0], target[1], pre])
            self.creep[i] = pre
        if gap > CREEP_STEP and p[2] - self.creep[i] < CREEP_LEAD:
            # still above, and the airframe has caught up with the creep: on down (a little below target,
            # where the box hangs lower than measured)
            self.creep[i] = max(float(target[2]) - SETTLE_HEIGHT, self.creep[i] - CREEP_STEP)
        elif gap < -CREEP_STEP:  # past it (the creep ran ahead of a lagging airframe): back up
            self.creep[i] = min(pre, self.creep[i] + CREEP_STEP)
        return np.array([target[0], target[1], self.creep[i]])

    def _plumb(self, i: int, p: np.ndarray, target: np.ndarray) -> np.ndarray:
        """``plumb_legs``: the target (3,) m of agent ``i`` at ``p`` (3,) m descending to ``target``: while it is
        more than ``PLUMB_TOL`` off the column (pushed aside by an avoidance layer) and still above the target,
        the top of the column at its cruise altitude, not on down (it would reach the box or structure sideways;
        held at its height, just under the others' lane, the avoidance layer's wake column froze it there)."""
        if not self.params.plumb_legs:
            return target
        off = float(np.hypot(p[0] - target[0], p[1] - target[1]))
        if off > PLUMB_TOL and p[2] > target[2] + PLUMB_TOL:
            self.creep[i] = np.nan  # a soft landing starts again from the top
            return np.array([target[0], target[1], self._alt(i)])
        return target

    def _near_xy(self, p: np.ndarray, q: np.ndarray) -> bool:
        return bool(np.linalg.norm(p[:2] - q[:2]) <= self.arrive_tol)

    def _cruise(self, i: int, view: ConstructionWorldView, target: np.ndarray) -> Command:
        """Go to ``target`` at cruise altitude: climb first, then fly straight (with ``wake_clear``, stop short
        of the column of an agent on a vertical leg below)."""
        p = view.positions[i]
        if not self._near_xy(p, target) and abs(p[2] - self._alt(i)) > 0.03:
            return Command.goto([p[0], p[1], self._alt(i)])
        if not self._near_xy(p, target) and self._wake_blocked(i, view, target):
            self.held[i] = True
            return Command.goto([p[0], p[1], self._alt(i)])
        self.held[i] = False
        return Command.goto(self._detour(i, view, target))

    def _step(self, i: int, view: ConstructionWorldView) -> Command:
        p = view.positions[i]
        ph = Phase(self.phase[i])
        if ph == Phase.IDLE:
            self._assign(i, view)
            ph = Phase(self.phase[i])
        if ph == Phase.DONE:  # nothing left to carry: park above the start, out of the others' way
            xy = self._park_point(i, view)
            return self._cruise(i, view, np.array([xy[0], xy[1], self._alt(i)]))
        b, s = self.box[i], self.slot[i]
        if ph == Phase.TO_BOX:
            if view.task.state.object_state[b] != 0:  # someone took or placed it meanwhile: choose again
                self.phase[i] = Phase.IDLE
                self.box[i] = -1
                return Command.goto([p[0], p[1], self._alt(i)])
            above = np.array([*view.task.state.objects[b, :2], self._alt(i)])
            if self._descents_near(i, above).size:
                return self._wait_aside(i, view, above, self.structure_xy)
            if self._near_xy(p, above) and abs(p[2] - self._alt(i)) < 0.05 and not self._under_wake(i, view, above):
                self.phase[i] = Phase.DESCEND_BOX
                self.columns[i] = above[:2]
                self.creep[i] = np.nan
            return self._cruise(i, view, above)
        if ph == Phase.DESCEND_BOX:
            grasp = view.task.state.objects[b] + [0.0, 0.0, self.gh]
            if view.carrying[i] == b:
                self.phase[i] = Phase.LIFT
                return Command.goto([p[0], p[1], self._alt(i)])
            act = Action.GRASP if np.linalg.norm(p - grasp) <= 0.6 * self.attach else Action.NONE
            return Command.goto(
                self._plumb(i, p, self._soft(i, p, float(view.velocities[i, 2]), grasp, float(p[2] - grasp[2]))), act
            )
        if ph == Phase.LIFT:
            if view.carrying[i] != b:  # lost the box: start over
                self.phase[i] = Phase.IDLE
                self.box[i] = -1
                self.next_slot = min(self.next_slot, self.order.index(s))
                return Command.goto([p[0], p[1], self._alt(i)])
            if abs(p[2] - self._alt(i)) < 0.05 and np.linalg.norm(view.velocities[i]) < 0.02:
                self.phase[i] = Phase.TO_SLOT
                # where the box hangs under this agent, measured once while hovering steadily
                # (measuring it in flight would feed the airframe's tilt back into the target)
                self.offset[i] = view.task.state.objects[b] - p
            return Command.goto([p[0], p[1], self._alt(i)])
        # where the agent must be for the box it holds (at its actual offset) to hang just above the slot
        drop = self.info.layout.slots[s] + [
            0.0,
            0.0,
            self.clearances[s] + (self.release_tol if self.params.soft_landing else 0.0),
        ]
        slot_top = drop - self.offset[i]
        if ph == Phase.TO_SLOT:
            above = np.array([slot_top[0], slot_top[1], self._alt(i)])
            if not view.task.state.slot_open[s] and (
                self.estimated or (self.params.wait_beside and self._overflown(i, s))
            ):
                # wait beside the column, not over it: an agent serving a slot under this one descends
                # there, and the avoidance layer (on jittering estimates, or a higher agent's way down
                # through this one's altitude) would hold it up for ever
                return self._wait_aside(i, view, above, self.depot_xy)
            if self._descents_near(i, above).size:
                return self._wait_aside(i, view, above, self.depot_xy)
            if (
                self._near_xy(p, above)
                and view.task.state.slot_open[s]
                and abs(p[2] - self._alt(i)) < 0.05
                and not self._under_wake(i, view, above)
            ):
                self.phase[i] = Phase.DESCEND_SLOT
                self.columns[i] = above[:2]
                self.creep[i] = np.nan
                self.correction[i] = 0.0
                self.within_since[i] = np.nan
                self.last_box[i] = np.nan
                self._targets = getattr(self, "_targets", {})
                self._targets[(i, s)] = slot_top
            return self._cruise(i, view, above)
        if ph == Phase.DESCEND_SLOT:
            if view.carrying[i] != b:
                self.phase[i] = Phase.CLIMB
                return Command.goto([p[0], p[1], self._alt(i)])
            err = view.task.state.objects[b] - drop
            speed = np.linalg.norm(view.velocities[i])
            ok = bool(np.hypot(err[0], err[1]) <= self.release_tol and abs(err[2]) <= self.release_tol and speed < 0.02)
            if not hasattr(self, "_targets"):
                self._targets = {}
            # the drop point is fixed once the descent starts, so box swing does not move the target
            target = self._targets.setdefault((i, s), slot_top)
            if self.estimated:
                target, ok = self._servo(i, view, target, err, ok)
            elif self.params.recentre_box and not ok:
                target = self._recentre(i, view, target, err)
            return Command.goto(
                self._plumb(
                    i,
                    p,
                    self._soft(
                        i, p, float(view.velocities[i, 2]), target, float(view.task.state.objects[b, 2] - drop[2])
                    ),
                ),
                Action.RELEASE if ok else Action.NONE,
            )
        # CLIMB
        if abs(p[2] - self._alt(i)) < 0.05:
            self.phase[i] = Phase.IDLE
            self.box[i] = -1
        return Command.goto([p[0], p[1], self._alt(i)])

    def _box_still(self, i: int, view: ConstructionWorldView) -> bool:
        """True when the box carrier ``i`` holds moved less than 2 mm since the last tick (remembered here)."""
        box = view.task.state.objects[self.box[i]]
        still = bool(np.all(np.isfinite(self.last_box[i])) and np.linalg.norm(box - self.last_box[i]) < 0.002)
        self.last_box[i] = box
        return still

    def _recentre(self, i: int, view: ConstructionWorldView, target: np.ndarray, err: np.ndarray) -> np.ndarray:
        """``recentre_box``: the target (3,) m of carrier ``i`` over its slot, its box ``err`` (3,) m off the drop
        point: once the agent has arrived and the box is still, a box more than ``release_tol`` off horizontally
        (and at most ``SERVO_LIMIT``: farther is no error of the offset) moves the target by ``SERVO_GAIN`` of
        that error a tick (in all at most ``SERVO_LIMIT`` per axis). The offset under the
        agent is measured once, after the lift, in flight; 7 mm off it (the airframe tilted as it was measured,
        the box hanging straight under it over the slot), a carrier held its box out of the release tolerance
        for 150 s (suite solid_stepped_wall, seed 3)."""
        still = self._box_still(i, view)
        off = view.positions[i, :2] - (target[:2] + self.correction[i, :2])
        arrived = np.hypot(off[0], off[1]) < RECENTRE_ARRIVED and np.linalg.norm(view.velocities[i]) < CREEP_SPEED
        if arrived and still and self.release_tol < np.hypot(err[0], err[1]) <= SERVO_LIMIT:
            step = np.array([err[0], err[1], 0.0])
            self.correction[i] = np.clip(self.correction[i] - SERVO_GAIN * step, -SERVO_LIMIT, SERVO_LIMIT)
        return target + self.correction[i]

    def _servo(
        self, i: int, view: ConstructionWorldView, target: np.ndarray, err: np.ndarray, ok: bool
    ) -> tuple[np.ndarray, bool]:
        """On estimated state: the target (3,) m of carrier ``i`` corrected by what is seen of its box
        (error ``err`` (3,) m from the drop point), and whether to let go (``ok``, held for the dwell
        while the box is still)."""
        p = view.positions[i]
        still = self._box_still(i, view)
        if np.linalg.norm(p - (target + self.correction[i])) < 0.02 and still:  # arrived: servo the box
            self.correction[i] = np.clip(self.correction[i] - SERVO_GAIN * err, -SERVO_LIMIT, SERVO_LIMIT)
        if not (ok and still):
            self.within_since[i] = np.nan
        elif np.isnan(self.within_since[i]):
            self.within_since[i] = view.time_s
        ready = bool(ok and still and view.time_s - self.within_since[i] >= RELEASE_DWELL_S - 1e-9)
        if ready:
            self.correction[i] = 0.0
            self.within_since[i] = np.nan
            self.last_box[i] = np.nan
        return target + self.correction[i], ready

    def activities(self) -> list[str]:
        """What each agent is doing, in words: its phase and the box and slot it is assigned."""
        out = []
        for i in range(self.n):
            words = [f"phase {Phase(self.phase[i]).name.lower()}"]
            if self.box[i] >= 0:
                words.append(f"box {self.box[i]}")
            if self.slot[i] >= 0:
                q = self.info.layout.slots[self.slot[i]]
                words.append(f"slot {self.slot[i]} at ({q[0]:.2f}, {q[1]:.2f}, {q[2]:.2f})")
            out.append(", ".join(words))
        return out

    def _swap_boxes(self, view: ConstructionWorldView) -> None:
        """``swap_boxes``: two agents on their way to boxes exchange them when that shortens their summed
        (horizontal) flights by more than ``SWAP_GAIN``; boxes lying in a slot stay with their agents."""
        going = [
            i
            for i in np.flatnonzero(self.phase == Phase.TO_BOX)
            if self.box[i] >= 0
            and not any(self._in_slot(view.task.state.objects[self.box[i]], int(s)) for s in self.slot)
        ]
        for a, i in enumerate(going):
            for j in going[a + 1 :]:
                pi, pj = view.positions[i, :2], view.positions[j, :2]
                bi, bj = view.task.state.objects[self.box[i], :2], view.task.state.objects[self.box[j], :2]
                now = np.linalg.norm(pi - bi) + np.linalg.norm(pj - bj)
                swapped = np.linalg.norm(pi - bj) + np.linalg.norm(pj - bi)
                if swapped < now - SWAP_GAIN:
                    self.box[i], self.box[j] = self.box[j], self.box[i]

    def plan_all(self, view: ConstructionWorldView) -> list[Command]:
        """One command per agent."""
        if self.home is None:
            self.home = view.positions.copy()
        if self.params.swap_boxes:
            self._swap_boxes(view)
        return [self._step(i, view) for i in range(self.n)]


from pybullet_swarm.planning.registry import register_planner  # noqa: E402

register_planner(
    "shortest_path",
    ShortestPath,
    "centralised baseline: boxes in structure order, straight lines at a cruise altitude, other agents ignored",
    ("construction",),
    default_for=("construction",),
)
