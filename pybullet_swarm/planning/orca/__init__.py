"""Optimal reciprocal collision avoidance (ORCA) in 3-D: a safety layer between any planner and the controller.

``core`` is the paper, van den Berg, Guy, Lin and Manocha, "Reciprocal n-body collision avoidance"
(ISRR 2009), with the solver of its RVO2-3D library. For every sensed neighbour it builds the velocity
obstacle truncated at the time horizon, u (the smallest change of the relative velocity that leaves
it) and the ORCA half-space in which the agent takes half of u. The new velocity is the one closest to
the preferred velocity inside every half-space, the velocity limits and the speed sphere (incremental
3-D LP); when no velocity satisfies them all, it is the one whose largest violation is smallest (the
4-D fallback LP). Static obstacles are the paper's too: the agent takes the whole u. Agents are
spheres (the paper) or attitude-aware bounding boxes of airframe and hanging payload (``shape: box``,
the default: the exact VO of two boxes; boxes placed side by side at a 20 cm pitch are cleared by
15 cm airframes with 5 cm to spare, which no sphere around a 15 cm square allows).

Our extensions are ``Rule``s, each with a one-line description and a switch of its name in
``OrcaParams`` (on by default; ``avoidance_params: {preset: paper}`` switches every one off). A rule
that only patches another (``rules.REQUIRES``) is refused on while that one is off. They act in the
stages of one planner tick, each a compiled function of ``kernel`` reading its own parameters:

1. Inflation (``kernel.pair_u``): shapes grow by the safety margin; ``lag_margin``, by
   ``lag_margin_s`` x the pair's closing speed (the cascade follows a new velocity about 0.3 s late),
   with ``headway`` by either agent's own speed towards the other; ``uncertainty_margin``, flying on
   estimates, by ``uncertainty_sigmas`` standard deviations of a pair's relative position error;
   ``wake_column``, against other agents, downwards by the depth of the rotor wake the airframe's wake
   model gives at run time (``wake_fraction`` of the weight, docs/science/wake.md: 5.47 m for quad150
   with a 10 g box).
2. Reference (``rules.reference_velocities``): ``clipped_reference`` linearises about the sensed
   velocity clipped to the limits.
3. Responsibility (``kernel.agent_planes``): a pair apart vertically but for the wake is
   resolved by the agent moving into the conflict (``wake_share_by_approach``), on a collision course
   only (``wake_share_on_course``); ``pinned_share`` gives the whole way out to the agent free to
   move against a neighbour its bounds pin.
4. Bounds (``rules.velocity_bounds``, six hard half-spaces first, never traded away): ``column_rule``,
   below ``floor_height`` on a vertical leg within ``column_radius`` of its target an agent is only
   slowed or lifted where a box, the structure or an obstacle lies within ``column_reach`` beside it,
   or the ground under it.
5. Obstacles (``kernel.obstacle_planes``, the paper's, no switch): boxes, the structure and the arena's
   walls and pillars, as data (``planning.base.Obstacles``), each a VO the agent avoids alone, with
   ``obstacle_horizon``; an obstacle the agent's shape at its own POSITION/HOLD target touches (the
   box it grasps, the slot it fills) is left out (``goal_reach``; ``rules.own_target``), a test of
   command and shapes only, so it serves any task. The ground (z = 0) is one more such obstacle:
   nothing pushes an agent into it, nor does it fly into it within the horizon, unless its target
   rests on it.
6. LP and fallback (``core.solve``): ``gap_weighted_fallback`` weighs each plane's violation by 1 /
   its pair's gap a lag later; ``margin_overlap`` recovers overlapping boxes along the axes on which
   the bare shapes are still apart.
7. Deadlock resolution (``kernel.resolve_stall``, ``deadlock_resolution``): an agent whose LP velocity
   makes progress below ``stuck_fraction`` of its preferred speed finds what holds it up (the nearest
   neighbour ahead in its way, or an obstacle; one sitting on its goal is waited for) and solves again
   with ``right_bias`` of its preferred speed added towards the side the other leaves free; still
   held, or pushed backwards, it asks for the sideways step alone.
8. Pass-through (``kernel.orca_batch`` and ``rules.clear_paths``): ``minimal_intervention`` keeps a
   command that violates no half-space; ``passthrough`` passes a POSITION/HOLD command within
   ``capture_radius`` unchanged when the swept box stays clear (grasp and release need millimetres),
   ``passthrough_turns`` asking a waypoint's neighbours for the room they may turn into.

Which rules pay was measured on the construction benchmark's holdout split, stage by stage and then
rule by rule within the stages that paid (``scripts/orca_stage_ablation.py``, docs/results/orca-ablation.md),
then the rest in groups (``scripts/switch_ablation.py``, docs/results/switch-ablation.md); the rules that
did not pay were deleted.

Shared design decisions: each pair's (n, u) is computed once in index order and negated for the
other agent, so both halves match to the last bit, from sensed state only (no agent reads another's
command). The preferred velocity of a POSITION command is ``(target - p) / arrive_time`` per axis,
clipped to the limit; a VELOCITY command's is itself; HOLD's is zero. A changed command becomes a
VELOCITY command with the same action. A relative velocity exactly on the line of centres is taken
to the right (``d x z``), antisymmetric, so both keep right.

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
