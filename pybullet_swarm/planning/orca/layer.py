"""The ``--avoidance orca`` layer: the ORCA kernel between any planner and the controller, behind the layer protocol."""

from __future__ import annotations

import functools
import math
import time
from typing import Any, ClassVar

import numpy as np

from pybullet_swarm.planning.base import AvoidanceSetup, Command, CommandKind, TaskView
from pybullet_swarm.planning.orca import rules
from pybullet_swarm.planning.orca.kernel import (
    FLAG_BIASED,
    FLAG_FREE,
    FLAG_INFEASIBLE,
    FLAG_OBSTACLE,
    commanded_velocities,
    neighbour_table,
    orca_velocities,
    preferred_velocities,
    shape_parts,
    union_boxes,
)
from pybullet_swarm.planning.orca.params import OrcaParams, Shape
from pybullet_swarm.planning.orca.rules import clear_paths, obstacles_beside, targets_touching, velocity_bounds
from pybullet_swarm.types import Perception
from pybullet_swarm.vehicle.downwash import DownwashParams


@functools.lru_cache(maxsize=32)
def wake_column(model: DownwashParams, fraction: float, mass: float, load: float) -> tuple[float, float]:
    """(depth m, half-width m) of the column below a vehicle of ``mass`` kg carrying ``load`` kg in which its wake
    pushes an unladen one of the same airframe down with more than ``fraction`` of its weight (``model.column``;
    cached: every run of a sweep asks the same)."""
    return model.column(fraction, mass=mass, load=load)


def _warm_up() -> None:
    """Compile (or load from the cache) the kernels now, so that no planner tick pays for it."""
    pos = np.array([[0.0, 0.0, 1.0], [0.5, 0.0, 1.0]])
    z3 = np.zeros((2, 3))
    nbr = neighbour_table(pos, 1.0, 4)
    for shape in Shape:
        orca_velocities(
            pos,
            z3,
            z3,
            params=OrcaParams(shape=shape),
            sensing_radius=1.0,
            v_max=np.full(3, 1.0),
            radii=np.full(2, 0.1),
            boxes=(z3, np.full((2, 3), 0.05)),
            bounds=(z3 - 1.0, z3 + 1.0),
            neighbours=nbr,
            obstacles=(np.array([[0.25, 0.3, 1.0]]), np.full((1, 3), 0.05)),
        )
    clear_paths(
        pos,
        pos,
        z3,
        np.full((2, 3), 0.05),
        z3,
        nbr,
        np.ones(2, dtype=np.bool_),
        0.0,
        0.0,
        np.zeros(2, dtype=np.bool_),
        z3,
        np.full((2, 3), 0.05),
        np.zeros((2, 12)),
        0.0,
        0.0,
        np.zeros((2, 3)),
    )
    targets_touching(
        z3, np.zeros((2, 12)), np.ones(2, dtype=np.bool_), z3, np.full((2, 3), 0.05), 0.0, np.zeros(2, dtype=np.bool_)
    )


class OrcaLayer:
    """The ``--avoidance orca`` layer: turns every planner's commands into safe ones.

    Each planner tick, per agent: the nearest neighbours within the sensing radius (from the swarm's
    perception snapshot), shapes from sensed attitude and load, the static obstacles
    (the paper's: the arena's from the set-up, the task's from its view), one LP; a
    command is kept when it is safe as it is (``minimal_intervention``) or a precise final approach
    is clear (``passthrough``), else replaced by a VELOCITY command with the same ``action`` and ``yaw``.

    Args:
        setup: what the layer is told before the run (vehicle, limits, rates, sensing radius, task layout).
        params: validated ``OrcaParams`` (scenario ``avoidance_params``; default: the defaults).
    """

    Params: ClassVar[type[OrcaParams]] = OrcaParams
    needs_range_sensors: ClassVar[bool] = False

    def __init__(self, setup: AvoidanceSetup, params: OrcaParams | None = None) -> None:
        self.params = params if params is not None else OrcaParams()
        info = setup.info
        std = float(info.extra.get("position_std", 0.0))  # m, per-axis, flying on estimates
        if std > 0.0 and self.params.uncertainty_margin:
            grow = rules.uncertainty_growth(self.params.uncertainty_sigmas, std)
            self.params = self.params.model_copy(update={"safety_margin": self.params.margin + grow})
        #: (depth m, half-width m) of the wake column the wake model gives for this vehicle and load (None: unused)
        self.wake_shape: tuple[float, float] | None = None
        if self.params.wake_depth is None:  # the wake column acts where the run has wakes, as deep as they push
            model = setup.downwash_model
            if setup.downwash and model is not None and self.params.wake_column and self.params.shape is Shape.BOX:
                self.wake_shape = wake_column(model, self.params.wake_fraction, setup.mass, setup.load_mass)
            depth = self.params.wake(setup.downwash, None if self.wake_shape is None else self.wake_shape[0])
            self.params = self.params.model_copy(update={"wake_depth": depth})
        self.n = setup.n
        self.v_max = setup.v_max  # (3,) m/s or None
        self.a_max = setup.a_max  # (3,) m/s^2
        self.control_dt = setup.control_dt  # s, the shaper's tick
        self.sensing_radius = setup.sensing_radius
        self.r_agent = float(setup.agent_radius)  # m, airframe enclosing radius
        self.half_extent = 0.5 * np.asarray(setup.collision_size, dtype=float)  # (3,) m
        load = setup.payload  # a hanging payload to keep clear (a cube), None when the task carries nothing
        self.box_size = float(load.edge) if load is not None else 0.0  # m, 0 when the task carries nothing
        self.box_drop = float(load.hang) if load is not None else 0.0  # m, payload centre below the agent
        self.arena_obstacles = setup.obstacles  # the arena's, for the whole run
        # sphere around the agent centre enclosing airframe and hanging box
        self.r_carry = max(
            self.r_agent, math.hypot(math.sqrt(2.0) * 0.5 * self.box_size, self.box_drop + 0.5 * self.box_size)
        )
        self.planner_dt = float(setup.planner_dt)  # s, between filter calls
        _warm_up()
        self._ticks = 0
        self._agent_ticks = 0
        self._infeasible = 0
        self._biased = 0
        self._obstacle = 0
        self._changed = 0
        self._time_total = 0.0
        self._time_max = 0.0

    def filter(self, commands: list[Command], perception: Perception, task: TaskView) -> list[Command]:
        """Safe commands for this planner tick (``action`` and ``yaw`` of each command are kept)."""
        t0 = time.perf_counter()
        p = self.params
        n = self.n
        pos = np.ascontiguousarray(perception.positions)  # sensed (estimated) own states
        vel = np.ascontiguousarray(perception.velocities)
        carrying = task.carrying >= 0
        kinds = np.fromiter((int(cmd.kind) for cmd in commands), dtype=np.int64, count=n)
        vectors = np.array([cmd.vector for cmd in commands], dtype=float).reshape(n, 3)
        hold = kinds == int(CommandKind.HOLD)
        has_goal = (kinds == int(CommandKind.POSITION)) | hold
        goals = np.where(has_goal[:, None], vectors, pos)
        goals[hold] = pos[hold]
        pref = preferred_velocities(
            kinds, vectors, pos, arrive_time=p.arrive_time, v_max=self.v_max, max_speed=p.max_speed
        )
        v_cmd = commanded_velocities(kinds, vectors, pos, v_max=self.v_max, a_max=self.a_max, dt=self.control_dt)
        nbr = perception.nearest_table(p.max_neighbours)
        parts = shape_parts(
            np.ascontiguousarray(perception.quaternions), self.half_extent, carrying, self.box_size, self.box_drop
        )
        centre, half = union_boxes(parts)
        radii = np.where(carrying, self.r_carry, self.r_agent)
        obstacles = self.arena_obstacles + task.obstacles  # the paper's static obstacles; passthrough_turns reads them
        oc = np.ascontiguousarray(obstacles.centres, dtype=float)
        oh = np.ascontiguousarray(obstacles.half_extents, dtype=float)
        beside = None
        if p.column_rule and p.column_reach is not None:
            beside = obstacles_beside(pos, centre, half, oc, oh, p.column_reach)
        # bounds around what the command itself asks for (per axis it covers the preferred velocity)
        bounds = velocity_bounds(
            pos,
            v_cmd,
            self.v_max,
            floor_height=p.floor_height,
            goals=goals,
            has_goal=has_goal,
            column=p.column_radius if p.column_rule else 0.0,
            beside=beside,
            column_tick=self.planner_dt if p.column_tick else None,
        )
        safe, flags = orca_velocities(
            pos,
            rules.reference_velocities(vel, self.v_max, p.clipped_reference),
            pref,
            params=p,
            sensing_radius=self.sensing_radius,
            v_max=self.v_max,
            radii=radii,
            boxes=(centre, half),
            goals=goals,
            has_goal=has_goal,
            bounds=bounds,
            commanded=v_cmd,
            neighbours=nbr,
            obstacles=(oc, oh),
            parts=parts,
            ground=True,
        )
        passthrough = np.zeros(n, dtype=np.bool_)
        if p.passthrough:
            near = has_goal & (np.linalg.norm(goals - pos, axis=1) <= p.capture_radius)
            if near.any():
                turn = np.zeros((n, 3))
                if p.passthrough_turns:  # to a waypoint: clear of where each neighbour may turn to
                    touching = np.zeros(n, dtype=np.bool_)
                    targets_touching(
                        goals,
                        parts,
                        near,
                        oc,
                        oh,
                        p.margin + p.goal_reach,
                        touching,
                    )
                    turn[near & ~touching] = 0.5 * self.a_max * p.clearance_lookahead**2
                clear_paths(
                    pos,
                    goals,
                    centre,
                    half,
                    vel,
                    nbr,
                    near,
                    p.clearance_margin,
                    p.clearance_lookahead,
                    passthrough,
                    oc,
                    oh,
                    parts,
                    p.margin + p.goal_reach,
                    p.wake(downwash=False),
                    turn,
                )
        keep = passthrough | ((flags & FLAG_FREE) != 0)
        out = [
            cmd if keep[i] else Command(CommandKind.VELOCITY, safe[i].copy(), cmd.yaw, cmd.action)
            for i, cmd in enumerate(commands)
        ]
        dt = time.perf_counter() - t0
        self._ticks += 1
        self._agent_ticks += n
        self._infeasible += int(np.count_nonzero(flags & FLAG_INFEASIBLE))
        self._biased += int(np.count_nonzero(flags & FLAG_BIASED))
        self._obstacle += int(np.count_nonzero(flags & FLAG_OBSTACLE))
        self._changed += int(n - np.count_nonzero(keep))
        self._time_total += dt
        self._time_max = max(self._time_max, dt)
        return out

    def metrics(self) -> dict[str, Any]:
        """Counters of the run (merged into metrics.json); the ``*_ms`` ones are wall-clock timings."""
        ticks = max(self._ticks, 1)
        return {
            "orca_ticks": self._ticks,
            "orca_changed_fraction": self._changed / max(self._agent_ticks, 1),
            "orca_infeasible_agent_ticks": self._infeasible,
            "orca_biased_agent_ticks": self._biased,
            "orca_obstacle_agent_ticks": self._obstacle,
            "orca_mean_solve_ms": 1e3 * self._time_total / ticks,
            "orca_max_solve_ms": 1e3 * self._time_max,
            "orca_wake_depth_m": float(self.params.wake_depth or 0.0),
            "orca_wake_half_width_m": None if self.wake_shape is None else self.wake_shape[1],
        }
