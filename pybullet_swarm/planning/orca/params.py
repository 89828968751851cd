"""Parameters of the ORCA layer (scenario ``avoidance_params``): the core's, then each rule's switch and its own.

Every extension rule of ``rules.py`` has one bool field of its name (``lag_margin: false``), on by
default, with its one-line description; the parameters a rule uses follow its switch and act
only while it is on. ``preset: paper`` switches every rule off (the paper's ORCA); a rule given
explicitly beside the preset keeps its value (``{preset: paper, column_rule: true}``).
"""

from __future__ import annotations

import enum
from typing import Any, ClassVar

import pydantic
from pydantic import Field

from pybullet_swarm.planning.orca.rules import REQUIRES, Rule
from pybullet_swarm.planning.params import ParamRuleError, Params, Preset


class Shape(enum.Enum):
    """How agents are modelled for avoidance."""

    BOX = "box"  # attitude-aware bounding boxes of airframe and load (exact VO of boxes)
    SPHERE = "sphere"  # enclosing spheres (the classic ORCA model)


#: m, safety margin of each shape when ``safety_margin`` is null: two airframes side by side at the
#: construction task's 20 cm pitch keep 2 cm of slack with boxes
DEFAULT_MARGIN: dict[Shape, float] = {Shape.BOX: 0.015, Shape.SPHERE: 0.03}


def _switch(rule: Rule) -> Any:
    """The bool field of a rule: on by default, described by the rule's line."""
    return Field(True, description=rule.doc)


class OrcaParams(Params):
    """Parameters of the ORCA layer (scenario field ``avoidance_params``); see the package notes."""

    preset: Preset | None = Field(
        None, strict=False, description="paper: every rule off, the paper's ORCA alone (explicit values still win)"
    )
    # ------------------------------------------------------------------ the paper's core
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
    max_neighbours: int = Field(10, ge=1, le=100, description="the nearest this many sensed neighbours give planes")
    recovery_time: float = Field(0.5, gt=0.0, le=60.0, description="s, shapes that already overlap separate over this")
    responsibility: float = Field(
        0.5, gt=0.0, le=1.0, description="share of each pair's avoidance an agent takes (0.5: reciprocal)"
    )
    arrive_time: float = Field(
        0.5, gt=0.0, le=60.0, description="s, POSITION targets are approached at distance / arrive_time per axis"
    )
    max_speed: float | None = Field(
        None,
        gt=0.0,
        le=100.0,
        description="m/s, radius of the speed sphere (null: the corner of the velocity-"
        "limit box, or 1 m/s without limits)",
    )
    # ------------------------------------------------------------------ the rules
    lag_margin: bool = _switch(Rule.LAG_MARGIN)
    lag_margin_s: float = Field(
        0.4, ge=0.0, le=10.0, description="s, a pair's shapes also grow by this times their closing speed"
    )
    headway_s: float | None = Field(
        None,
        ge=0.0,
        le=10.0,
        description="s, with headway: a pair flying the same way, one behind the other, keeps this time headway "
        "(its shapes grow by headway_s - lag_margin_s times the speed the two share; null: lag_margin_s). 0.8 s, "
        "twice the lag, keeps a line of followers string-stable; measured, not the default (docs/results/history)",
    )
    uncertainty_margin: bool = _switch(Rule.UNCERTAINTY_MARGIN)
    uncertainty_sigmas: float = Field(
        2.0,
        ge=0.0,
        le=10.0,
        description="flying on estimates, shapes grow by this many standard deviations "
        "of a pair's relative position error",
    )
    clipped_reference: bool = _switch(Rule.CLIPPED_REFERENCE)
    floor_height: float = Field(0.5, ge=0.0, le=100.0, description="m, the column rule holds agents below this")
    column_rule: bool = _switch(Rule.COLUMN_RULE)
    column_radius: float = Field(
        0.03,
        ge=0.0,
        le=10.0,
        description="m, below floor_height an agent this close to its target (horizontally) "
        "is never moved sideways (0: off)",
    )
    column_reach: float | None = Field(
        0.05,
        ge=0.0,
        le=10.0,
        description="m, the column rule holds an agent only with a box, the structure or an obstacle this close to "
        "its airframe or load horizontally and not wholly above it, or the ground this close under it "
        "(null: wherever it is)",
    )
    column_tick: bool = Field(
        True,
        description="with column_rule, the sideways speed let through is at most what reaches the target's column "
        "in one planner tick (the layer's velocity is held that long) [false: the shaped command's speed, meant "
        "for one shaper tick]",
    )
    minimal_intervention: bool = _switch(Rule.MINIMAL_INTERVENTION)
    passthrough: bool = _switch(Rule.PASSTHROUGH)
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
    deadlock_resolution: bool = _switch(Rule.DEADLOCK_RESOLUTION)
    right_bias: float = Field(
        0.5, ge=0.0, le=10.0, description="fraction of the preferred speed added sideways to a stalled agent (0: off)"
    )
    stuck_fraction: float = Field(
        0.25,
        ge=0.0,
        lt=1.0,
        description="progress below this fraction of the preferred speed counts as stalled (deadlock_resolution)",
    )
    obstacle_horizon: float = Field(
        1.0, gt=0.0, le=60.0, description="s, collisions with static obstacles predicted later than this are ignored"
    )
    goal_reach: float = Field(
        0.02,
        ge=0.0,
        le=1.0,
        description="m, an obstacle within the safety margin plus this of the airframe or load at the agent's own "
        "target (the box it grasps, the structure it places on) is not avoided, unless the target lies inside it",
    )

    wake_column: bool = _switch(Rule.WAKE_COLUMN)
    wake_depth: float | None = Field(
        None,
        ge=0.0,
        le=10.0,
        description="m, boxes: against other agents each agent's box reaches this far further down, its rotor wake "
        "kept clear of others (null: where the run models downwash, computed at run time from the airframe's wake "
        "model: the depth down to which a laden agent's wake pushes an agent straight under it with more than "
        "wake_fraction of its weight; 0 without; spheres: no effect)",
    )
    wake_fraction: float = Field(
        0.05,
        gt=0.0,
        lt=1.0,
        description="with wake_depth null: the wake column reaches as deep as the wake model's force on a vehicle "
        "straight below exceeds this fraction of its weight (computed at run time for the run's vehicle and load)",
    )

    wake_share_by_approach: bool = _switch(Rule.WAKE_SHARE_BY_APPROACH)
    headway: bool = _switch(Rule.HEADWAY)
    wake_share_on_course: bool = _switch(Rule.WAKE_SHARE_ON_COURSE)
    margin_overlap: bool = _switch(Rule.MARGIN_OVERLAP)
    passthrough_turns: bool = _switch(Rule.PASSTHROUGH_TURNS)
    pinned_share: bool = _switch(Rule.PINNED_SHARE)
    gap_weighted_fallback: bool = _switch(Rule.GAP_WEIGHTED_FALLBACK)
    gap_floor: float = Field(
        0.01,
        gt=0.0,
        le=1.0,
        description="m, with gap_weighted_fallback: pairs whose bare shapes are nearer than this (or overlap) "
        "weigh alike, as if this far apart",
    )

    PRESETS: ClassVar[dict[Preset, dict[str, Any]]] = {Preset.PAPER: {rule.value: False for rule in Rule}}

    @pydantic.model_validator(mode="after")
    def _patched_rules_on(self) -> OrcaParams:
        """A rule that patches another (``rules.REQUIRES``) is refused on while that one is off."""
        for rule, base in REQUIRES.items():
            if self.on(rule) and not self.on(base):
                raise ParamRuleError(
                    rule.value,
                    f"patches {base.value}, which is off: switch {rule.value} off too, or {base.value} on",
                )
        return self

    @property
    def margin(self) -> float:
        """m, the safety margin in use."""
        if self.safety_margin is not None:
            return float(self.safety_margin)
        return DEFAULT_MARGIN[self.shape]

    def wake(self, downwash: bool, model_depth: float | None = None) -> float:
        """m, the wake column's depth in use: ``wake_depth``, or when null, with downwash, ``model_depth`` (the
        depth the airframe's wake model gives at ``wake_fraction``, computed at run time); 0 without downwash,
        when the rule is off or agents are spheres.

        Raises:
            ValueError: the run models downwash, ``wake_depth`` is null and no model depth is given.
        """
        if not self.wake_column or self.shape is not Shape.BOX:
            return 0.0
        if self.wake_depth is not None:
            return float(self.wake_depth)
        if not downwash:
            return 0.0
        if model_depth is None:
            raise ValueError("wake_depth is null and the run models downwash: the layer needs the wake model's depth")
        return float(model_depth)

    def on(self, rule: Rule) -> bool:
        """True when ``rule`` is switched on."""
        return bool(getattr(self, rule.value))

    @property
    def rules(self) -> tuple[Rule, ...]:
        """The rules switched on, in ``Rule`` order."""
        return tuple(r for r in Rule if self.on(r))
