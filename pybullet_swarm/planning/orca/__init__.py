"""Optimal reciprocal collision avoidance (ORCA) in 3-D: a safety layer between any planner and the controller.

The paper's core and our extension rules are kept apart:

* ``core``: the paper, van den Berg, Guy, Lin and Manocha, "Reciprocal n-body collision
  avoidance" (ISRR 2009), with the solver of its RVO2-3D library: for every sensed neighbour the
  velocity obstacle truncated at the time horizon, u (the smallest change of the relative
  velocity that leaves it) and the ORCA half-space in which the agent takes half of u; the new
  velocity is the one closest to the preferred velocity inside every half-space, the velocity
  limits and the speed sphere (incremental 3-D LP), or, when no velocity satisfies them all, the
  one whose largest violation is smallest (the 4-D fallback LP). Agents are spheres (the paper)
  or attitude-aware bounding boxes of airframe and hanging load (``shape: box``, the default: the
  exact VO of two boxes; the construction task places boxes side by side at a 20 cm pitch,
  which 15 cm airframes clear by 5 cm but no sphere around a 15 cm square allows).
* ``rules``: each extension is a ``Rule`` with a one-line description and a switch of the same
  name in ``OrcaParams`` (on by default; ``avoidance_params: {preset: paper}`` switches all off):

  - ``lag_margin``: shapes grow by ``lag_margin_s`` x closing speed (the cascade follows a new
    velocity about 0.3 s late and overshoots it by up to 100 %);
  - ``uncertainty_margin``: flying on estimates, shapes grow by ``uncertainty_sigmas`` standard
    deviations of a pair's relative position error;
  - ``clipped_reference``: ORCA linearises about the sensed velocity clipped to the limits;
  - ``weighted_way_out``: a box VO's way out counts vertical changes ``vertical_cost`` times
    horizontal ones (0.75 favours passing over: a 2 cm thin airframe clears a neighbour a few cm
    above it, where a sideways dodge needs two airframe widths);
  - ``climb_over``: the upper agent of a pair takes the whole of a vertical way out when the lower
    one flies level: an empty agent hops over a carrier and its box;
  - ``floor_rule``: below ``floor_height`` avoidance never pushes an agent down faster than it means
    to go (``floor_preferred``: no faster than its preferred approach to its own target either);
  - ``column_rule``: low on a vertical leg (within ``column_radius`` of its target) an agent is
    only slowed or lifted: a sideways dodge there tilts it into the box under it (with
    ``static_obstacles``, only where a box, the structure or an obstacle lies within ``column_reach``
    of its airframe or load: a leg in the open, such as a climb at the structure's edge, dodges;
    ``column_tick``: no faster sideways than reaches the target's column in one planner tick);
  - ``minimal_intervention``: a command that violates no half-space is kept unchanged;
  - ``passthrough``: within ``capture_radius`` of a POSITION/HOLD target the command passes
    unchanged when the swept box is clear (grasp and release need millimetres);
  - ``sidestep``: a stalled agent adds ``right_bias`` of its preferred speed sideways (right, or
    the side a neighbour already off to one side leaves free): crowds become roundabouts;
  - ``climb_past``: a stalled agent above the one in its way climbs past it instead;
  - ``make_way``: an agent descending onto its goal's occupant rises straight up, the only way the
    one below can leave.
  - ``static_obstacles``: boxes (free and placed), the structure and the arena's walls and obstacles
    are velocity obstacles the agent avoids alone, the paper's obstacles (see below).
  - ``wake_column``: against other agents each agent's box reaches ``wake_depth`` further down
    (null: where the run models downwash, computed at run time from the airframe's wake model, as
    deep as a laden agent's wake pushes a vehicle straight below with more than ``wake_fraction``,
    5 %, of its weight: 5.47 m for quad150 with a 10 g box, 4.05 m for cf2x unladen; 0 without;
    docs/science/wake.md): nobody flies in another's rotor wake; a pair apart
    vertically but for the wake is the upper agent's to resolve.
  - ``wake_share_by_approach``: such a pair's share goes to whichever agent moves into the
    conflict, in proportion to their speeds towards each other; the upper one takes it all only
    when neither does (the upper one fleeing a lower agent closing in was pushed into a third).
  - ``wake_share_on_course``: those unequal shares apply on a collision course only; off it (the
    relative velocity outside the VO, u the freedom left) each agent keeps half: the lower one,
    left none, was frozen along the pair's normal.
  - ``headway``: with ``lag_margin``, shapes grow by ``lag_margin_s`` x the faster speed at which
    either agent of a pair flies towards the other, not only their closing speed: ORCA takes a
    neighbour's velocity as constant, but the one ahead stops for its target without warning,
    and a follower at its speed then closes in at full speed, a lag late. A pair flying the same
    way, one behind the other, grows by (``headway_s`` - ``lag_margin_s``) x the speed they share
    besides (``headway_s``; null, the default: ``lag_margin_s``, no more): a line of followers
    damps a stop down the line (string stability) only with a time headway above twice that lag
    (0.8 s; measured in the results history of the docs, not the default).
  - ``margin_overlap``: boxes that overlap within their margins and growths open the gap along
    the least overlap of the axes on which the bare shapes are still apart (when there are
    any): the recovery leaves the other axes free, and only those axes keep the pair apart.
  - ``impatience``: an agent that has waited ``wait_patience_s`` (10 s) for a neighbour sitting on
    its goal treats it as in its way (``sidestep``, ``climb_past``): the neighbour is not leaving,
    perhaps because the agent sits on its own goal; without it, two agents each on the other's
    goal (a swap: each goal in the other's wake column) wait for each other until the run stalls.
    The wait goes on counting while the agent breaks free of it for less than ``wait_memory_s``
    (2 s): two carriers head-on in a row of slots, each over the other's, stepped aside for half a
    second once impatient, were free of each other for a tick, fell back into line and waited
    their 10 s again, for 150 s.
  - ``climb_when_shorter``: ``climb_past`` climbs only when rising clear of the neighbour's box
    (the wake column included) is shorter than the step aside, weighted by ``vertical_cost``: with
    a 0.5 m wake column a climb past takes the agent out of the arena's working height, and the
    planner pulls it back down.
  - ``side_memory``: a stalled agent keeps the side it took round a neighbour while that neighbour
    holds it up: head-on, a few centimetres apart across the way, their offset flipped sign as
    both moved, and with it ``sidestep``'s choice of side, tick after tick, while the neighbour,
    not stalled, pushed the agent backwards 1 m (a carrier with the last box, among empty agents
    searching the empty depot).
  - ``pushed_back``: a stalled agent that its biased velocity takes backwards and hardly sideways
    asks for the sideways step alone: ORCA linearises about the present velocities, so an agent
    flying at one that is pushed back at its speed keeps its speed, and the pushed one keeps
    retreating, its bias cancelled by its preferred velocity back towards its line.
  - ``passthrough_turns``: passing through to a waypoint (a target touching neither the ground, a
    box nor the structure: ``rules.targets_touching``), the clearance test grows each neighbour's
    swept box by what its acceleration limit allows over ``clearance_lookahead`` (1/2 a_max t^2):
    swept along its velocity, a neighbour that then turned towards a carrier passed through to its
    waypoint seemed clear. Grasp and drop points keep the plain test (they need millimetres).
  - ``pinned_share``: against a neighbour whose velocity bounds forbid it any velocity away along
    the horizontal axis on which the pair's way out mostly runs (``column_rule``: on a leg over a
    box or the structure, it may only slow down), an agent free to move its way takes the whole way
    out: the neighbour cannot take its half. A carrier lifting off beside an empty agent held over a depot box took
    half and touched it.
  - ``ground_beside``: the column rule's premise (``column_reach``: a box, the structure or an obstacle
    beside the agent) counts the ground as well. A carrier held at its grasp height by a neighbour in
    its wake column, its box still resting on the ground, was stepped sideways: the box dragged, the
    position integrators wound up and the agent flipped when the box came free.
  - ``gap_weighted_fallback``: where an agent's planes have no common velocity, the fallback minimises
    the largest violation weighted by 1 / the gap the pair's bare shapes will have ``lag_margin_s``
    later at their closing speed (``gap_floor`` at least), not the paper's plain largest violation:
    it maximises the shortest time in which an extra closing speed eats up a pair's gap. An agent in
    a line leaving the start grid, squeezed between its planes ahead and behind, otherwise shared
    the violation with a neighbour 3 cm beside it and touched it; weighed by the present gap, an
    agent squeezed in a row fled the nearer neighbour into the other, back and forth.
  - ``free_side``: ``sidestep`` takes the side a neighbour in the way leaves free at any bearing,
    not only within 30 deg of straight ahead (beyond, it went right, even where the neighbour was):
    two agents held up by each other at about 45 deg over a depot column each stepped towards the
    other, and with a third beside them the three held each other in a row for 23 s.

* ``kernel``: one compiled (numba) call per planner tick for all agents, composing the two;
  ``params``: ``OrcaParams``; ``layer``: ``OrcaLayer``, the ``--avoidance orca`` layer.

Design decisions the rules share (numbers are ``OrcaParams`` defaults):

* Hard bounds. The per-axis velocity limits are six half-spaces that come first and are never
  traded away by the least-violation fallback (as RVO2 treats obstacle lines); the speed sphere
  (radius |v_max|) only bounds the problem, so the reference shaper, which clips each axis,
  receives exactly the velocity the LP certified. ``floor_rule`` and ``column_rule`` narrow
  these bounds.
* Reference velocity: the sensed velocity of every agent. Each pair's (n, u) is computed once in
  index order and negated for the other agent, so both halves match to the last bit, from sensed
  state only: no agent reads another's command.
* Preferred velocity: ``(target - p) / arrive_time`` per axis, clipped to the limit, for a
  POSITION command (a smooth approach that slows down on arrival), the command itself for
  VELOCITY, zero for HOLD. A changed command becomes a VELOCITY command with the same action.
* Head-on. A relative velocity exactly on the line of centres has no defined nearest side of a
  sphere VO; the core takes it to the right (``d x z``, or ``d x x`` for a vertical line),
  antisymmetric, so both keep right.
* Stalls (``sidestep``, ``climb_past``, ``make_way``): an agent whose LP velocity makes progress
  below ``stuck_fraction`` of its preferred speed is stalled; the nearest neighbour ahead in its
  way that does not sit on its goal decides the bias. When the biased velocity is still held (the
  bias can exactly cancel the preferred velocity along the one axis a box VO leaves free) the
  agent asks for the sideways step alone. A neighbour sitting on the goal is waited for.
* Static obstacles (``static_obstacles``, ``obstacle_horizon`` 1 s, ``goal_reach`` 2 cm). They reach
  the layer as data, axis-aligned boxes (``planning.base.Obstacles``): the arena's walls and
  obstacles once in ``AvoidanceSetup.obstacles`` (a pillar as the box around it: its corners
  stick out by (sqrt(2) - 1) r, the price of the box VO, which is exact, against a rounded
  Minkowski sum the core does not have), the task's at every tick in ``TaskView.obstacles`` (the
  construction task's free and placed boxes; a carried box is its carrier's shape). As the paper
  treats obstacles, the agent takes the whole u (not half: the obstacle does not move), with the
  obstacle's own time horizon and the agent's margin only; the planes are hard, after the
  velocity bounds, and never traded away (those of obstacles the agent already overlaps are soft:
  recovery may contradict the bounds). The target's own obstacles are left out: an obstacle that
  the airframe or the load at the agent's POSITION/HOLD target comes within the margin plus
  ``goal_reach`` of (the box under a grasp point, a slot's support and neighbours beside the
  load at a drop point, the box just let go) must be approached closer than the margin, so its
  VO would forbid the grasp or the placing; unless one of them would reach into it by more than
  5 mm (``rules.GOAL_OVERLAP``): such a target lies inside the obstacle (an airframe in a taller
  neighbour of its slot) and the agent is held off it. The test needs nothing but the command and
  the shapes, so it serves any task. A stall in front
  of an obstacle takes ``sidestep``'s bias (away from its centre across the way, or over it when
  climbing is shorter, weighted by ``vertical_cost``); ``passthrough`` also needs the obstacles
  but the target's own clear.
* Measured (``construction.yaml``, stigmergy, seeds 0..49): median completion 128.6 s with
  ``vertical_cost`` 3.0 and no climbing over, 117.7 s with both, no contact either way. The
  simulator models no downwash; a study of airframes that suffer from it raises ``vertical_cost``
  (or ``safety_margin``). ``scripts/orca_ablation.py`` switches the rules off one at a time.

Public pieces: ``orca_plane`` (one half-space), ``solve_velocity`` (one LP), ``orca_velocities``
(all agents, plain arrays), ``OrcaLayer`` (the ``--avoidance orca`` layer), ``OrcaParams``, ``Rule``.
"""

from __future__ import annotations

from pybullet_swarm.planning.orca.core import orca_plane, solve_velocity
from pybullet_swarm.planning.orca.kernel import (
    FLAG_BIASED,
    FLAG_FREE,
    FLAG_INFEASIBLE,
    FLAG_OBSTACLE,
    bounding_boxes,
    commanded_velocities,
    neighbour_table,
    orca_velocities,
    preferred_velocities,
    shape_parts,
)
from pybullet_swarm.planning.orca.layer import OrcaLayer
from pybullet_swarm.planning.orca.params import OrcaParams, Shape
from pybullet_swarm.planning.orca.rules import RULE_DOCS, Rule, velocity_bounds
from pybullet_swarm.planning.registry import register_avoidance

register_avoidance(
    "orca",
    OrcaLayer,
    "optimal reciprocal collision avoidance in 3-D on every planner's commands "
    "(sensed neighbours, attitude-aware boxes or spheres, velocity limits, exact positioning at "
    "targets; each extension of the paper a rule with its own switch)",
)

__all__ = [
    "FLAG_BIASED",
    "FLAG_FREE",
    "FLAG_INFEASIBLE",
    "FLAG_OBSTACLE",
    "RULE_DOCS",
    "OrcaLayer",
    "OrcaParams",
    "Rule",
    "Shape",
    "bounding_boxes",
    "commanded_velocities",
    "neighbour_table",
    "orca_plane",
    "orca_velocities",
    "preferred_velocities",
    "shape_parts",
    "solve_velocity",
    "velocity_bounds",
]
