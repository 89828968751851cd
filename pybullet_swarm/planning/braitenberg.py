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

What a reading weighs. The rule does not use a raw reading ``r`` but the free distance that is
left once the agent has braked: ``s = r - (c t_r + c^2 / (2 a_max))`` with ``c`` the speed at
which the agent closes on the echo, ``t_r`` the ``reaction_time`` and ``a_max`` the horizontal
acceleration limit, so that an agent flying fast at an obstacle takes over earlier and brakes
harder than one drifting past it (activation ``clip(1 - s / R, 0, 1)``). With the agent's own
position (``Observation.position``) and its neighbours' (``Observation.neighbour_positions``)
the rule also

* remembers where obstacles echoed. A hit point is kept, in the world frame, for ``memory_s``
  and weighs like a reading (it goes to the sector of the nearest ray, at its own bearing).
  With 8 rays 45 deg apart a pillar or the corner of a box can slip between two rays as the
  agent moves or turns; without the memory the layer forgot it and handed back to a planner
  that flew straight into it. A remembered point is dropped when a ray now passes freely
  through it (within ``clear_width``), so that what has moved away does not haunt the agent.
* tells echoes of flock mates apart. A range sensor cannot tell a drone from a pillar, but an
  echo within ``neighbour_margin`` of the airframe of a sensed neighbour is explained by it.
  Such an echo is not remembered (it moves), closes at the relative speed, and weighs over the
  shorter ``neighbour_range_m``: the planner's separation keeps mates apart; the layer only
  steps in when one is about to be touched, instead of turning the whole flock away from
  itself at every tick. A sensed neighbour also counts as an echo of its airframe (radius: the
  rays' start offset) where no ray hits it, so a mate cannot slip between two rays either, and
  an echo the agent closes on (faster than ``CLOSING_SPEED``) is watched whatever its bearing,
  so that an agent drifting against its heading is not handed back while it flies into a mate.
  Without neighbour positions every echo is an obstacle.

Velocities are scaled down, direction kept, to the per-axis limits. An agent the layer does not
take over keeps its planner's command untouched.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
import pydantic
from numpy.typing import NDArray
from pydantic import Field

from pybullet_swarm.planning.base import AvoidanceSetup, Command, CommandKind, TaskView
from pybullet_swarm.planning.orca import preferred_velocities
from pybullet_swarm.planning.params import ParamRuleError, Params, PlanContext, check_memory
from pybullet_swarm.types import Perception


def lateral_weight(phi: NDArray[np.float64]) -> NDArray[np.float64]:
    """Lateral weight (...) of rays at bearings phi (...) rad from the heading (+: push to the left)."""
    return -np.sin(phi) * 0.5 * (1.0 + np.cos(phi))


def forward_weight(phi: NDArray[np.float64]) -> NDArray[np.float64]:
    """Longitudinal weight (...) of rays at bearings phi (...) rad (+: push forwards)."""
    return -np.cos(phi)


def stopping_distance(closing: NDArray[np.float64], reaction_time: float, decel: float) -> NDArray[np.float64]:
    """Distance (...) m covered before stopping from a closing speed (...) m/s (<= 0: none).

    Args:
        closing: m/s, speed towards the echo.
        reaction_time: s, flown at full speed before braking starts.
        decel: m/s^2, braking deceleration (0: reaction distance only).
    """
    c = np.maximum(np.asarray(closing, dtype=float), 0.0)
    return c * reaction_time + (c * c / (2.0 * decel) if decel > 0.0 else 0.0)


#: m/s, an echo the agent closes on faster than this is watched whatever its bearing
CLOSING_SPEED = 0.05


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


class BraitenbergParams(Params):
    """Parameters of the braitenberg layer (scenario ``avoidance_params``).

    Weights, corrections and the reverse speed are in units of the horizontal velocity limit;
    activations (1 - reading / range) lie in [0, 1].
    """

    weight_lateral: float = Field(3.0, ge=0.0, le=100.0, description="sideways push per unit of summed activation")
    weight_forward: float = Field(
        2.0, ge=0.0, le=100.0, description="braking (ahead) or pushing (behind) per unit of summed activation"
    )
    on_threshold: float = Field(0.3, ge=0.0, le=1.0, description="activation above which the layer takes over")
    off_threshold: float = Field(
        0.15,
        ge=0.0,
        le=1.0,
        description="the layer hands back when every watched activation is below this (<= on_threshold)",
    )
    watch_deg: float = Field(
        100.0,
        ge=0.0,
        le=180.0,
        description="deg, rays within this bearing of the heading are watched for the thresholds",
    )
    front_deg: float = Field(
        50.0, ge=0.0, le=180.0, description="deg, the cone in which a symmetric obstacle is looked for"
    )
    symmetry_threshold: float = Field(
        0.3, ge=0.0, le=1.0, description="front activation above which a symmetric reading is corrected"
    )
    symmetry_ratio: float = Field(
        0.25, ge=0.0, le=10.0, description="a lateral sum below this fraction of the front activation is symmetric"
    )
    symmetry_step: float = Field(
        0.25, ge=0.0, le=10.0, description="growth of the symmetry correction per planner tick"
    )
    symmetry_max: float = Field(1.0, ge=0.0, le=10.0, description="cap of the symmetry correction")
    max_reverse: float = Field(0.3, ge=0.0, le=10.0, description="fastest backing away along the heading")
    arrive_time: float = Field(
        0.5, gt=0.0, le=60.0, description="s, a POSITION command's preferred velocity is (target - p) / arrive_time"
    )
    reaction_time: float = Field(
        0.3,
        ge=0.0,
        le=10.0,
        description="s, readings are shortened by the distance flown in this time at the "
        "closing speed and the braking distance (0: raw readings)",
    )
    memory_s: float = Field(2.0, ge=0.0, le=60.0, description="s, an obstacle echo is remembered this long (0: none)")
    clear_width: float = Field(
        0.02, ge=0.0, le=1.0, description="m, a remembered point is dropped when a ray passes freely this close"
    )
    neighbour_margin: float = Field(
        0.05, ge=0.0, le=1.0, description="m, an echo this close to a sensed neighbour's airframe is that neighbour"
    )
    neighbour_range_m: float = Field(
        0.2, ge=0.0, le=100.0, description="m, range over which a neighbour's echo weighs (0: ignored)"
    )

    @pydantic.model_validator(mode="after")
    def _hysteresis(self) -> BraitenbergParams:
        if self.off_threshold > self.on_threshold:
            raise ParamRuleError(
                "off_threshold", f"must be <= on_threshold ({self.on_threshold:g}), got {self.off_threshold:g}"
            )
        return self

    def check_for(self, context: PlanContext) -> None:
        """Refuse a memory of echoes larger than the memory budget."""
        ticks = math.ceil(self.memory_s * context.planner_hz - 1e-9)
        check_memory(
            "memory_s",
            17.0 * context.n_agents * ticks * context.range_rays,
            context.memory_budget,
            f"a memory of {ticks} ticks of {context.range_rays} echoes for {context.n_agents} agents",
        )


class Braitenberg:
    """The avoidance rule for n agents, on plain arrays (one state per agent: heading, mode,
    correction, remembered obstacle echoes).

    Args:
        params: weights and thresholds.
        angles: (r,) rad, ray bearings in the levelled body frame.
        range_m: m, length of a ray.
        v_max: (3,) m/s per-axis limit (None: 1 m/s is the unit of the weights).
        n: number of agents.
        offset: m, rays start this far from the agent's centre (the airframe's radius).
        decel: m/s^2, horizontal braking deceleration (the acceleration limit).
        dt: s, planner period (ticks of the memory).
    """

    def __init__(
        self,
        params: BraitenbergParams,
        angles: NDArray[np.float64],
        range_m: float,
        v_max: NDArray[np.float64] | None,
        n: int,
        *,
        offset: float = 0.0,
        decel: float = 1.0,
        dt: float = 0.1,
    ) -> None:
        self.params = params
        self.angles = np.asarray(angles, dtype=float).reshape(-1)
        self.range_m = float(range_m)
        self.v_max = None if v_max is None else np.asarray(v_max, dtype=float).reshape(3)
        self.v_h = 1.0 if self.v_max is None else float(min(self.v_max[0], self.v_max[1]))
        self.n = int(n)
        self.offset = float(offset)
        self.decel = float(decel)
        self.heading = np.zeros(self.n)  # rad, last heading of each agent
        self.active = np.zeros(self.n, dtype=bool)  # taking over from the planner
        self.correction = np.zeros(self.n)  # units of the limit, push to the right
        r = self.angles.size
        self.memory_ticks = int(math.ceil(params.memory_s / dt - 1e-9)) if params.memory_s > 0 else 0
        self.memory = np.zeros((self.n, self.memory_ticks * r, 2))  # (n, M, 2) m, world xy
        self.remembered = np.zeros((self.n, self.memory_ticks * r), dtype=bool)  # (n, M)
        self._tick = 0

    def step(
        self,
        ranges: NDArray[np.float64],
        yaws: NDArray[np.float64],
        velocities: NDArray[np.float64],
        preferred: NDArray[np.float64],
        *,
        positions: NDArray[np.float64] | None = None,
        neighbour_positions: NDArray[np.float64] | None = None,
        neighbour_velocities: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """One planner tick for every agent.

        Args:
            ranges: (n, r) m, each agent's own readings.
            yaws: (n,) rad.
            velocities: (n, 3) m/s, each agent's own velocity.
            preferred: (n, 3) m/s, the velocity each agent's planner asks for.
            positions: (n, 3) m, each agent's own position (None: no memory, no neighbours).
            neighbour_positions: (n, k, 3) m, the neighbours each agent senses, NaN-padded.
            neighbour_velocities: (n, k, 3) m/s, their velocities, NaN-padded.

        Returns:
            velocities (n, 3) m/s to command where the layer takes over, and that mask (n,).
        """
        p = self.params
        pref = np.asarray(preferred, dtype=float)
        vel = np.asarray(velocities, dtype=float)
        yaws = np.asarray(yaws, dtype=float).reshape(self.n)
        a, bearing, closing = self._activations(
            np.asarray(ranges, dtype=float).reshape(self.n, -1),
            yaws,
            vel,
            positions,
            neighbour_positions,
            neighbour_velocities,
        )
        sp = np.hypot(pref[:, 0], pref[:, 1])
        sv = np.hypot(vel[:, 0], vel[:, 1])
        self.heading = np.where(
            sp > 1e-3,
            np.arctan2(pref[:, 1], pref[:, 0]),
            np.where(sv > 0.05, np.arctan2(vel[:, 1], vel[:, 0]), self.heading),
        )
        phi = _wrap(bearing - self.heading[:, None])
        lat = np.sum(a * lateral_weight(phi), axis=1)  # (n,)
        lon = np.sum(a * forward_weight(phi), axis=1)
        # an echo the agent is closing on is watched wherever it is: pushed sideways, or still drifting
        # against its heading, an agent must not be handed back while it flies into something behind
        seen = (np.abs(phi) <= math.radians(p.watch_deg)) | (closing > CLOSING_SPEED)
        watched = np.where(seen, a, 0.0).max(axis=1, initial=0.0)
        self.active = np.where(watched > p.on_threshold, True, np.where(watched < p.off_threshold, False, self.active))
        front = np.where(np.abs(phi) <= math.radians(p.front_deg), a, 0.0).max(axis=1, initial=0.0)
        symmetric = (front > p.symmetry_threshold) & (np.abs(lat) < p.symmetry_ratio * front)
        self.correction = np.where(
            symmetric, np.minimum(self.correction + p.symmetry_step, p.symmetry_max), 0.5 * self.correction
        )
        h = np.column_stack([np.cos(self.heading), np.sin(self.heading), np.zeros(self.n)])
        left = np.column_stack([-np.sin(self.heading), np.cos(self.heading), np.zeros(self.n)])
        side = self.v_h * (p.weight_lateral * lat - self.correction)
        along = np.sum(pref * h, axis=1)
        floor = np.minimum(0.0, -p.max_reverse * self.v_h - along)  # braking may not throw it backwards
        ahead = np.maximum(self.v_h * p.weight_forward * lon, floor)
        out = pref + ahead[:, None] * h + side[:, None] * left
        if self.v_max is not None:
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(np.abs(out) > self.v_max, self.v_max / np.abs(out), 1.0).min(axis=1)
            out *= ratio[:, None]
        return out, self.active.copy()

    def _activations(
        self,
        ranges: NDArray[np.float64],
        yaws: NDArray[np.float64],
        vel: NDArray[np.float64],
        positions: NDArray[np.float64] | None,
        nb_pos: NDArray[np.float64] | None,
        nb_vel: NDArray[np.float64] | None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Activation (n, r) of each ray's sector, the world bearing (n, r) rad it comes from and the
        speed (n, r) m/s at which the agent closes on it."""
        n, r = ranges.shape
        world = yaws[:, None] + self.angles[None, :]  # (n, r) rad
        dirs = np.stack([np.cos(world), np.sin(world)], axis=2)  # (n, r, 2)
        hit = ranges < self.range_m - 1e-9
        closing = np.sum(vel[:, None, :2] * dirs, axis=2)  # (n, r) m/s
        scale = np.full((n, r), self.range_m)  # m, range the echo weighs over
        if positions is None:
            return self._activation(ranges, closing, scale, hit), world, closing
        pos = np.asarray(positions, dtype=float).reshape(n, 3)[:, :2]
        points = pos[:, None, :] + (self.offset + ranges)[:, :, None] * dirs  # (n, r, 2) m
        mate, mate_vel = self._explaining_neighbour(points, hit, nb_pos, nb_vel)
        closing = np.where(mate, np.sum((vel[:, None, :2] - mate_vel) * dirs, axis=2), closing)
        scale = np.where(mate, self.params.neighbour_range_m, scale)
        # candidates (n, P): the rays, then remembered obstacle echoes and the sensed neighbours
        a_all: list[NDArray[Any]] = [self._activation(ranges, closing, scale, hit)]
        b_all: list[NDArray[Any]] = [world]
        c_all: list[NDArray[Any]] = [closing]
        s_all: list[NDArray[Any]] = [np.broadcast_to(np.arange(r), (n, r))]
        if self.memory_ticks > 0:
            self._forget_crossed(pos, dirs, ranges)
            for lst, x in zip((a_all, b_all, c_all, s_all), self._remembered(pos, yaws, vel)):
                lst.append(x)
            self._store(points, hit & ~mate)
        if nb_pos is not None and np.asarray(nb_pos).size > 0:
            for lst, x in zip((a_all, b_all, c_all, s_all), self._neighbours(pos, yaws, vel, nb_pos, nb_vel)):
                lst.append(x)
        if len(a_all) == 1:
            return a_all[0], world, closing
        a, b, c, sec = (np.concatenate(x, axis=1) for x in (a_all, b_all, c_all, s_all))
        cand = np.where(sec[:, None, :] == np.arange(r)[None, :, None], a[:, None, :], -1.0)  # (n, r, P)
        k = np.argmax(cand, axis=2)
        best = np.take_along_axis(cand, k[..., None], axis=2)[..., 0]
        pick = lambda x: np.take_along_axis(np.broadcast_to(x[:, None, :], cand.shape), k[..., None], axis=2)[..., 0]  # noqa: E731
        return np.maximum(best, 0.0), np.where(best > 0.0, pick(b), world), np.where(best > 0.0, pick(c), 0.0)

    def _sector(self, bearing: NDArray[np.float64], yaws: NDArray[np.float64]) -> NDArray[np.int64]:
        """Nearest ray (n, m) of world bearings (n, m) rad for agents with yaws (n,) rad."""
        body = _wrap(bearing - yaws[:, None])
        return np.argmin(np.abs(_wrap(body[:, :, None] - self.angles[None, None, :])), axis=2)

    def _neighbours(
        self,
        pos: NDArray[np.float64],
        yaws: NDArray[np.float64],
        vel: NDArray[np.float64],
        nb_pos: NDArray[np.float64],
        nb_vel: NDArray[np.float64] | None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """Activation (n, k), world bearing (n, k) rad, closing speed (n, k) m/s and nearest ray (n, k) of
        each sensed neighbour's airframe (radius: the rays' offset), as an echo that cannot slip between rays."""
        n = pos.shape[0]
        q = np.asarray(nb_pos, dtype=float).reshape(n, -1, 3)[:, :, :2]
        qv = (
            np.zeros_like(q)
            if nb_vel is None
            else np.nan_to_num(np.asarray(nb_vel, dtype=float).reshape(n, -1, 3)[:, :, :2])
        )
        known = ~np.isnan(q[:, :, 0])
        rel = np.nan_to_num(q - pos[:, None, :], nan=1e9)
        dist = np.linalg.norm(rel, axis=2)
        unit = rel / np.maximum(dist, 1e-9)[:, :, None]
        closing = np.sum((vel[:, None, :2] - qv) * unit, axis=2)
        free = np.maximum(dist - 2.0 * self.offset, 0.0)
        scale = np.full(free.shape, self.params.neighbour_range_m)
        bearing = np.arctan2(rel[:, :, 1], rel[:, :, 0])
        return self._activation(free, closing, scale, known), bearing, closing, self._sector(bearing, yaws)

    def _activation(
        self,
        free: NDArray[np.float64],
        closing: NDArray[np.float64],
        scale: NDArray[np.float64],
        hit: NDArray[np.bool_],
    ) -> NDArray[np.float64]:
        """Activation (...) of echoes at free distance (...) m closing at (...) m/s, weighing over scale (...) m."""
        left = free - stopping_distance(closing, self.params.reaction_time, self.decel)
        with np.errstate(divide="ignore", invalid="ignore"):
            a = np.where(scale > 0.0, 1.0 - left / scale, 0.0)
        return np.where(hit, np.clip(a, 0.0, 1.0), 0.0)

    def _explaining_neighbour(
        self,
        points: NDArray[np.float64],
        hit: NDArray[np.bool_],
        nb_pos: NDArray[np.float64] | None,
        nb_vel: NDArray[np.float64] | None,
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        """Which echoes (n, r) a sensed neighbour explains, and that neighbour's velocity (n, r, 2) m/s."""
        n, r = hit.shape
        if nb_pos is None or np.asarray(nb_pos).size == 0:
            return np.zeros((n, r), dtype=bool), np.zeros((n, r, 2))
        q = np.asarray(nb_pos, dtype=float).reshape(n, -1, 3)[:, :, :2]  # (n, k, 2)
        qv = np.zeros_like(q) if nb_vel is None else np.asarray(nb_vel, dtype=float).reshape(n, -1, 3)[:, :, :2]
        d = np.linalg.norm(points[:, :, None, :] - q[:, None, :, :], axis=3)  # (n, r, k) m
        d = np.where(np.isnan(d), np.inf, d)
        j = np.argmin(d, axis=2)
        near = np.take_along_axis(d, j[..., None], axis=2)[..., 0] <= self.offset + self.params.neighbour_margin
        mv = np.take_along_axis(qv, j[..., None], axis=1)  # (n, r, 2)
        return hit & near, np.nan_to_num(mv)

    def _forget_crossed(self, pos: NDArray[np.float64], dirs: NDArray[np.float64], ranges: NDArray[np.float64]) -> None:
        """Drop remembered points a ray now passes freely through (it saw beyond them)."""
        rel = self.memory - pos[:, None, :]  # (n, M, 2)
        along = np.einsum("nmi,nri->nmr", rel, dirs) - self.offset  # (n, M, r) m
        across = np.abs(rel[:, :, None, 0] * dirs[:, None, :, 1] - rel[:, :, None, 1] * dirs[:, None, :, 0])
        margin = 2.0 * self.params.clear_width
        crossed = (across < self.params.clear_width) & (along >= 0.0) & (along < ranges[:, None, :] - margin)
        self.remembered &= ~np.any(crossed, axis=2)

    def _remembered(
        self, pos: NDArray[np.float64], yaws: NDArray[np.float64], vel: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """Activation (n, M), world bearing (n, M) rad, closing speed (n, M) m/s and nearest ray (n, M)
        of the remembered points."""
        rel = self.memory - pos[:, None, :]
        dist = np.linalg.norm(rel, axis=2)
        bearing = np.arctan2(rel[:, :, 1], rel[:, :, 0])
        unit = rel / np.maximum(dist, 1e-9)[:, :, None]
        closing = np.sum(vel[:, None, :2] * unit, axis=2)
        free = np.maximum(dist - self.offset, 0.0)
        valid = self.remembered & (free < self.range_m)
        a = self._activation(free, closing, np.full(free.shape, self.range_m), valid)
        return a, bearing, closing, self._sector(bearing, yaws)

    def _store(self, points: NDArray[np.float64], keep: NDArray[np.bool_]) -> None:
        """Write this tick's obstacle echoes (n, r) over the oldest block of the memory."""
        r = points.shape[1]
        block = slice((self._tick % self.memory_ticks) * r, (self._tick % self.memory_ticks + 1) * r)
        self.memory[:, block] = points
        self.remembered[:, block] = keep
        self._tick += 1


class BraitenbergLayer:
    """The ``--avoidance braitenberg`` layer: each agent avoids what its own range sensors see.

    Needs the range sensors (``sensing.range`` of the scenario: 8 horizontal rays of 0.5 m by
    default; the clock turns them on for this layer). Every planner tick it reads each agent's own
    row of the perception snapshot (range readings, position, velocity, yaw, sensed neighbours) and
    replaces the command of each agent it takes over by a VELOCITY command with the same yaw and action.

    Args:
        setup: what the layer is told before the run (ray fan, limits, planner period).
        params: validated ``BraitenbergParams`` (scenario ``avoidance_params``; default: the defaults).
    """

    Params: ClassVar[type[BraitenbergParams]] = BraitenbergParams
    needs_range_sensors: ClassVar[bool] = True

    def __init__(self, setup: AvoidanceSetup, params: BraitenbergParams | None = None) -> None:
        self.params = params if params is not None else BraitenbergParams()
        if setup.range_angles.size == 0:
            raise ValueError("the braitenberg layer needs range sensors (sensing.range)")
        self.v_max = setup.v_max
        acc = setup.a_max
        self.rule = Braitenberg(
            self.params,
            setup.range_angles,
            setup.range_m,
            self.v_max,
            setup.n,
            offset=setup.range_offset,
            decel=float(min(acc[0], acc[1])),
            dt=setup.planner_dt,
        )
        self.n = setup.n
        self._ticks = 0
        self._active_ticks = 0
        self._switches = 0

    def filter(self, commands: list[Command], perception: Perception, task: TaskView) -> list[Command]:
        """Commands for this planner tick (``action`` and ``yaw`` of each command are kept)."""
        n = self.n
        pos, vel, yaws, ranges = perception.positions, perception.velocities, perception.yaws, perception.ranges
        counts = np.diff(perception.nb_start)
        k = int(counts.max()) if counts.size else 0
        nb_pos = np.full((n, k, 3), np.nan)
        nb_vel = np.full((n, k, 3), np.nan)
        if perception.nb_ids.size:
            owner = np.repeat(np.arange(n), counts)
            col = np.arange(owner.size) - np.repeat(perception.nb_start[:-1], counts)
            nb_pos[owner, col] = perception.nb_positions
            nb_vel[owner, col] = perception.nb_velocities
        kinds = np.fromiter((int(c.kind) for c in commands), dtype=np.int64, count=n)
        vectors = np.array([c.vector for c in commands], dtype=float).reshape(n, 3)
        pref = preferred_velocities(kinds, vectors, pos, arrive_time=self.params.arrive_time, v_max=None)
        if self.v_max is not None:  # scaled, not clipped per axis: the heading is where the planner points
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(np.abs(pref) > self.v_max, self.v_max / np.abs(pref), 1.0).min(axis=1)
            pref *= ratio[:, None]
        before = self.rule.active.copy()
        v, active = self.rule.step(
            ranges, yaws, vel, pref, positions=pos, neighbour_positions=nb_pos, neighbour_velocities=nb_vel
        )
        self._ticks += 1
        self._active_ticks += int(np.count_nonzero(active))
        self._switches += int(np.count_nonzero(active != before))
        return [
            Command(CommandKind.VELOCITY, v[i].copy(), c.yaw, c.action) if active[i] else c
            for i, c in enumerate(commands)
        ]

    def metrics(self) -> dict[str, Any]:
        """Counters of the run (merged into metrics.json)."""
        return {
            "braitenberg_active_fraction": self._active_ticks / max(self._ticks * self.n, 1),
            "braitenberg_switches": self._switches,
        }


from pybullet_swarm.planning.registry import register_avoidance  # noqa: E402

register_avoidance(
    "braitenberg",
    BraitenbergLayer,
    "Braitenberg avoidance on each agent's own range sensors "
    "(weighted readings onto the velocity, threshold with hysteresis, symmetry correction)",
)
