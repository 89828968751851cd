"""Stigmergy planners of the construction thesis: 3-D stigmergy (chapter 5) and layered stigmergy (chapter 6).

Decentralised: each agent sees its own state, its neighbours within the sensing radius, the free
boxes and open slots within its view radius, and the shared pheromone grid; nothing else.

**3-D stigmergy** (``stigmergy``, thesis Fig. 5.1 and appendix A). An agent alternates between
looking for a box and looking for a goal. Each time it needs somewhere to look it takes the next
strategy of a cycle (appendix A): a uniformly random point of the arena; then the cell with the
strongest pheromone of the wanted sign (+ for boxes, - for goals; among equally strong cells one
drawn at random, ``ties``, a vertical column counting once: the thesis's layer is the 2-D slice at
the search height, where the boxes placed on top of each other mark one cell); then a random point within ``local_radius`` of itself; then random
again, and so on. Without any pheromone of that sign it searches at random. It flies to that
point watching for a free box (or, carrying one, for an open slot); when one comes into view it
goes for it. Pheromone rules (thesis Table 5.2), all in one layer that never fades (fatigue 0):
grasping a box sets the agent's cell to +1, placing one sets it to -1, and while looking for a
box the agent leaves a trail of 0.2 in every empty cell it passes.

**Layered stigmergy** (``layered_stigmergy``, thesis chapter 6 and appendix B) adds a second
layer: every agent marks its cell with 2 each tick and the marks fade at 2/s, so they show
where the agents are and were a moment ago. An agent may not move into a cell holding another
agent's mark: when one lies ahead of it, within ``lookahead`` along its way, it stops and chooses
a new search point by the cycle above (the thesis's "a search is recalculated based on the
pheromones in the 1st grid"), and keeps to it for as long as a mark lasts (1 s) before it goes
for a seen object again. Its own marks it ignores (the grid remembers who marked each cell).

What this platform needs beyond the thesis, whose agents moved boxes by being near them and
flew through boxes, structure and each other (its collisions were "detected, but not simulated",
Table 3.1): each item is either a need of physical boxes (kept under every preset) or an
extension with its own switch (bold; the table below).

* Altitudes. The task lets an agent see an object only near its grasp point, so agents fly low:
  over the open floor and the depot high enough for a carried box to clear a box lying on the floor
  or waiting in the depot, over the structure at the task's ``search_height``, clear of the finished
  structure; an agent climbs straight up before it enters a higher zone and descends after leaving
  it (needs). Without the extension below, floor and depot share one altitude, the box clearance
  counted from where a climb ends (``ALTITUDE_TOL`` below the altitude: a carried box that clears
  the depot's boxes only at the nominal altitude snags one as its carrier sets off, and a
  layered agent held up there flips over). **layout_altitudes**: the floor altitude also level with the middle of the
  structure's grasp points and the depot's half a view above the boxes' grasp points, so that slots
  of every layer and the depot's boxes are in view; a search point over the structure moved to the
  edge of its zone (on the agent's side), where the agent sees its slots; a local search point of an
  agent beside the structure spread along that edge (the thesis's local square, turned to the
  wall). The layout is used for nothing else: boxes and slots are still found by seeing them,
  guided by the pheromones. For any structure height, depot and arena the altitudes rise from
  floor to depot to structure by construction (a tall structure raises the floor, and the depot's
  altitude with it, no higher than where the depot's boxes stay in view); a column whose slots an
  agent beside the structure cannot see (the middle of a wide slab) is searched for from above, at
  a cruise altitude lowered (never below the finished structure's clearance) until its lowest slot
  is in view. Explicit altitudes that do not rise, and slots no agent sees from beside or from
  above, are refused when the scenario is loaded (``StigmergyParams.check_layout``), never mid-run.
* Grasping and placing (needs). An agent goes above the object, descends straight down, grasps
  within 60 % of the attach threshold, and places its box from ``release_clearance`` above the
  slot at the lowest (**raise_drop_point**: its drop point is ``release_tol`` higher still: the settle test lets it go
  anywhere within ``release_tol`` of that point; at ``release_clearance`` over the slot exactly,
  a settled agent could press its box onto the one below), where the box hangs at the offset it had when grasped (measured from the box it saw then).
  **drift_breakoff**: a descent pushed more than ``DRIFT_TOL`` off its column (by a neighbour's
  avoidance, say) is broken off; the agent climbs straight back and comes over the object again,
  rather than sweeping what hangs under it diagonally through a neighbouring stack.
  **descent_timeout_s**: a descent that does not end in a release by then is broken off.
* **release_over_neighbours**: a box for a slot with others beside it on its level (boxes side by
  side) is let go ``OVER_NEIGHBOURS_CLEARANCE`` above their tops, where the task's guide still takes
  it (``pybullet_swarm/planning/placing.py``); lowered into a gap of its own width it would catch on
  their edges and tip its carrier over.
* **clear_spent_goals**: an agent with a box that reaches its search point and sees no open slot
  there clears the goal marks (-1) over the columns whose every slot it sees from there: they mark
  slots filled since, and in a large structure the strongest-pheromone search would otherwise draw
  among every column ever built on, the last open slot's as likely as any (a column whose upper
  slot opens later gets a fresh mark from the placement that opens it, next to it).
* **claims**: an agent leaves a box or slot to a neighbour already working over it (lower, or at
  the same height and nearer), so two agents never descend onto one object.
* **queue_at_slots**: a carrier whose slot's working square (an airframe's width and
  ``QUEUE_MARGIN`` per axis round the column it serves the slot from) holds another carrier, and
  which is not in that square itself, waits ``QUEUE_GAP`` outside every slot's square until it is
  free: ten carriers round a 3 x 3 slab pushed each other about over it and none set its box down.
  Waiting outside every square, no waiting carrier holds up another slot's.
* **wide_view**: an agent notices every object the task shows it (grasp point within the task's
  ``view_radius`` plus the grasp height, max-norm: 27.7 cm per axis for ``quad150``) instead of the
  thesis's window of two agent radii (15 cm: its 15 cm airframe) from its centre to the object's.
* **search_near**: a random search point is drawn near what is sought (within the view range,
  per axis, of a slot drawn at random for a carrier, of a depot box for an empty agent), not
  anywhere in the arena: section 5.2.5 names limiting the search space as one of the three
  reactions, but appendix A draws over the whole arena. In a 6 x 3 m arena the carrier of the
  last box searched it for its slot for 150 s.
* **ties**: among equally strong cells one is drawn at random (spreading agents over every found
  box) instead of the first in the thesis's grid order.
* Flying on an estimate (``TaskInfo.extra["position_std"]``, the per-axis standard deviation the
  agent's filter settles to; needs, the thesis's agents knew where they were). The box is let go
  ``CLEARANCE_SIGMAS`` standard deviations above its slot at least (a box pressed onto what is
  under it sticks there and drags the agent), and only once the estimate has stayed within
  ``release_tol`` of the drop point for ``release_dwell_s``.
* Layered only: **lookahead** (20 cm along the way instead of the next 10 cm cell),
  **detour** (after a re-plan the agent keeps to its new search point for as long as a
  mark lasts, 1 s, before going for a seen object again: two agents wanting to pass each other would
  otherwise block each other for ever).

**The thesis preset** (``planner.params.preset: thesis``) switches every extension off:

============================  ==========  ==========  =================================================
switch                        default     thesis      source of the thesis's value
============================  ==========  ==========  =================================================
``ties``                      random      first       appendix A: ``[maxval, maxind] = max(pheromones(:))``
``claims``                    true        false       neither: a box is skipped only once carried
``wide_view``                 true        false       Table 5.1 (2 x agent radius), appendix A (max-norm)
``view_window``               0.15 m      0.15 m      Table 3.2: 15 x 15 cm airframe, radius 7.5 cm
``layout_altitudes``          true        false       appendix A: one ``search_height``, points as drawn
``drift_breakoff``            true        false       not in the thesis
``descent_timeout_s``         20 s        null        not in the thesis
``release_over_neighbours``   true        false       not in the thesis (its boxes passed through each other)
``clear_spent_goals``         true        false       appendix A: goal marks never change (fatigue 0)
``raise_drop_point``          true        false       not in the thesis
``lookahead``                 0.2 m       0.1 m       appendix B: the cells next to the agent's own
``detour``                    true        false       not in the thesis
``queue_at_slots``            true        false       not in the thesis (five agents, a gapped wall)
``search_near``               true        false       section 5.2.5 (limit the search space); not appendix A
============================  ==========  ==========  =================================================

It also sets the thesis's numbers where they are parameters (Tables 5.1, 5.2, 6.1: 10 cm cells,
+1, -1, trail 0.2, fatigue 0, local square +-20 cm, presence 2 fading at 2/s, no distance effect);
explicitly given values win over it. Where the thesis's chapters and its appendix code disagree,
the preset follows:

* The trail: Table 5.2 lays 0.2 "at any time" where the value is below 0.2; appendix A lays it
  only while looking for a box (state 1), only in an empty cell (``cur_p_value == 0``) and not
  once at the target. The appendix: the chapter's rule would overwrite every -1 goal mark (-1 <
  0.2), and the appendix is the code that produced Table 5.3.
* The search: section 5.2.5 names three reactions (limit the search space, strongest pheromone,
  distance effects) and says a mix of all three is used; appendix A cycles random -> strongest
  (global maximum) -> local random (+-20 cm) -> random, without distance effects or a limited
  search space. The appendix (``distance_scale: null``), for the same reason.
* The presence layer: Table 6.1 marks with 2 fading at 2/s, and section 6.0.4 forbids moving into
  a marked area and re-plans from the first layer; appendix B marks with 1, has no fading code,
  erases the 3 x 3 cells around the agent (its neighbours' marks included) and computes the marked
  neighbours (``taken``) without ever using them: as printed it avoids nothing, which would make
  layered stigmergy 3-D stigmergy, against the different results of Table 6.2. The chapter for the
  values and the reaction; the appendix for the area checked (the cells next to the agent's own:
  ``lookahead`` one cell), read with the chapter's "area they move into" (the cells along its
  way).
* The view: Table 5.1 gives "2 x agent-radius" and appendix A measures it in the max-norm from the
  agent's centre to the object's (``dist = max(abs(object - agent))``) at the objects' level. Our
  agents fly above the objects (physical boxes), so the window is measured horizontally and the
  task's view bounds the vertical. With it an agent beside the structure sees no bottom slot: the
  structure's keep-out zone (half a box, one agent radius and ``structure_margin``, 17.6 cm from a
  column's centre) is wider than the 15 cm window, and from above, at the structure's altitude,
  bottom slots are out of the task's view. So under the bare preset no box is ever placed (the
  thesis's agents flew through the structure); ``wide_view: true`` on top of it builds.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from typing import Any, ClassVar

import numba
import numpy as np
from numpy.typing import NDArray

from pydantic import Field

from pybullet_swarm.errors import ConfigError, LayoutNeedError
from pybullet_swarm.planning.base import Action, Command, CommandKind, TaskInfo, view_distance
from pybullet_swarm.planning.views.construction import ConstructionInfo, ConstructionObservation
from pybullet_swarm.planning.params import Params, PlanContext, Preset, check_memory
from pybullet_swarm.planning.pheromone_grid import DepositRule, LayerSpec, PheromoneGrid
from pybullet_swarm.planning.placing import release_clearances


class Layer(str, enum.Enum):
    """Pheromone layers of the stigmergy planners."""

    TASK = "task"  # thesis layer 1: +1 box found, -1 box placed, 0.2 trail; never fades by default
    PRESENCE = "presence"  # thesis layer 2 (layered variant): where the agents are; fades in about 1 s


class Phase(enum.IntEnum):
    """Where an agent is in its cycle: thesis Fig. 5.1 (states 0-3), with every flying step explicit.

    ==============  =================================================  ==========================================
    phase           what the agent does                                next phase (the method that decides)
    ==============  =================================================  ==========================================
    CHOOSE_BOX      thesis state 0: next search point for a box        SEEK_BOX (``_step_choose_box``)
    SEEK_BOX        thesis state 1: fly there, trail 0.2, watch        TO_BOX: a free box in view; CHOOSE_BOX:
                                                                       point reached (``_step_seek_box``)
    TO_BOX          fly over the box at the flying altitude            DESCEND_BOX: over it, settled; SEEK_BOX:
                                                                       gone or claimed (``_step_to_box``)
    DESCEND_BOX     straight down to its grasp point                   GRASPING: there, steady; RECLIMB_BOX:
                                                                       pushed off the column; SEEK_BOX: gone
                                                                       (``_step_descend_box``)
    RECLIMB_BOX     straight back up after a broken-off descent        TO_BOX: at the flying altitude; SEEK_BOX
                                                                       (``_step_reclimb_box``)
    GRASPING        GRASP asked                                        LIFT (+1 marked): held; DESCEND_BOX: not
                                                                       (``_sync``)
    LIFT            straight up with the box                           CHOOSE_GOAL: at the flying altitude
    CHOOSE_GOAL     thesis state 2: next search point for a slot       SEEK_GOAL
    SEEK_GOAL       thesis state 3: fly there, watch for open slots    TO_SLOT: an open, empty slot in view;
                                                                       CHOOSE_GOAL: point reached
    TO_SLOT         fly over the slot at the flying altitude           DESCEND_SLOT: over it, settled; SEEK_GOAL:
                                                                       filled or claimed
    DESCEND_SLOT    straight down to the drop point                    RELEASING: settled there; RECLIMB_SLOT:
                                                                       pushed off; SEEK_GOAL: filled, or
                                                                       ``DESCENT_TIMEOUT_S`` passed
    RECLIMB_SLOT    straight back up after a broken-off descent        TO_SLOT; SEEK_GOAL
    RELEASING       RELEASE asked                                      CLIMB (-1 marked): let go;
                                                                       DESCEND_SLOT: still held (``_sync``)
    CLIMB           straight up from the release                       CHOOSE_BOX: at the flying altitude
    ==============  =================================================  ==========================================

    A held box slipping out of the grip sends any holding phase to CHOOSE_BOX (``_sync``); a
    layered agent that meets another's presence mark while travelling goes to CHOOSE_BOX or
    CHOOSE_GOAL (``_replan``).
    """

    CHOOSE_BOX = 0
    SEEK_BOX = 1
    TO_BOX = 2
    DESCEND_BOX = 3
    RECLIMB_BOX = 4
    GRASPING = 5
    LIFT = 6
    CHOOSE_GOAL = 7
    SEEK_GOAL = 8
    TO_SLOT = 9
    DESCEND_SLOT = 10
    RECLIMB_SLOT = 11
    RELEASING = 12
    CLIMB = 13


#: phases in which an agent travels (searching, heading for an object, or back up to its altitude)
TRAVELLING = frozenset(
    {Phase.SEEK_BOX, Phase.SEEK_GOAL, Phase.TO_BOX, Phase.TO_SLOT, Phase.RECLIMB_BOX, Phase.RECLIMB_SLOT}
)


class TieBreak(str, enum.Enum):
    """Which of several equally strong pheromone cells an agent heads for."""

    RANDOM = "random"  # any, drawn with the agent's own generator (spreads the agents out)
    NEAREST = "nearest"  # the nearest to the agent
    FIRST = "first"  # the first in the thesis's grid order (MATLAB's max over pheromones(:), appendix A)


#: axes (x, y, z of the arena) from most to least significant in the thesis's grid order: its grid is
#: (long side, vertical, short side) stored column-major, so the short side (our y) varies slowest
THESIS_GRID_ORDER = (1, 2, 0)


class Strategy(enum.IntEnum):
    """How the next search point is chosen (appendix A, column 6 of the agent data)."""

    RANDOM = 0  # anywhere in the arena
    PHEROMONE = 1  # the strongest pheromone of the wanted sign
    LOCAL = 2  # near the agent


ALTITUDE_TOL = 0.03
"""m: an agent counts as at a flying altitude within this."""
COLUMN_TOL = 0.01
"""m: horizontal distance from an object's column at which the straight descent starts."""
DRIFT_TOL = 0.04
"""m: a descent pushed this far off its column is broken off: the agent climbs straight back to its
flying altitude and comes over the object again (a diagonal way back would sweep its box, or the box
hanging under it, through a neighbouring stack)."""
SETTLED_SPEED = 0.03
"""m/s: an agent starts a descent only below this speed."""
RELEASE_SPEED = 0.02
"""m/s: an agent lets go of its box only below this speed."""
VERTICAL_CLEARANCE = 0.03
"""m: a carried box or an airframe stays this far above what it flies over."""
VIEW_MARGIN = ALTITUDE_TOL
"""m: an object counts as in view from an altitude when it is this much inside the vertical view range
(horizontally the margin is ``arrive_tol``: an agent arrives that near its search point)."""
GRASP_FRACTION = 0.6
"""An agent asks to grasp within this fraction of the attach threshold (margin for tracking error)."""
CLEARANCE_SIGMAS = 3.0
"""Least release clearance, in standard deviations of the agent's own position estimate."""
DESCENT_TIMEOUT_S = 20.0
"""s: default of ``descent_timeout_s``."""
THESIS_VIEW_M = 0.15
"""m: the thesis's view window, two agent radii of its 15 cm airframe (Tables 3.2 and 5.1)."""
MAX_STEPS = 6
QUEUE_MARGIN = 0.03
"""m: ``queue_at_slots``: a slot's working square reaches an airframe's width and this much (per axis) from the
column where a carrier stands to serve it: two carriers nearer than that touch, or the upper one's wake pushes
the lower one down."""
QUEUE_GAP = 0.05
"""m: ``queue_at_slots``: a carrier waits this much further out than every slot's working square."""
QUEUE_PATIENCE_S = 40.0
"""s: default of ``queue_patience_s``: twice ``DESCENT_TIMEOUT_S``. A carrier searching for an open slot at the
search altitude, where the bottom slots are out of its view, stood in a slot's working square, held by the
waiting carriers' wake columns, while they waited for it to leave (tower of 5 and ring, stigmergy + orca: no
progress for 150 s)."""
"""Most phase steps an agent takes in one planner tick (a step that only changes the phase lets the next act)."""


def _field_error(name: str, message: str) -> ConfigError:
    return ConfigError(message, field=f"planner.params.{name}")


class StigmergyParams(Params):
    """Parameters of the 3-D stigmergy planner (defaults: thesis Tables 5.1 and 5.2, plus our extensions).

    The floor, depot and cruise altitudes default (null) to values derived from the task layout
    (see ``FlightGeometry.from_task``); ``release_dwell_s`` defaults to 0 on the true state and
    0.5 s when the agent flies on an estimate. Each extension of the thesis's algorithm is one
    switch (``claims`` ... ``descent_timeout_s``), on by default; ``preset: thesis`` turns them
    all off (the module's docstring has the table).
    """

    preset: Preset | None = Field(
        None,
        strict=False,
        description="thesis: every extension off, as the thesis's chapters and appendix "
        "code write the algorithm (explicit values still win)",
    )

    cell_size: float = Field(
        0.1, ge=0.01, le=1.0, description="m, edge of a pheromone cell (thesis: 10 cm, a 30 x 10 x 10 grid)"
    )
    grid_height: float = Field(1.0, gt=0.0, le=20.0, description="m, top of the pheromone grid")
    box_pheromone: float = Field(1.0, gt=0.0, le=1e3, description="value set in the agent's cell when it grasps a box")
    goal_pheromone: float = Field(
        -1.0, ge=-1e3, lt=0.0, description="value set in the agent's cell when it places a box"
    )
    trail_pheromone: float = Field(
        0.2, ge=0.0, le=1e3, description="value set in every empty cell an agent passes while looking for a box"
    )
    fatigue: float = Field(0.0, ge=0.0, le=1e3, description="value units per second by which the task layer fades")
    local_radius: float = Field(
        0.2, gt=0.0, le=100.0, description="m, half-width of the square of a local random search point"
    )
    distance_scale: float | None = Field(
        None,
        gt=0.0,
        le=1e3,
        description="m, nearer pheromone cells appear stronger (value / (1 + d / "
        "scale)); null: the strongest cell wins",
    )
    ties: TieBreak = Field(
        TieBreak.RANDOM, strict=False, description="which of equally strong cells wins: random or nearest"
    )
    floor_altitude: float | None = Field(
        None, gt=0.0, le=100.0, description="m, flying altitude over the open floor (null: from the layout)"
    )
    look_altitude: float | None = Field(
        None, gt=0.0, le=100.0, description="m, flying altitude over the depot (null: from the layout)"
    )
    cruise_altitude: float | None = Field(
        None, gt=0.0, le=100.0, description="m, flying altitude over the structure (null: from the task)"
    )
    arrive_tol: float = Field(
        0.05, gt=0.0, le=10.0, description="m, horizontal distance at which a search point counts as reached"
    )
    structure_margin: float = Field(
        0.02, ge=0.0, le=1.0, description="m, keep-out zone around the structure beyond one agent radius"
    )
    release_clearance: float = Field(
        0.004,
        ge=0.0,
        le=0.5,
        description="m, least height of the box above its slot when it is let go (its drop point is release_tol higher)",
    )
    release_tol: float = Field(
        0.005, gt=0.0, le=0.5, description="m, per-axis position error within which the box is let go"
    )
    release_dwell_s: float | None = Field(
        None,
        ge=0.0,
        le=60.0,
        description="s, time within release_tol before the box is let go (null: 0, or 0.5 s flying on an estimate)",
    )
    snapshot_s: float = Field(
        1.0, ge=0.0, le=1e4, description="s, period of the pheromone snapshots kept for the figures (0: none)"
    )
    # ---- extensions of the thesis's algorithm (thesis value in brackets)
    claims: bool = Field(True, description="leave a box or slot to a neighbour already working over it [false]")
    wide_view: bool = Field(
        True,
        description="notice every object the task shows (view_radius + grasp height "
        "around its grasp point); false: only within view_window [false]",
    )
    view_window: float = Field(
        THESIS_VIEW_M,
        gt=0.0,
        le=10.0,
        description="m, half-width (max-norm, horizontal, centre to centre) of the view "
        "without wide_view: two radii of the thesis's 15 cm airframe",
    )
    layout_altitudes: bool = Field(
        True,
        description="floor and depot altitudes for seeing, search points over the "
        "structure moved to its edge, local search along its face "
        "[false: one altitude at which a carried box clears the "
        "boxes on the floor, points as drawn]",
    )
    drift_breakoff: bool = Field(
        True, description="break off a descent pushed off its column and climb straight back [false]"
    )
    descent_timeout_s: float | None = Field(
        DESCENT_TIMEOUT_S,
        gt=0.0,
        le=1e4,
        description="s, break off a descent with a box that has not ended in a release by then [null: never]",
    )
    release_over_neighbours: bool = Field(
        True,
        description="let a box for a slot with boxes beside it go above their tops, where the task's guide "
        "takes it [false]",
    )
    raise_drop_point: bool = Field(
        True,
        description="the drop point release_tol above the least release height, so a settled agent never "
        "presses its box onto the one below [false: release_clearance over the slot]",
    )
    clear_spent_goals: bool = Field(
        True,
        description="at a search point with no open slot in view, clear the goal marks over the columns "
        "whose every slot is in view [false]",
    )
    search_near: bool = Field(
        True,
        description="draw a random search point within the view range of a slot (carrying) or a depot box "
        "(empty) drawn at random, not anywhere in the arena [false]",
    )
    queue_at_slots: bool = Field(
        True,
        description="a carrier whose slot's working square (an airframe's width and QUEUE_MARGIN round the "
        "column it serves the slot from) holds another carrier, and which is not in it itself, waits outside "
        "every slot's square until that one is free [false]",
    )
    queue_patience_s: float | None = Field(
        QUEUE_PATIENCE_S,
        gt=0.0,
        le=1e4,
        description="s, with queue_at_slots: a carrier that has held a slot's working square this long is not "
        "serving it (a descent breaks off after descent_timeout_s), and no longer holds a waiting one out "
        "[null: it holds it for ever]",
    )

    #: pheromone layers of the grid (sizes its memory)
    LAYERS: ClassVar[int] = 1
    PRESETS: ClassVar[dict[Preset, dict[str, Any]]] = {
        Preset.THESIS: {
            "cell_size": 0.1,
            "grid_height": 1.0,
            "box_pheromone": 1.0,
            "goal_pheromone": -1.0,
            "trail_pheromone": 0.2,
            "fatigue": 0.0,
            "local_radius": 0.2,
            "distance_scale": None,
            "ties": TieBreak.FIRST.value,
            "claims": False,
            "wide_view": False,
            "view_window": THESIS_VIEW_M,
            "layout_altitudes": False,
            "drift_breakoff": False,
            "descent_timeout_s": None,
            "release_over_neighbours": False,
            "clear_spent_goals": False,
            "raise_drop_point": False,
            "queue_at_slots": False,
            "search_near": False,
        }
    }

    def check_layout(self, info: TaskInfo) -> None:
        """Refuse altitudes that cannot work with the task's layout, and slots no agent would see
        (``FlightGeometry.from_task``, as each agent derives them when the run starts)."""
        if len(info.layout.slots) and info.layout.box_size > 0:
            FlightGeometry.from_task(info, self)

    def check_for(self, context: PlanContext) -> None:
        """Refuse a pheromone grid (with its snapshots) larger than the memory budget."""
        nx, ny = (max(1, math.ceil(x / self.cell_size - 1e-9)) for x in context.arena_size)
        nz = max(1, math.ceil(self.grid_height / self.cell_size - 1e-9))
        need = self.LAYERS * 16.0 * nx * ny * nz  # values (float64) and sources (int64) per cell
        if self.snapshot_s > 0.0:
            period = max(self.snapshot_s, 1.0 / context.planner_hz)
            need += self.LAYERS * 4.0 * nx * ny * (math.floor(context.time_limit_s / period) + 1)
        check_memory(
            "cell_size",
            need,
            context.memory_budget,
            f"a pheromone grid of {nx} x {ny} x {nz} cells ({self.LAYERS} layer(s), with its snapshots)",
        )


class LayeredStigmergyParams(StigmergyParams):
    """Parameters of the layered stigmergy planner: those of 3-D stigmergy plus the presence layer
    (defaults: thesis Table 6.1)."""

    presence_pheromone: float = Field(2.0, gt=0.0, le=1e3, description="value an agent sets in its cell every tick")
    presence_fatigue: float = Field(
        2.0, gt=0.0, le=1e3, description="value units per second by which presence marks fade (2/s erases a 2 in 1 s)"
    )
    lookahead: float = Field(
        0.2,
        gt=0.0,
        le=2.0,
        description="m, how far along its way an agent checks for other agents' marks [0.1: the next cell]",
    )
    detour: bool = Field(
        True,
        description="after a re-plan keep to the new search point for as long as a mark "
        "lasts before going for a seen object again [false]",
    )

    LAYERS: ClassVar[int] = 2
    PRESETS: ClassVar[dict[Preset, dict[str, Any]]] = {
        Preset.THESIS: {
            **StigmergyParams.PRESETS[Preset.THESIS],
            "presence_pheromone": 2.0,
            "presence_fatigue": 2.0,
            "lookahead": 0.1,
            "detour": False,
        }
    }


@dataclasses.dataclass(frozen=True)
class Zone:
    """Rectangles of the floor over which agents fly at least at one altitude.

    Attributes:
        lo: (k, 2) m, lower corners.
        hi: (k, 2) m, upper corners.
        altitude: m, least flying altitude over them.
    """

    lo: NDArray[np.float64]
    hi: NDArray[np.float64]
    altitude: float

    def contains(self, xy: NDArray[np.float64]) -> bool:
        """True when the point (2,) m lies in the zone."""
        return bool(_zone_contains(self.lo, self.hi, float(xy[0]), float(xy[1])))

    def entry(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> float | None:
        """Fraction of the way from a (2,) to b (2,) m at which the segment enters the zone (0 when a
        is inside), or None when it stays out."""
        t = _zone_entry(self.lo, self.hi, float(a[0]), float(a[1]), float(b[0]), float(b[1]))
        return None if t < 0.0 else t


# The zone tests run for every agent at every planner tick (a zone of a 100-box depot is 100
# rectangles): compiled slab tests, one rectangle at a time, instead of (k, 2) arrays per call.
@numba.njit(cache=True)
def _zone_contains(lo: NDArray[np.float64], hi: NDArray[np.float64], x: float, y: float) -> bool:
    """True when (x, y) m lies in one of the rectangles lo (k, 2) .. hi (k, 2) m (edges included)."""
    for k in range(lo.shape[0]):
        if lo[k, 0] <= x <= hi[k, 0] and lo[k, 1] <= y <= hi[k, 1]:
            return True
    return False


@numba.njit(cache=True)
def _slab(lo: float, hi: float, a: float, d: float) -> tuple[float, float]:
    """Entry and exit fractions of the line a + t d through the slab [lo, hi] (d = 0: inside or never)."""
    if d == 0.0:
        if lo <= a <= hi:
            return -np.inf, np.inf
        return np.inf, -np.inf
    t1, t2 = (lo - a) / d, (hi - a) / d
    return min(t1, t2), max(t1, t2)


@numba.njit(cache=True)
def _zone_entry(lo: NDArray[np.float64], hi: NDArray[np.float64], ax: float, ay: float, bx: float, by: float) -> float:
    """Least fraction in [0, 1] of the way from (ax, ay) to (bx, by) m at which the segment is inside one of
    the rectangles lo (k, 2) .. hi (k, 2) m (0 when it starts inside), or -1 when it stays out."""
    dx, dy = bx - ax, by - ay
    best = np.inf
    for k in range(lo.shape[0]):
        xin, xout = _slab(lo[k, 0], hi[k, 0], ax, dx)
        yin, yout = _slab(lo[k, 1], hi[k, 1], ay, dy)
        t_in, t_out = max(xin, yin), min(xout, yout)
        if t_out >= max(t_in, 0.0) and t_in <= 1.0 and t_in < best:
            best = t_in
    if best == np.inf:
        return -1.0
    return max(0.0, best)


def _floor_altitude(p: StigmergyParams, info: ConstructionInfo, view: float, depot_grasp: float) -> float:
    """m, flying altitude over the open floor derived from the layout.

    A carried box clears a box lying on the floor (one knocked out of the structure or let go beside
    it lies where carriers stop to climb: a box caught on its edge pushes on the carried box gh + bs/2
    below the airframe's centre, a torque the attitude loop of a small airframe cannot hold). With
    ``layout_altitudes`` the floor is also level with the middle of the structure's grasp points (slots
    of every layer in view from its edge), but no higher than where the depot's boxes are still in view
    (the depot's altitude is not below the floor's); without it, only the clearance, counted from where
    a climb ends (``ALTITUDE_TOL`` below the altitude).
    """
    gh, bs = info.layout.grasp_height, info.layout.box_size
    clear = bs + gh + 0.5 * bs + VERTICAL_CLEARANCE
    if not p.layout_altitudes:
        return clear + ALTITUDE_TOL
    slot_grasp = info.layout.slots[:, 2] + gh
    middle = 0.5 * (float(slot_grasp.min()) + float(slot_grasp.max()))
    return max(clear, min(middle, depot_grasp + view - VIEW_MARGIN))


def _around(xy: NDArray[np.float64], half: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    cols = np.unique(np.round(np.asarray(xy, dtype=float).reshape(-1, 2), 9), axis=0)
    return cols - half, cols + half


@dataclasses.dataclass(frozen=True)
class FlightGeometry:
    """Flying altitudes over the floor, derived once from the task layout every agent is told.

    Three levels: the open floor, low enough to see slots of every layer from beside the structure;
    the depot, where a carried box must clear the boxes still waiting; the structure, where it must
    clear the finished structure. An agent climbs before it enters a higher zone.

    Attributes:
        floor_altitude: m, over the open floor.
        depot: the depot boxes' footprints (inflated by one agent radius and a margin) and their altitude.
        structure: the same around the structure's columns: the keep-out zone below the cruise altitude.
        arena_lo: (2,) m, lowest reachable agent centre.
        arena_hi: (2,) m, highest reachable agent centre.
        view_range: m, an agent sees an object whose grasp point is this close (task rule).
        standoff: m, how far before a higher zone an agent climbs.
        columns: (c, 2) m, centres of the structure's columns of slots.
        hidden: (h, 2) m, centres of the columns with a slot an agent beside the structure does not see
            (searched for from above them).
        sight: m, the farthest horizontal (per-axis) distance from a search point beside the structure at
            which a column's slots count as in view (the view range less ``arrive_tol``; 0: not checked).
    """

    floor_altitude: float
    depot: Zone
    structure: Zone
    arena_lo: NDArray[np.float64]
    arena_hi: NDArray[np.float64]
    view_range: float
    standoff: float
    columns: NDArray[np.float64]
    hidden: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros((0, 2)))
    sight: float = 0.0

    @property
    def look_altitude(self) -> float:
        """m, flying altitude over the depot."""
        return self.depot.altitude

    @property
    def cruise_altitude(self) -> float:
        """m, flying altitude over the structure."""
        return self.structure.altitude

    @staticmethod
    def from_task(info: ConstructionInfo, p: StigmergyParams) -> FlightGeometry:
        """Derive the altitudes and zones of a construction task.

        Raises:
            ConfigError: altitudes given explicitly that do not rise from floor to depot to structure,
                or (``layout_altitudes``) a slot no agent sees, from beside the structure at the floor
                altitude or from above it at the cruise altitude (naming ``task.view_radius``).
        """
        gh, bs, r = info.layout.grasp_height, info.layout.box_size, info.agent_radius
        view = float(info.layout.view_radius) + gh
        carried_bottom = gh + 0.5 * bs  # m, agent centre above the bottom of its box
        slot_grasp = info.layout.slots[:, 2] + gh
        seeing = p.layout_altitudes
        ground_grasp = 0.5 * bs + gh
        depot_top = float(np.max(info.layout.depot[:, 2])) + 0.5 * bs if len(info.layout.depot) else bs
        depot_grasp = float(np.min(info.layout.depot[:, 2])) + gh if len(info.layout.depot) else ground_grasp
        floor = p.floor_altitude if p.floor_altitude is not None else _floor_altitude(p, info, view, depot_grasp)
        look = (
            p.look_altitude
            if p.look_altitude is not None
            else max(ground_grasp + 0.5 * view, depot_top + carried_bottom + VERTICAL_CLEARANCE, floor)
            if seeing
            else max(floor, depot_top + carried_bottom + VERTICAL_CLEARANCE + ALTITUDE_TOL)
        )
        top = float(np.max(info.layout.slots[:, 2])) + 0.5 * bs
        clear = top + carried_bottom + VERTICAL_CLEARANCE  # m, a carried box clears the finished structure
        cruise = (
            p.cruise_altitude if p.cruise_altitude is not None else max(float(info.layout.search_height), clear, look)
        )
        if not floor <= look <= cruise:
            raise _field_error(
                "cruise_altitude",
                f"altitudes must rise from floor ({floor:.3f} m) to depot ({look:.3f} m) to structure ({cruise:.3f} m)",
            )
        half = 0.5 * bs + r + p.structure_margin
        lo = np.full(2, r)
        hi = np.maximum(np.asarray(info.arena_size, dtype=float)[:2] - r, lo)
        cols = np.unique(np.round(info.layout.slots[:, :2], 9), axis=0)
        geo = FlightGeometry(
            float(floor),
            Zone(*_around(info.layout.depot[:, :2], half), float(look)),
            Zone(*_around(cols, half), float(cruise)),
            lo,
            hi,
            view,
            standoff=max(0.03, p.structure_margin),
            columns=cols,
            sight=view - p.arrive_tol,
        )
        if not seeing:
            return geo
        # slots an agent beside the structure does not see are searched for from above: over their columns
        # at the cruise altitude, lowered (not below the clearance of the finished structure) to see them
        norm = str(info.layout.view_norm)
        hidden_cols = np.zeros(len(cols), dtype=bool)
        for k, c in enumerate(cols):
            edge = geo.outside(c, c)
            reach = float(view_distance(np.array([*(edge - c), 0.0]), norm)) if geo.inside(c) else 0.0
            in_col = np.all(np.isclose(info.layout.slots[:, :2], c, atol=1e-9), axis=1)
            beside = reach <= view - p.arrive_tol and np.all(np.abs(slot_grasp[in_col] - floor) <= view - VIEW_MARGIN)
            hidden_cols[k] = not beside
        if not hidden_cols.any():
            return geo
        in_hidden = np.any(
            np.all(np.isclose(info.layout.slots[:, None, :2], cols[hidden_cols][None, :, :], atol=1e-9), axis=2), axis=1
        )
        lowest = float(np.min(slot_grasp[in_hidden]))
        if p.cruise_altitude is None:
            cruise = max(clear, look, min(cruise, lowest + view - VIEW_MARGIN))
        if cruise - lowest > view - VIEW_MARGIN:
            s = int(np.flatnonzero(in_hidden & np.isclose(slot_grasp, lowest))[0])
            q = info.layout.slots[s]
            least = math.ceil((cruise - lowest + VIEW_MARGIN - gh) * 1e3 + 1e-6) / 1e3  # m, up to the millimetre
            raise LayoutNeedError(
                f"slot {s} at ({q[0]:g}, {q[1]:g}, {q[2]:g}) is out of view both from beside the structure (at the "
                f"floor altitude {floor:.3f} m) and from above it (at the cruise altitude {cruise:.3f} m, which "
                f"clears the finished structure); an agent sees {view:.3f} m around it: a view_radius of at least "
                f"{least:.3f} m lets agents see it from above (unset, it is derived from the layout)",
                field="task.view_radius",
                least=least,
            )
        structure = Zone(geo.structure.lo, geo.structure.hi, float(cruise))
        return dataclasses.replace(geo, structure=structure, hidden=cols[hidden_cols])

    @property
    def zones(self) -> tuple[Zone, Zone]:
        """The zones, lower first."""
        return self.depot, self.structure

    def inside(self, xy: NDArray[np.float64]) -> bool:
        """True when the point (2,) m lies in the structure's keep-out zone."""
        return self.structure.contains(xy)

    def altitude(self, xy: NDArray[np.float64]) -> float:
        """Flying altitude, m, over the point (2,) m."""
        return max([self.floor_altitude, *(z.altitude for z in self.zones if z.contains(xy))])

    def entry(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> float | None:
        """Fraction of the way from a (2,) to b (2,) m at which the segment enters the keep-out zone
        (0 when a is inside), or None when it stays out."""
        return self.structure.entry(a, b)

    def outside(
        self, xy: NDArray[np.float64], start: NDArray[np.float64], *, keep_hidden: bool = False
    ) -> NDArray[np.float64]:
        """The point (2,) m itself when it lies outside the keep-out zone, else the point just outside
        it (``standoff`` beyond an edge, within the arena) on the shortest way from ``start`` (2,) m
        via the edge to ``xy``; with ``keep_hidden`` (a search for slots), a point whose nearest column
        is ``hidden`` is moved over that column instead (its slots are seen from above), and otherwise
        to an edge from which that column is in view (``sight``; the far side of a structure several
        columns deep, for a column there)."""
        if not self.inside(xy):
            return xy
        c = self.columns[int(np.argmin(np.max(np.abs(self.columns - xy), axis=1)))] if len(self.columns) else xy
        if keep_hidden and len(self.hidden):
            if np.any(np.all(np.isclose(self.hidden, c, atol=1e-9), axis=1)):
                return c.copy()
        k = self.structure
        pts = self._along_axes(xy, k.lo - self.standoff, k.hi + self.standoff)
        ok = np.array([not self.inside(c) for c in pts])
        if not ok.any():  # the zone fills the arena across: nowhere to look from but above it
            return xy
        pts = pts[ok]
        if keep_hidden and self.sight > 0.0:
            seen = np.max(np.abs(pts - c), axis=1) <= self.sight
            pts = pts[seen] if seen.any() else pts
        cost = np.linalg.norm(pts - xy, axis=1) + np.linalg.norm(pts - start, axis=1)
        return pts[int(np.argmin(cost))]

    def face_normal(self, xy: NDArray[np.float64], reach: float) -> NDArray[np.float64] | None:
        """Vector (2,) m from the point ``xy`` (2,) m to the nearest point of the keep-out zone when the
        point lies outside it but within ``reach`` m of it (an agent beside the structure), else None."""
        k = self.structure
        if len(k.lo) == 0:
            return None
        nearest = np.clip(xy, k.lo, k.hi)  # (z, 2) nearest point of each column's square
        d = np.hypot(*(nearest - xy).T)
        j = int(np.argmin(d))
        if not 0.0 < d[j] <= reach:
            return None
        return nearest[j] - xy

    def _along_axes(
        self, xy: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """(2k + 2k, 2) m: the points straight along x from ``xy`` (2,) m to each edge of the squares ``lo``,
        ``hi`` (k, 2) m, then along y, clipped to the arena."""
        cand = [np.array([x, xy[1]]) for x in (*lo[:, 0], *hi[:, 0])]
        cand += [np.array([xy[0], y]) for y in (*lo[:, 1], *hi[:, 1])]
        return np.clip(np.array(cand), self.arena_lo, self.arena_hi)

    def off_columns(self, xy: NDArray[np.float64], half: float) -> NDArray[np.float64]:
        """The point (2,) m itself when it lies at least ``half`` m (per axis) from every column, else the
        nearest point that does, straight along an axis from it and within the arena (itself when none
        does: a structure that spans the arena)."""
        if len(self.columns) == 0 or np.min(np.max(np.abs(self.columns - xy), axis=1)) >= half:
            return xy
        pts = self._along_axes(xy, self.columns - half - 1e-6, self.columns + half + 1e-6)
        ok = np.min(np.max(np.abs(pts[:, None, :] - self.columns[None, :, :]), axis=2), axis=1) >= half
        if not ok.any():
            return xy
        pts = pts[ok]
        return pts[int(np.argmin(np.linalg.norm(pts - xy, axis=1)))]


@dataclasses.dataclass
class Sighting:
    """An object an agent works on.

    Attributes:
        id: the box or slot id, -1 for none.
        pos: (3,) m, its centre where the agent last saw it.
    """

    id: int = -1
    pos: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros(3))


@dataclasses.dataclass(frozen=True)
class Carry:
    """The box an agent holds.

    Attributes:
        box: its id.
        offset: (3,) m, its centre relative to the agent's (measured when it was grasped).
    """

    box: int
    offset: NDArray[np.float64]


@dataclasses.dataclass
class ReleaseWatch:
    """How long an agent descending onto a slot has been ready to let go.

    Attributes:
        descent_start: s, when the descent onto the slot started.
        since: s, since when the agent's position has stayed within ``release_tol`` of the drop
            point (None: it is not).
        window: (time s, position (3,) m) samples since then (the dwell's average).
    """

    descent_start: float = math.inf
    since: float | None = None
    window: list[tuple[float, NDArray[np.float64]]] = dataclasses.field(default_factory=list)

    def clear(self) -> None:
        """Not ready to let go (the dwell starts again)."""
        self.since = None


class Stigmergy:
    """3-D stigmergy (thesis chapter 5): one instance per agent, the pheromone grid shared.

    Each agent is a state machine over ``Phase``; each phase's step is one method
    (``_step_<phase>``) that returns a command, or None after a transition when the next phase
    should act in the same tick (at most ``MAX_STEPS`` steps a tick). The outcome of the last
    GRASP or RELEASE is noticed first (``_sync``), since the task applies them between ticks.

    Per-agent state besides the phase: the search (``strategy``, ``target``), the box and slot
    worked on (``box``, ``slot``: ``Sighting``), the box held (``carry``), the column the agent
    climbs straight up on (``column``), the point it latched to climb before a higher zone
    (``climb_at``) and the release dwell (``watch``).

    Args:
        params: validated ``StigmergyParams`` (default: the defaults).
    """

    name: ClassVar[str] = "stigmergy"
    centralized: ClassVar[bool] = False
    Params: ClassVar[type[StigmergyParams]] = StigmergyParams

    def __init__(self, params: StigmergyParams | None = None) -> None:
        self.params = params if params is not None else self.Params()
        if not isinstance(self.params, self.Params):
            raise TypeError(f"{self.name}: expected {self.Params.__name__}, got {type(self.params).__name__}")
        self._steps = {
            Phase.CHOOSE_BOX: self._step_choose_box,
            Phase.SEEK_BOX: self._step_seek_box,
            Phase.TO_BOX: self._step_to_box,
            Phase.RECLIMB_BOX: self._step_reclimb_box,
            Phase.DESCEND_BOX: self._step_descend_box,
            Phase.GRASPING: self._step_descend_box,
            Phase.LIFT: self._step_lift,
            Phase.CHOOSE_GOAL: self._step_choose_goal,
            Phase.SEEK_GOAL: self._step_seek_goal,
            Phase.TO_SLOT: self._step_to_slot,
            Phase.RECLIMB_SLOT: self._step_reclimb_slot,
            Phase.DESCEND_SLOT: self._step_descend_slot,
            Phase.RELEASING: self._step_descend_slot,
            Phase.CLIMB: self._step_climb,
        }

    # ------------------------------------------------------------- the medium
    @classmethod
    def layer_specs(cls, p: StigmergyParams) -> list[LayerSpec]:
        """The pheromone layers this planner uses."""
        return [LayerSpec(Layer.TASK.value, fatigue=p.fatigue)]

    @classmethod
    def make_medium(cls, params: StigmergyParams, info: ConstructionInfo) -> PheromoneGrid:
        """The pheromone grid shared by the agents of a run, from the planner's validated parameters."""
        return PheromoneGrid(
            info.arena_size,
            cls.layer_specs(params),
            cell=params.cell_size,
            height=params.grid_height,
            snapshot_s=params.snapshot_s,
        )

    # ------------------------------------------------------------- protocol
    def reset(self, agent_id: int, rng: np.random.Generator, info: ConstructionInfo) -> None:
        """Start a run as agent ``agent_id``: looking for a box, no pheromone strategy used yet."""
        if len(info.layout.slots) == 0 or info.layout.box_size <= 0:
            raise ConfigError("the stigmergy planners solve construction tasks (boxes and slots)", field="planner.name")
        self.id = int(agent_id)
        self.rng = rng
        self.info = info
        self.geo = FlightGeometry.from_task(info, self.params)
        self.attach = float(info.layout.attach_threshold)
        sigma = float(info.extra.get("position_std", 0.0))  # m, per-axis std of the agent's own position estimate
        self.sigma = sigma
        # m, height of the drop point's box over its slot: the settle test lets the agent go anywhere
        # within release_tol of it, so the box's bottom clears the slot by release_clearance at the lowest
        self.clearance = max(self.params.release_clearance, CLEARANCE_SIGMAS * sigma) + (
            self.params.release_tol if self.params.raise_drop_point else 0.0
        )
        # (S,) m, release height of each slot's box (over its neighbours' tops with ``release_over_neighbours``)
        self.clearances = release_clearances(info, self.clearance, over_neighbours=self.params.release_over_neighbours)
        dwell = self.params.release_dwell_s
        self.dwell = (0.5 if sigma > 0.0 else 0.0) if dwell is None else float(dwell)  # s
        self.phase = Phase.CHOOSE_BOX
        self.strategy = Strategy.RANDOM  # the thesis starts every agent in mode 0 ("random")
        self.target = np.zeros(2)  # m, current search point
        self.box = Sighting()  # the box being fetched
        self.slot = Sighting()  # the slot being served
        self.carry: Carry | None = None  # the box held
        self.grasp_offset = np.zeros(3)  # m, box centre relative to the agent when it asked to GRASP
        self.column = np.zeros(2)  # m, where the agent climbs straight up (LIFT, CLIMB, RECLIMB_*)
        self.climb_at: NDArray[np.float64] | None = None  # m, where it latched to climb before a higher zone
        self.watch = ReleaseWatch()
        self.holders: dict[int, float] = {}  # queue_patience_s: neighbour id -> since when it holds the square
        self.queue_at: NDArray[np.float64] | None = None  # (x, y, t): the column queued for, and when last

    def activity(self) -> str:
        """What the agent is doing, in words: its phase, search point, and the box or slot it works on."""
        words = [f"phase {self.phase.name.lower()}"]
        if self.phase in (Phase.SEEK_BOX, Phase.SEEK_GOAL):
            words.append(f"{self.strategy.name.lower()} search point ({self.target[0]:.2f}, {self.target[1]:.2f})")
        if self.box.id >= 0:
            words.append(f"box {self.box.id} at ({self.box.pos[0]:.2f}, {self.box.pos[1]:.2f}, {self.box.pos[2]:.2f})")
        if self.slot.id >= 0:
            q = self.slot.pos
            words.append(f"slot {self.slot.id} at ({q[0]:.2f}, {q[1]:.2f}, {q[2]:.2f})")
        if self.carry is not None:
            words.append(f"holding box {self.carry.box}")
        return ", ".join(words)

    @property
    def holding(self) -> bool:
        """True while the agent holds a box (from the grasp the task applied to the release)."""
        return self.carry is not None

    @property
    def offset(self) -> NDArray[np.float64]:
        """(3,) m, the held box's centre relative to the agent (straight under it when not holding)."""
        return self.carry.offset if self.carry is not None else np.array([0.0, 0.0, -self.info.layout.grasp_height])

    def plan(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command:
        """The agent's command for the next planner period."""
        self._sync(obs, medium)
        for _ in range(MAX_STEPS):  # a step returns None when it changed the phase and the next one should act now
            cmd = self._steps[self.phase](obs, medium)
            if cmd is not None:
                return cmd
        return Command.goto(obs.position)

    # ------------------------------------------------------------- outcome of the last action
    def _sync(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> None:
        """Notice the outcome of the last GRASP or RELEASE (the task applies them between ticks)."""
        if obs.carrying >= 0 and self.carry is None:
            self._grasped(obs, medium)
        elif obs.carrying < 0 and self.carry is not None:
            self._let_go(obs, medium)
        elif self.phase is Phase.GRASPING:  # the grasp did not take: keep at it
            self.phase = Phase.DESCEND_BOX
        elif self.phase is Phase.RELEASING:  # the box is still held: keep at it
            self.phase = Phase.DESCEND_SLOT

    def _grasped(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> None:
        """GRASPING -> LIFT (+1 in the agent's cell)."""
        self.carry = Carry(int(obs.carrying), self.grasp_offset if self.phase is Phase.GRASPING else self.offset)
        self.column = obs.position[:2].copy()
        self.box = Sighting(-1, self.box.pos)
        self._mark(medium, obs.position, self.params.box_pheromone, "boxes_found")
        self.phase = Phase.LIFT

    def _let_go(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> None:
        """RELEASING -> CLIMB (-1 in the agent's cell); a box that slipped out of the grip -> CHOOSE_BOX."""
        assert self.carry is not None
        if self.phase is Phase.RELEASING:
            self._mark(medium, obs.position, self.params.goal_pheromone, "goals_found")
            self.column = obs.position[:2].copy()
            self.phase = Phase.CLIMB
        else:
            self.phase = Phase.CHOOSE_BOX
        self.carry = None
        self.slot = Sighting(-1, self.slot.pos)
        self.watch.clear()

    def _mark(self, medium: PheromoneGrid | None, p: NDArray[np.float64], value: float, tally: str) -> None:
        if medium is not None:
            medium.deposit(Layer.TASK.value, p, value, rule=DepositRule.SET, source=self.id)
            medium.tally(tally)

    def _replan(self) -> None:
        """Drop the current search point and object; choose again (by the strategy cycle)."""
        self.phase = Phase.CHOOSE_GOAL if self.holding else Phase.CHOOSE_BOX
        self.box = Sighting(-1, self.box.pos)
        self.slot = Sighting(-1, self.slot.pos)

    # ------------------------------------------------------------- search (thesis states 0-3)
    def _step_choose_box(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """CHOOSE_BOX -> SEEK_BOX: the next search point for a box."""
        self._choose(obs, medium, +1)
        self.phase = Phase.SEEK_BOX
        return None

    def _step_choose_goal(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """CHOOSE_GOAL -> SEEK_GOAL: the next search point for an open slot."""
        self._choose(obs, medium, -1)
        self.phase = Phase.SEEK_GOAL
        return None

    def _choose(self, obs: ConstructionObservation, medium: PheromoneGrid | None, sign: int) -> None:
        """Next search point by the thesis's cycle: random, strongest pheromone, local random, random, ..."""
        p = obs.position
        ties = self.params.ties
        best = None
        if medium is not None:
            best = medium.strongest(
                Layer.TASK.value,
                sign,
                near=p,
                distance_scale=self.params.distance_scale,
                rng=self.rng if ties is TieBreak.RANDOM else None,
                by_column=True,
                first_by=THESIS_GRID_ORDER if ties is TieBreak.FIRST else None,
            )
        g = self.geo
        layout = self.params.layout_altitudes
        if best is None or self.strategy == Strategy.LOCAL:
            self.strategy = Strategy.RANDOM
            near = (
                (self.info.layout.slots if sign < 0 else self.info.layout.depot)[:, :2]
                if self.params.search_near
                else None
            )
            if near is not None and len(near):
                c = near[int(self.rng.integers(len(near)))]
                xy = c + self.rng.uniform(-g.view_range, g.view_range, size=2)
            else:
                xy = self.rng.uniform(g.arena_lo, g.arena_hi)
        elif self.strategy == Strategy.RANDOM:
            self.strategy = Strategy.PHEROMONE
            xy = best[:2]
        else:
            self.strategy = Strategy.LOCAL
            r = self.params.local_radius
            xy = p[:2] + self.rng.uniform(-r, r, size=2)
            face = g.face_normal(p[:2], reach=g.standoff + self.params.arrive_tol + COLUMN_TOL) if layout else None
            if face is not None:  # beside the structure: look along its face, where slots are in view
                tangent = np.array([-face[1], face[0]]) / np.hypot(*face)
                xy = p[:2] + self.rng.uniform(-r, r) * tangent + face * (1.0 + 1e-6) + 1e-3 * face / np.hypot(*face)
        # a point over the structure is searched from the edge of the keep-out zone, low, where the
        # agent sees slots of every layer (over the structure it flies too high to see the bottom one)
        xy = np.clip(xy, g.arena_lo, g.arena_hi)
        self.target = g.outside(xy, p[:2], keep_hidden=sign < 0) if layout else xy
        if medium is not None:
            medium.tally(f"target_{self.strategy.name.lower()}")

    def _arrived(self, p: NDArray[np.float64], xy: NDArray[np.float64]) -> bool:
        return bool(np.hypot(*(p[:2] - xy)) <= self.params.arrive_tol and abs(p[2] - self.geo.altitude(xy)) <= 0.05)

    def _step_seek_box(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """SEEK_BOX -> TO_BOX (a free box in view) | CHOOSE_BOX (search point reached); trail 0.2 on the way."""
        p = obs.position
        b = self._pick(obs, obs.seen.box_ids, obs.seen.boxes, np.zeros(3))
        if b >= 0:
            self.box = Sighting(int(obs.seen.box_ids[b]), obs.seen.boxes[b].copy())
            self.phase = Phase.TO_BOX
            return None
        trail = self.params.trail_pheromone
        if medium is not None and trail > 0 and medium.sample(Layer.TASK.value, p) == 0.0:
            medium.deposit(Layer.TASK.value, p, trail, rule=DepositRule.SET, source=self.id)
        if self._arrived(p, self.target):
            self.phase = Phase.CHOOSE_BOX
            return None
        return self._travel(p, self.target)

    def _step_seek_goal(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """SEEK_GOAL -> TO_SLOT (an open, empty slot in view) | CHOOSE_GOAL (search point reached)."""
        p = obs.position
        s = self._pick(obs, obs.seen.slot_ids, obs.seen.slots, self.offset)
        if s >= 0:
            self.slot = Sighting(int(obs.seen.slot_ids[s]), obs.seen.slots[s].copy())
            self.phase = Phase.TO_SLOT
            return None
        if self._arrived(p, self.target):
            self._clear_spent_goals(obs, medium)
            self.phase = Phase.CHOOSE_GOAL
            return None
        return self._travel(p, self.target)

    def _clear_spent_goals(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> None:
        """``clear_spent_goals``: with no open slot in view (claimed ones included), clear the goal marks
        over the columns whose every slot the agent sees from here (a mark over no slot: when its cell's
        centre is in view horizontally)."""
        if medium is None or not self.params.clear_spent_goals or len(obs.seen.slot_ids):
            return
        layer = Layer.TASK.value
        idx = np.argwhere(medium.values[layer] < 0.0)  # (k, 3) cells with a goal mark
        if len(idx) == 0:
            return
        p = obs.position
        # horizontally the agent is where it knows itself to be (within CLEARANCE_SIGMAS of its estimate's
        # error); vertically VIEW_MARGIN inside the view, as the geometry chose the altitudes. With
        # VIEW_MARGIN horizontally too, a column 25 cm beside a search point 4 cm short of which the agent
        # arrived was never cleared though the agent saw it (construction seed 66: 150 s of searches
        # drawn back to spent marks)
        margin = CLEARANCE_SIGMAS * self.sigma
        reach = self.geo.view_range - margin
        norm = str(self.info.layout.view_norm)
        slots = self.info.layout.slots
        d = slots + [0.0, 0.0, self.info.layout.grasp_height] - p
        d[:, 2] = np.abs(d[:, 2]) + max(VIEW_MARGIN - margin, 0.0)
        seen = view_distance(d, norm) <= reach  # (S,)
        half = 0.5 * medium.cell + 1e-9
        cleared = 0
        for c in medium.centre(idx):
            under = np.all(np.abs(slots[:, :2] - c[:2]) <= half, axis=1)  # slots in the mark's column
            if under.any():
                spent = bool(np.all(seen[under]))
            else:
                spent = bool(np.max(np.abs(c[:2] - p[:2])) <= reach)
            if spent:
                medium.deposit(layer, c, 0.0, rule=DepositRule.SET, source=self.id)
                cleared += 1
        if cleared:
            medium.tally("goal_marks_cleared", cleared)

    def _ignoring_objects(self, obs: ConstructionObservation) -> bool:
        """True while the agent keeps to its search point whatever it sees (none in 3-D stigmergy)."""
        return False

    def _pick(
        self,
        obs: ConstructionObservation,
        ids: NDArray[np.int64],
        where: NDArray[np.float64],
        shift: NDArray[np.float64],
    ) -> int:
        """Index (into ``ids``) of the nearest visible object nobody else is working on, or -1.
        ``shift`` (3,) m moves an object's centre to where the agent's column over it is."""
        if len(ids) == 0 or self._ignoring_objects(obs):
            return -1
        par = self.params
        cols = where[:, :2] - shift[:2]
        free = np.array([not (par.claims and self._claimed(obs, c)) for c in cols])
        free &= self._in_window(obs, where)
        if not free.any():
            return -1
        d = np.hypot(*(cols - obs.position[:2]).T)
        d[~free] = np.inf
        return int(np.argmin(d))

    def _in_window(self, obs: ConstructionObservation, where: NDArray[np.float64]) -> NDArray[np.bool_]:
        """(k,) bool: which objects at ``where`` (k, 3) m the agent notices: every one the task shows it with
        ``wide_view``, else those in the thesis's window (object centre to agent centre, largest horizontal
        difference within ``view_window``)."""
        if self.params.wide_view:
            return np.ones(len(where), dtype=np.bool_)
        return np.asarray(np.max(np.abs(where[:, :2] - obs.position[:2]), axis=1) <= self.params.view_window)

    def _claimed(self, obs: ConstructionObservation, xy: NDArray[np.float64]) -> bool:
        """True when a neighbour works over the column at ``xy`` (2,) m: within one agent radius of
        it and lower than this agent, or level with it and nearer (a tie goes to the lower id)."""
        if len(obs.neighbour_ids) == 0:
            return False
        q = obs.neighbour_positions
        p = obs.position
        dn = np.hypot(*(q[:, :2] - xy).T)
        dm = float(np.hypot(*(p[:2] - xy)))
        lower = q[:, 2] < p[2] - 0.05
        level = np.abs(q[:, 2] - p[2]) <= 0.05
        nearer = (dn < dm - 1e-3) | ((np.abs(dn - dm) <= 1e-3) & (obs.neighbour_ids < self.id))
        return bool(np.any((dn < self.info.agent_radius) & (lower | (level & nearer))))

    def _gone(self, p: NDArray[np.float64], obj: NDArray[np.float64]) -> bool:
        """True when an object the agent should see from here (well inside its view range) is not there."""
        grasp = obj + [0.0, 0.0, self.info.layout.grasp_height]
        return bool(view_distance(grasp - p, self.info.layout.view_norm) <= 0.9 * self.geo.view_range)

    # ------------------------------------------------------------- a box: over it, down, grasp, up
    def _box_lost(self, obs: ConstructionObservation, *, claims: bool) -> bool:
        """-> SEEK_BOX when the box is gone from where it should be seen, or (with ``claims``) a
        neighbour works over it; otherwise its position is updated from what is seen."""
        seen = np.flatnonzero(obs.seen.box_ids == self.box.id)
        if seen.size:
            self.box.pos = obs.seen.boxes[seen[0]].copy()
        if (not seen.size and self._gone(obs.position, self.box.pos)) or (
            claims and self.params.claims and self._claimed(obs, self.box.pos[:2])
        ):
            self.phase = Phase.SEEK_BOX  # taken or claimed by another agent: keep looking
            self.box = Sighting(-1, self.box.pos)
            return True
        return False

    def _grasp_point(self) -> NDArray[np.float64]:
        return self.box.pos + [0.0, 0.0, self.info.layout.grasp_height]

    def _step_to_box(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """TO_BOX -> DESCEND_BOX (over it at the flying altitude) | SEEK_BOX (lost)."""
        if self._box_lost(obs, claims=True):
            return None
        return self._approach_box(obs)

    def _approach_box(self, obs: ConstructionObservation) -> Command:
        grasp = self._grasp_point()
        if self._over(obs, grasp[:2]):
            self.phase = Phase.DESCEND_BOX
            return self._grasp(obs, grasp)
        return self._travel(obs.position, grasp[:2])

    def _step_reclimb_box(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """RECLIMB_BOX -> TO_BOX (back at the flying altitude) | SEEK_BOX (lost)."""
        if self._box_lost(obs, claims=True):
            return None
        return self._reclimb(obs, Phase.TO_BOX) or self._approach_box(obs)

    def _step_descend_box(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """DESCEND_BOX -> GRASPING (at the grasp point, steady) | RECLIMB_BOX (pushed off the column) | SEEK_BOX."""
        if self._box_lost(obs, claims=False):
            return None
        grasp = self._grasp_point()
        if self._drifted(obs.position, grasp[:2]):
            self._break_off(obs, Phase.RECLIMB_BOX)
            return self._reclimb(obs, Phase.TO_BOX) or self._approach_box(obs)
        return self._grasp(obs, grasp)

    def _grasp(self, obs: ConstructionObservation, grasp: NDArray[np.float64]) -> Command:
        """Down to the grasp point (3,) m; GRASP there once steady (-> GRASPING)."""
        p = obs.position
        steady = self.dwell == 0.0 or np.linalg.norm(obs.velocity) < SETTLED_SPEED  # a tilted grasp skews the offset
        if np.linalg.norm(p - grasp) <= GRASP_FRACTION * self.attach and steady:
            self.grasp_offset = self.box.pos - p
            self.phase = Phase.GRASPING
            return Command.goto(grasp, Action.GRASP)
        return Command.goto(grasp)

    def _step_lift(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """LIFT -> CHOOSE_GOAL: straight up from the grasp to the flying altitude."""
        return self._rise(obs, Phase.CHOOSE_GOAL)

    # ------------------------------------------------------------- a slot: over it, down, release, up
    def _slot_lost(self, obs: ConstructionObservation, *, claims: bool) -> bool:
        """-> SEEK_GOAL when the slot is no longer open where it should be seen, or (with ``claims``)
        a neighbour works over it."""
        seen = bool(np.any(obs.seen.slot_ids == self.slot.id))
        if (not seen and self._gone(obs.position, self.slot.pos)) or (
            claims and self.params.claims and self._claimed(obs, self.slot.pos[:2] - self.offset[:2])
        ):
            self.phase = Phase.SEEK_GOAL  # filled or claimed by another agent: keep looking
            self.slot = Sighting(-1, self.slot.pos)
            return True
        return False

    def _descent_timed_out(self, obs: ConstructionObservation) -> bool:
        """-> SEEK_GOAL when the box could not be set down within ``descent_timeout_s``."""
        timeout = self.params.descent_timeout_s
        if timeout is not None and obs.time_s - self.watch.descent_start > timeout:
            self.phase = Phase.SEEK_GOAL
            self.slot = Sighting(-1, self.slot.pos)
            self.watch.clear()
            return True
        return False

    def _drop_point(self) -> NDArray[np.float64]:
        """(3,) m, the agent's centre when the box it holds hangs its slot's clearance above the slot."""
        k = self.slot.id
        c = self.clearances[k] if 0 <= k < len(self.clearances) else self.clearance
        return self.slot.pos + [0.0, 0.0, c] - self.offset

    def _step_to_slot(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """TO_SLOT -> DESCEND_SLOT (over it at the flying altitude) | SEEK_GOAL (lost)."""
        if self._slot_lost(obs, claims=True):
            return None
        return self._approach_slot(obs)

    def _approach_slot(self, obs: ConstructionObservation) -> Command:
        drop = self._drop_point()
        hold = self._queue_point(obs, drop[:2])
        if hold is not None:
            return self._travel(obs.position, hold)
        if self._over(obs, drop[:2]):
            self.phase = Phase.DESCEND_SLOT
            self.watch.descent_start = obs.time_s
            return self._release(obs, drop)
        return self._travel(obs.position, drop[:2])

    def _queue_point(self, obs: ConstructionObservation, column: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """``queue_at_slots``: where the agent waits (2,) m for its turn at the slot it serves from ``column``
        (2,) m, or None when it goes on: when it is in that slot's working square itself (an airframe's width
        and ``QUEUE_MARGIN`` per axis), or no other carrier is. It waits ``QUEUE_GAP`` outside every slot's
        square, so that no waiting carrier holds up another slot (ten carriers round a 3 x 3 slab pushed
        each other about over it for 150 s and none set its box down)."""
        if not self.params.queue_at_slots or len(obs.neighbour_ids) == 0:
            self.holders.clear()
            return None
        half = math.sqrt(2.0) * self.info.agent_radius + QUEUE_MARGIN
        if np.max(np.abs(obs.position[:2] - column)) < half:
            self.holders.clear()
            return None
        inside = np.max(np.abs(obs.neighbour_positions[:, :2] - column), axis=1) < half
        if len(obs.neighbour_carrying) == len(obs.neighbour_ids):
            inside &= obs.neighbour_carrying
        ids = obs.neighbour_ids[inside].tolist()
        # queue_patience_s: since when each carrier in the square has held it (the wait for one that leaves ends,
        # and so does every wait when the agent queues for another column or has not queued for a tick)
        same = (
            self.queue_at is not None and np.allclose(self.queue_at[:2], column) and obs.time_s - self.queue_at[2] < 0.5
        )
        self.queue_at = np.array([column[0], column[1], obs.time_s])
        self.holders = {int(j): self.holders.get(int(j), obs.time_s) if same else obs.time_s for j in ids}
        patience = self.params.queue_patience_s
        if patience is not None:
            ids = [j for j in ids if obs.time_s - self.holders[int(j)] < patience]
        if not ids:
            return None
        return self.geo.off_columns(obs.position[:2], half + QUEUE_GAP)

    def _step_reclimb_slot(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """RECLIMB_SLOT -> TO_SLOT (back at the flying altitude) | SEEK_GOAL."""
        if self._slot_lost(obs, claims=True):
            return None
        return self._reclimb(obs, Phase.TO_SLOT) or self._approach_slot(obs)

    def _step_descend_slot(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """DESCEND_SLOT -> RELEASING (settled at the drop point) | RECLIMB_SLOT (pushed off) | SEEK_GOAL."""
        if self._slot_lost(obs, claims=False) or self._descent_timed_out(obs):
            return None
        drop = self._drop_point()
        if self._drifted(obs.position, drop[:2]):
            self._break_off(obs, Phase.RECLIMB_SLOT)
            return self._reclimb(obs, Phase.TO_SLOT) or self._approach_slot(obs)
        return self._release(obs, drop)

    def _release(self, obs: ConstructionObservation, drop: NDArray[np.float64]) -> Command:
        """Down to the drop point (3,) m; RELEASE there once settled (-> RELEASING)."""
        if self._settled_at(obs, drop):
            self.phase = Phase.RELEASING
            return Command.goto(drop, Action.RELEASE)
        return Command.goto(drop)

    def _settled_at(self, obs: ConstructionObservation, drop: NDArray[np.float64]) -> bool:
        """True when the agent may let go at ``drop`` (3,) m: slower than ``RELEASE_SPEED`` and, averaged
        over the last ``dwell`` s (an estimate's jitter averages out, a drift does not), within
        ``release_tol`` per axis of it, while never more than twice that off during the dwell."""
        tol = self.params.release_tol
        w = self.watch
        err = np.abs(obs.position - drop)
        if np.linalg.norm(obs.velocity) >= RELEASE_SPEED or np.any(err > (2.0 * tol if self.dwell > 0 else tol)):
            w.clear()
            return False
        if w.since is None:
            w.since = obs.time_s
            w.window = []
        w.window.append((obs.time_s, obs.position.copy()))
        if obs.time_s - w.since < self.dwell - 1e-9:
            return False
        w.window = [(t, q) for t, q in w.window if t >= obs.time_s - self.dwell - 1e-9]
        mean = np.mean([q for _, q in w.window], axis=0)
        return bool(np.all(np.abs(mean - drop) <= tol))

    def _step_climb(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command | None:
        """CLIMB -> CHOOSE_BOX: straight up from the release to the flying altitude."""
        return self._rise(obs, Phase.CHOOSE_BOX)

    # ------------------------------------------------------------- straight up and down
    def _rise(self, obs: ConstructionObservation, then: Phase) -> Command | None:
        """Climb straight up over ``column`` to the flying altitude there; at it -> ``then``."""
        h = self.geo.altitude(self.column)
        if abs(obs.position[2] - h) <= ALTITUDE_TOL:
            self.phase = then
            return None
        return Command.goto([self.column[0], self.column[1], h])

    def _drifted(self, p: NDArray[np.float64], xy: NDArray[np.float64]) -> bool:
        """True when a descent at ``p`` (3,) m has been pushed more than ``DRIFT_TOL`` off its column ``xy`` (2,) m
        (never without ``drift_breakoff``: the descent goes on towards its point)."""
        return self.params.drift_breakoff and bool(np.hypot(*(p[:2] - xy)) > DRIFT_TOL)

    def _break_off(self, obs: ConstructionObservation, then: Phase) -> None:
        """Break off a descent pushed off its column (by a neighbour's avoidance, a gust, a snagged box):
        the agent climbs straight back from where it is (``then``: a RECLIMB phase) and comes over the
        object again (a diagonal way back would sweep its box through a neighbouring stack)."""
        self.watch.descent_start = math.inf
        self.watch.clear()
        self.column = obs.position[:2].copy()
        self.phase = then

    def _reclimb(self, obs: ConstructionObservation, then: Phase) -> Command | None:
        """RECLIMB_*: straight up over ``column`` to the flying altitude; once there -> ``then`` and None."""
        h = self.geo.altitude(self.column)
        if obs.position[2] >= h - ALTITUDE_TOL:
            self.phase = then
            return None
        return Command.goto([self.column[0], self.column[1], h])

    def _over(self, obs: ConstructionObservation, xy: NDArray[np.float64]) -> bool:
        """True when the agent hovers over ``xy`` (2,) m at its flying altitude, ready to descend."""
        p = obs.position
        return bool(
            np.hypot(*(p[:2] - xy)) <= COLUMN_TOL
            and abs(p[2] - self.geo.altitude(xy)) <= ALTITUDE_TOL
            and np.linalg.norm(obs.velocity) < SETTLED_SPEED
        )

    # ------------------------------------------------------------- flight
    def _travel(self, p: NDArray[np.float64], dest: NDArray[np.float64]) -> Command:
        """Fly towards the point ``dest`` (2,) m at the flying altitude of the way there, stopping short
        of a higher zone to climb straight up before entering it."""
        cmd, climbing = self._route(p, dest)
        if not climbing:
            self.climb_at = None
        return cmd

    def _route(self, p: NDArray[np.float64], dest: NDArray[np.float64]) -> tuple[Command, bool]:
        """The next command towards ``dest`` (2,) m, and whether it is a climb before a higher zone."""
        g = self.geo
        xy = p[:2]
        hits = [(t, z) for z in g.zones if (t := z.entry(xy, dest)) is not None]
        h_way = max([g.floor_altitude, *(z.altitude for _, z in hits)])  # m, altitude over the whole way
        higher = [(t, z) for t, z in hits if z.altitude > p[2] + ALTITUDE_TOL]
        if not higher:  # high enough (or only the open floor to climb over): fly there
            return Command.goto([dest[0], dest[1], h_way]), False
        t, zone = min(higher, key=lambda tz: tz[0])
        way = dest - xy
        entry = xy + t * way
        if self.climb_at is None and t > 0.0 and np.hypot(*(entry - xy)) > g.standoff + COLUMN_TOL:
            before = entry - g.standoff * way / np.linalg.norm(way)
            if np.hypot(*(before - xy)) > COLUMN_TOL:
                h_now = max([g.floor_altitude, *(z.altitude for _, z in hits if z.altitude <= p[2] + ALTITUDE_TOL)])
                return Command.goto([before[0], before[1], h_now]), False
        if self.climb_at is None:  # latch where to climb: chasing the measured position would drift
            self.climb_at = xy.copy()
        return Command.goto([self.climb_at[0], self.climb_at[1], zone.altitude]), True


class LayeredStigmergy(Stigmergy):
    """Layered stigmergy (thesis chapter 6): 3-D stigmergy plus a fading presence layer that agents avoid.

    Args:
        params: validated ``LayeredStigmergyParams`` (default: the defaults).
    """

    name: ClassVar[str] = "layered_stigmergy"
    Params: ClassVar[type[StigmergyParams]] = LayeredStigmergyParams
    params: LayeredStigmergyParams

    @classmethod
    def layer_specs(cls, p: StigmergyParams) -> list[LayerSpec]:
        """The task layer and the presence layer."""
        assert isinstance(p, LayeredStigmergyParams)
        return [*super().layer_specs(p), LayerSpec(Layer.PRESENCE.value, fatigue=p.presence_fatigue)]

    def plan(self, obs: ConstructionObservation, medium: PheromoneGrid | None) -> Command:
        """The 3-D stigmergy command, unless another agent's mark lies ahead; then mark own position."""
        cmd = super().plan(obs, medium)
        if medium is None:
            return cmd
        if self.phase in TRAVELLING and self._blocked(obs, cmd, medium):
            medium.tally("presence_replans")
            self._replan()
            if self.params.detour:
                # search elsewhere for as long as a mark lasts before going for a seen object again:
                # two agents wanting to pass each other would otherwise block each other for ever
                self.detour_until = obs.time_s + self.params.presence_pheromone / self.params.presence_fatigue
            cmd = Command.hold()
        medium.deposit(
            Layer.PRESENCE.value, obs.position, self.params.presence_pheromone, rule=DepositRule.SET, source=self.id
        )
        return cmd

    def _ignoring_objects(self, obs: ConstructionObservation) -> bool:
        """True during a detour after a presence re-plan (the agent keeps to its new search point)."""
        return obs.time_s < self.detour_until

    def _blocked(self, obs: ConstructionObservation, cmd: Command, medium: PheromoneGrid) -> bool:
        """True when another agent's presence mark lies in the area the agent is about to move into:
        the cells along the way to the command's target for ``lookahead`` from its centre."""
        if cmd.kind != CommandKind.POSITION:
            return False
        p = obs.position
        way = cmd.vector - p
        dist = float(np.linalg.norm(way))
        if dist < 1e-3:
            return False
        u = way / dist
        step = 0.5 * self.params.cell_size
        s = np.arange(step, min(self.params.lookahead, dist) + step - 1e-9, step)  # (k,) m along the way
        pts = p + np.outer(s, u)
        return bool(np.any(medium.values_at(Layer.PRESENCE.value, pts, exclude_source=self.id) > 0.0))

    def reset(self, agent_id: int, rng: np.random.Generator, info: ConstructionInfo) -> None:
        """Start a run as agent ``agent_id`` (see ``Stigmergy.reset``)."""
        super().reset(agent_id, rng, info)
        self.detour_until = -math.inf  # s, until then the agent keeps to its search point


from pybullet_swarm.planning.registry import register_planner  # noqa: E402

register_planner(
    "stigmergy",
    Stigmergy,
    "3-D stigmergy (thesis ch. 5): random / strongest-pheromone / local search, "
    "boxes +1, goals -1, trail 0.2 in a shared grid",
    ("construction",),
)
register_planner(
    "layered_stigmergy",
    LayeredStigmergy,
    "layered stigmergy (thesis ch. 6): 3-D stigmergy plus a "
    "fading presence layer; agents re-plan rather than enter another's marked cell",
    ("construction",),
)
