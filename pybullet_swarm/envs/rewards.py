"""Rewards of an environment step: task progress, completion, collision and crash penalties.

Per agent i and step (weights from ``RewardWeights``)::

    r_i = box_placed * (boxes placed now - before)            # shared, construction
        + box_to_goal * (D before - D now)                     # shared, D: total box-to-goal distance, m
        + point_visited * (points visited now - before)        # shared, tour
        + goal_progress * (d_i before - d_i now)               # own, waypoints: distance to the set-point
                                                               #   active when the step began, m
        + completion * [the task was completed in this step]   # shared
        - collision_penalty * (contact events of agent i)      # own, every collision class
        - crash_penalty * [agent i crashed or diverged]        # own
        - time_penalty * (simulated seconds of the step)       # shared
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.envs.config import RewardWeights
from pybullet_swarm.metrics.collisions import COLLISION_CLASSES
from pybullet_swarm.metrics.construction import box_to_goal_distance
from pybullet_swarm.planning.views.construction import ConstructionState
from pybullet_swarm.planning.views.construction import boxes_of as _boxes
from pybullet_swarm.planning.views.points import points_of as _points
from pybullet_swarm.types import Event, ExitStatus

_COLLISION_KINDS = frozenset(COLLISION_CLASSES)
_FAILURE_KINDS = frozenset({ExitStatus.CRASHED.value, ExitStatus.DIVERGED.value})


def _distances(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Row-wise Euclidean distances (n,) of two (n, 3) arrays."""
    d = a - b
    return np.sqrt(np.einsum("ij,ij->i", d, d))


@dataclasses.dataclass
class StepOutcome:
    """What one step did, per agent.

    Attributes:
        rewards: (n,) reward of each agent.
        collisions: per agent, the contact events (as plain dicts) it was part of.
        goal_distance: (n,) m, distance to the active set-point now (waypoint tasks), else None.
    """

    rewards: NDArray[np.float64]
    collisions: list[list[dict[str, Any]]]
    goal_distance: NDArray[np.float64] | None


def event_dict(e: Event) -> dict[str, Any]:
    """An event as plain data."""
    return {"time_s": e.time_s, "kind": e.kind, "a": e.a, "b": e.b, "detail": e.detail}


class RewardTracker:
    """Keeps the task's progress between steps and turns it into rewards.

    Args:
        sim: the simulation of the episode (fresh, not stepped).
        weights: reward weights.
    """

    def __init__(self, sim: Any, weights: RewardWeights) -> None:
        self.w = weights
        self.n = sim.n
        self.agent_of = {f"agent{i}": i for i in range(sim.n)}  # World body names of the agents
        self.task = sim.task
        view = sim.task.view(sim.time)
        boxes, points = _boxes(view), _points(view)
        self.has_slots = len(boxes.slots) > 0
        self.has_points = len(points.points) > 0
        self.slots_total = len(boxes.slots)
        self.points_total = len(points.points)
        self.placed = int(np.count_nonzero(boxes.slot_filled >= 0))
        self.box_distance = self._box_distance(boxes)
        self.visited = int(np.count_nonzero(points.points_done))
        self.events_seen = len(sim.events)
        self._goal: NDArray[np.float64] | None = None
        self._d0: NDArray[np.float64] | None = None

    @staticmethod
    def _box_distance(boxes: ConstructionState) -> float:
        if len(boxes.objects) == 0 or len(boxes.slots) == 0:
            return 0.0
        return float(box_to_goal_distance(boxes.objects[None, :, :], boxes.slots)[0])

    def start(self, targets: NDArray[np.float64] | None, positions: NDArray[np.float64]) -> None:
        """Remember the active set-points (n, 3) m and the agents' distances to them at the episode start."""
        if targets is not None:
            self._goal = targets
            self._d0 = _distances(targets, positions)

    def end(self, sim: Any, dt: float, completed: bool, targets: NDArray[np.float64] | None = None) -> StepOutcome:
        """Rewards of the step that just ended after ``dt`` simulated seconds.

        Args:
            sim: the simulation.
            dt: simulated seconds of the step.
            completed: the task was completed in this step.
            targets: (n, 3) m, the set-points active now (waypoint tasks).
        """
        w = self.w
        shared = -w.time_penalty * dt
        view = self.task.view(sim.time)
        if self.has_slots:
            boxes = _boxes(view)
            placed = int(np.count_nonzero(boxes.slot_filled >= 0))
            shared += w.box_placed * (placed - self.placed)
            self.placed = placed
            if w.box_to_goal:
                d = self._box_distance(boxes)
                shared += w.box_to_goal * (self.box_distance - d)
                self.box_distance = d
        if self.has_points:
            visited = int(np.count_nonzero(_points(view).points_done))
            shared += w.point_visited * (visited - self.visited)
            self.visited = visited
        if completed:
            shared += w.completion
        goal_distance = None
        if targets is not None and self._goal is not None and self._d0 is not None:
            pos = sim.state_array[:, :3]
            d1 = _distances(self._goal, pos)
            r = shared + w.goal_progress * (self._d0 - d1)
            goal_distance = d1 if np.array_equal(targets, self._goal) else _distances(targets, pos)
            self._goal, self._d0 = targets, goal_distance
        else:
            r = np.full(self.n, shared)
        collisions: list[list[dict[str, Any]]] = [[] for _ in range(self.n)]
        if len(sim.events) > self.events_seen:
            new = sim.events[self.events_seen :]
            self.events_seen = len(sim.events)
            self._charge(new, r, collisions)
        return StepOutcome(r, collisions, goal_distance)

    def _charge(self, events: list[Event], r: NDArray[np.float64], collisions: list[list[dict[str, Any]]]) -> None:
        """Subtract the collision and crash penalties of ``events`` from the rewards ``r`` (n,)."""
        w = self.w
        for e in events:
            if e.kind in _COLLISION_KINDS:
                d = event_dict(e)
                for name in (e.a, e.b):
                    i = self.agent_of.get(name)
                    if i is not None:
                        r[i] -= w.collision_penalty
                        collisions[i].append(d)
            elif e.kind in _FAILURE_KINDS:
                i = self.agent_of.get(e.a)
                if i is None:
                    r -= w.crash_penalty
                else:
                    r[i] -= w.crash_penalty

    def progress(self) -> dict[str, Any]:
        """Task progress as plain data (part of the running metrics)."""
        out: dict[str, Any] = {}
        if self.has_slots:
            out.update(boxes_placed=self.placed, boxes_total=self.slots_total, box_to_goal_m=self.box_distance)
        if self.has_points:
            out.update(points_visited=self.visited, points_total=self.points_total)
        return out
