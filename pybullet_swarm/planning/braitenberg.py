"""Braitenberg obstacle avoidance on range sensors: a decentralised layer between planner and controller.

Each agent reads only its own range fan (``Observation.ranges``, see
``pybullet_swarm.sensing.range``). A reading ``r`` of a ray of length ``R`` becomes an activation
``a = clip(1 - r / R, 0, 1)`` (0: free, 1: touching), like the proximity values of an infrared
sensor. The course report's robot adds a weighted sum of its sensor values to its two wheel
speeds; a quadrotor is holonomic, so here the weighted sum acts on the velocity command, in
the frame of the agent's heading ``h`` (the horizontal direction of its planner's preferred
velocity; of its own velocity, or the last heading, when the planner wants to stand still).
For a ray at bearing ``phi`` from the heading (positive: to the left):

* lateral weight ``-sin(phi) (1 + cos(phi)) / 2``: an obstacle on the left pushes to the right
  and vice versa, strongest at 45-90 deg ahead and nothing from straight behind (the report's
  turning weights, continuous in phi so that any fan and any heading work);
* longitudinal weight ``-cos(phi)``: an obstacle ahead brakes, one behind pushes on.

The velocity becomes ``v_pref + v_h (w_lat * sum_k a_k lat_k - c) h_perp + v_h w_fwd * sum_k
a_k lon_k h`` with ``v_h`` the horizontal velocity limit and ``h_perp`` the left normal of the
heading; altitude is the planner's. Then, as in the report:

* Threshold with hysteresis. The layer only takes over when an activation among the rays
  within ``watch_deg`` of the heading exceeds ``on_threshold`` and hands back to the planner
  only when all of them are below ``off_threshold``; in between the agent keeps what it was
  doing, so it does not oscillate between avoiding and following its planner.
* Symmetry correction with memory. Straight at a wall (or a pillar on the axis) the left and
  right pushes cancel and the agent would only brake. When the strongest activation within
  ``front_deg`` is above ``symmetry_threshold`` while the lateral sum is below
  ``symmetry_ratio`` of it, the correction ``c`` grows by ``symmetry_step`` (in units of the
  limit, up to ``symmetry_max``) and pushes the agent to its right; otherwise ``c`` halves every
  tick, so it fades once the situation is asymmetric again. The memory keeps the agent from
  flickering between a corrected and an uncorrected command at a corner. Two agents meeting
  head-on both turn to their own right and pass each other.

Velocities are scaled down, direction kept, to the per-axis limits. An agent the layer does not
take over keeps its planner's command untouched.
"""
from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.base import Command, CommandKind
from pybullet_swarm.planning.orca import preferred_velocities

if TYPE_CHECKING:  # pragma: no cover
    from pybullet_swarm.experiment.simulation import Simulation


def lateral_weight(phi: NDArray[np.float64]) -> NDArray[np.float64]:
    """Lateral weight (...) of rays at bearings phi (...) rad from the heading (+: push to the left)."""
    return -np.sin(phi) * 0.5 * (1.0 + np.cos(phi))


def forward_weight(phi: NDArray[np.float64]) -> NDArray[np.float64]:
    """Longitudinal weight (...) of rays at bearings phi (...) rad (+: push forwards)."""
    return -np.cos(phi)


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@dataclasses.dataclass(frozen=True)
class BraitenbergParams:
    """Parameters of the braitenberg layer (scenario ``avoidance_params``).

    Attributes:
        weight_lateral: sideways push per unit of summed activation, in units of the horizontal
            velocity limit.
        weight_forward: braking (ahead) or pushing (behind) per unit of summed activation, same units.
        on_threshold: activation above which the layer takes over.
        off_threshold: the layer hands back when every watched activation is below this.
        watch_deg: deg, rays within this bearing of the heading are watched for the thresholds.
        front_deg: deg, the cone in which a symmetric obstacle is looked for.
        symmetry_threshold: front activation above which a symmetric reading is corrected.
        symmetry_ratio: a lateral sum below this fraction of the front activation is symmetric.
        symmetry_step: growth of the correction per planner tick, in units of the limit.
        symmetry_max: cap of the correction, in units of the limit.
        max_reverse: fastest backing away along the heading, in units of the limit: braking
            stops an agent but does not throw it back into the agents following it.
        arrive_time: s, a POSITION command's preferred velocity is (target - p) / arrive_time.
    """

    weight_lateral: float = 3.0
    weight_forward: float = 2.0
    on_threshold: float = 0.3
    off_threshold: float = 0.15
    watch_deg: float = 100.0
    front_deg: float = 50.0
    symmetry_threshold: float = 0.3
    symmetry_ratio: float = 0.25
    symmetry_step: float = 0.25
    symmetry_max: float = 1.0
    max_reverse: float = 0.3
    arrive_time: float = 0.5

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            if not ok or value < 0:
                raise ValueError(f"avoidance_params.{f.name} must be a number >= 0, got {value!r}")
        if self.arrive_time <= 0:
            raise ValueError(f"avoidance_params.arrive_time must be > 0, got {self.arrive_time!r}")
        if not 0.0 <= self.off_threshold <= self.on_threshold <= 1.0:
            raise ValueError(f"avoidance_params: need 0 <= off_threshold <= on_threshold <= 1, got "
                             f"{self.off_threshold!r} and {self.on_threshold!r}")
        if self.watch_deg > 180.0 or self.front_deg > 180.0:
            raise ValueError("avoidance_params.watch_deg and front_deg must be <= 180")

    @classmethod
    def from_mapping(cls, data: dict[str, Any]) -> BraitenbergParams:
        """Parameters from ``avoidance_params``; unknown names are refused with ValueError."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"avoidance_params.{unknown[0]}: unknown parameter of the braitenberg layer "
                             f"(known: {', '.join(sorted(known))})")
        return cls(**data)


class Braitenberg:
    """The avoidance rule for n agents, on plain arrays (one state per agent: heading, mode, correction).

    Args:
        params: weights and thresholds.
        angles: (r,) rad, ray bearings in the levelled body frame.
        range_m: m, length of a ray.
        v_max: (3,) m/s per-axis limit (None: 1 m/s is the unit of the weights).
        n: number of agents.
    """

    def __init__(self, params: BraitenbergParams, angles: NDArray[np.float64], range_m: float,
                 v_max: NDArray[np.float64] | None, n: int) -> None:
        self.params = params
        self.angles = np.asarray(angles, dtype=float).reshape(-1)
        self.range_m = float(range_m)
        self.v_max = None if v_max is None else np.asarray(v_max, dtype=float).reshape(3)
        self.v_h = 1.0 if self.v_max is None else float(min(self.v_max[0], self.v_max[1]))
        self.n = int(n)
        self.heading = np.zeros(self.n)               # rad, last heading of each agent
        self.active = np.zeros(self.n, dtype=bool)    # taking over from the planner
        self.correction = np.zeros(self.n)            # units of the limit, push to the right

    def step(self, ranges: NDArray[np.float64], yaws: NDArray[np.float64], velocities: NDArray[np.float64],
             preferred: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """One planner tick for every agent.

        Args:
            ranges: (n, r) m, each agent's own readings.
            yaws: (n,) rad.
            velocities: (n, 3) m/s, each agent's own velocity.
            preferred: (n, 3) m/s, the velocity each agent's planner asks for.

        Returns:
            velocities (n, 3) m/s to command where the layer takes over, and that mask (n,).
        """
        p = self.params
        pref = np.asarray(preferred, dtype=float)
        a = np.clip(1.0 - np.asarray(ranges, dtype=float) / self.range_m, 0.0, 1.0)        # (n, r)
        sp = np.hypot(pref[:, 0], pref[:, 1])
        vel = np.asarray(velocities, dtype=float)
        sv = np.hypot(vel[:, 0], vel[:, 1])
        self.heading = np.where(sp > 1e-3, np.arctan2(pref[:, 1], pref[:, 0]),
                                np.where(sv > 0.05, np.arctan2(vel[:, 1], vel[:, 0]), self.heading))
        phi = _wrap(np.asarray(yaws, dtype=float)[:, None] + self.angles[None, :] - self.heading[:, None])
        lat = np.sum(a * lateral_weight(phi), axis=1)                                       # (n,)
        lon = np.sum(a * forward_weight(phi), axis=1)
        watched = np.where(np.abs(phi) <= math.radians(p.watch_deg), a, 0.0).max(axis=1, initial=0.0)
        self.active = np.where(watched > p.on_threshold, True, np.where(watched < p.off_threshold, False, self.active))
        front = np.where(np.abs(phi) <= math.radians(p.front_deg), a, 0.0).max(axis=1, initial=0.0)
        symmetric = (front > p.symmetry_threshold) & (np.abs(lat) < p.symmetry_ratio * front)
        self.correction = np.where(symmetric, np.minimum(self.correction + p.symmetry_step, p.symmetry_max),
                                   0.5 * self.correction)
        h = np.column_stack([np.cos(self.heading), np.sin(self.heading), np.zeros(self.n)])
        left = np.column_stack([-np.sin(self.heading), np.cos(self.heading), np.zeros(self.n)])
        side = self.v_h * (p.weight_lateral * lat - self.correction)
        along = np.sum(pref * h, axis=1)
        floor = np.minimum(0.0, -p.max_reverse * self.v_h - along)   # braking may not throw it backwards
        ahead = np.maximum(self.v_h * p.weight_forward * lon, floor)
        out = pref + ahead[:, None] * h + side[:, None] * left
        if self.v_max is not None:
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(np.abs(out) > self.v_max, self.v_max / np.abs(out), 1.0).min(axis=1)
            out *= ratio[:, None]
        return out, self.active.copy()


class BraitenbergLayer:
    """The ``--avoidance braitenberg`` layer: each agent avoids what its own range sensors see.

    Turns the range sensors on (``sensing.range`` of the scenario: 8 horizontal rays of 0.5 m by
    default). Every planner tick it reads each agent's own observation (range readings,
    velocity, yaw) and replaces the command of each agent it takes over by a VELOCITY command
    with the same yaw and action.

    Args:
        sim: the simulation.
        **params: ``BraitenbergParams`` fields (scenario ``avoidance_params``).
    """

    def __init__(self, sim: Simulation, **params: Any) -> None:
        self.params = BraitenbergParams.from_mapping(params)
        sim.enable_range_sensors()
        fan = sim.range_sensor.fan
        self.v_max = sim.scenario.velocity_limits()
        self.rule = Braitenberg(self.params, fan.angles, fan.range_m, self.v_max, sim.n)
        self.n = sim.n
        self._ticks = 0
        self._active_ticks = 0
        self._switches = 0

    def filter(self, commands: list[Command], sim: Simulation) -> list[Command]:
        """Commands for this planner tick (``action`` and ``yaw`` of each command are kept)."""
        obs = sim.observations()   # each agent's own readings and state
        n = self.n
        pos = np.array([o.position for o in obs], dtype=float).reshape(n, 3)
        vel = np.array([o.velocity for o in obs], dtype=float).reshape(n, 3)
        yaws = np.array([o.yaw for o in obs], dtype=float)
        ranges = np.array([o.ranges for o in obs], dtype=float).reshape(n, -1)
        kinds = np.fromiter((int(c.kind) for c in commands), dtype=np.int64, count=n)
        vectors = np.array([c.vector for c in commands], dtype=float).reshape(n, 3)
        pref = preferred_velocities(kinds, vectors, pos, arrive_time=self.params.arrive_time, v_max=None)
        if self.v_max is not None:   # scaled, not clipped per axis: the heading is where the planner points
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(np.abs(pref) > self.v_max, self.v_max / np.abs(pref), 1.0).min(axis=1)
            pref *= ratio[:, None]
        before = self.rule.active.copy()
        v, active = self.rule.step(ranges, yaws, vel, pref)
        self._ticks += 1
        self._active_ticks += int(np.count_nonzero(active))
        self._switches += int(np.count_nonzero(active != before))
        return [Command(CommandKind.VELOCITY, v[i].copy(), c.yaw, c.action) if active[i] else c
                for i, c in enumerate(commands)]

    def metrics(self) -> dict[str, Any]:
        """Counters of the run (merged into metrics.json)."""
        return {
            "braitenberg_active_fraction": self._active_ticks / max(self._ticks * self.n, 1),
            "braitenberg_switches": self._switches,
        }


from pybullet_swarm.planning.registry import register_avoidance  # noqa: E402

register_avoidance("braitenberg", BraitenbergLayer, "Braitenberg avoidance on each agent's own range sensors "
                   "(weighted readings onto the velocity, threshold with hysteresis, symmetry correction)")
