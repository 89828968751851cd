"""Collision counting from Bullet contacts: classified onset events and time in contact."""

from __future__ import annotations

import enum
import math
from typing import AbstractSet, Callable

import numpy as np


class CollisionClass(str, enum.Enum):
    """Classes of contacts: an agent's, and a carried load's (a box an agent holds) with other task bodies."""

    AGENT_AGENT = "agent_agent"
    AGENT_BOX = "agent_box"
    AGENT_STRUCTURE = "agent_structure"
    AGENT_GROUND = "agent_ground"
    AGENT_OBSTACLE = "agent_obstacle"
    LOAD_LOAD = "load_load"  # two agents' carried boxes
    LOAD_BOX = "load_box"  # a carried box and a free box
    LOAD_STRUCTURE = "load_structure"  # a carried box and a placed one
    LOAD_GROUND = "load_ground"  # a carried box and the ground
    LOAD_WALL = "load_wall"  # a carried box and an arena wall
    LOAD_OBSTACLE = "load_obstacle"  # a carried box and a static obstacle


COLLISION_CLASSES: tuple[str, ...] = tuple(c.value for c in CollisionClass)


class ContactTracker:
    """Turns per-step sets of touching body pairs into collision events and contact time.

    An event is the onset of contact of a pair that was apart for at least ``debounce_s``.
    Pairs are classified by ``classify(a, b) -> CollisionClass | None`` (None: not counted,
    e.g. an agent and the box it carries, or an agent resting on the ground before take-off).

    Args:
        classify: pair classifier; called once per newly touching pair.
        dt: physics period, s.
        debounce_s: minimum separation time before a new onset counts, s.
    """

    def __init__(
        self, classify: Callable[[int, int], CollisionClass | None], dt: float, debounce_s: float = 0.1
    ) -> None:
        self.classify = classify
        self.dt = float(dt)
        self.debounce_s = float(debounce_s)
        self.counts = {c: 0 for c in COLLISION_CLASSES}
        self.time_s = {c: 0.0 for c in COLLISION_CLASSES}
        self._active: dict[tuple[int, int], CollisionClass | None] = {}  # touching pairs and their classes
        self._counted: dict[tuple[int, int], CollisionClass] = {}  # those of them that count
        # when each pair was last seen touching, written when it stops touching (stale while it touches)
        self._last_seen: dict[tuple[int, int], float] = {}
        self._prev: AbstractSet[tuple[int, int]] = frozenset()
        self._t_prev = 0.0  # s, time of the last update

    def update(self, pairs: AbstractSet[tuple[int, int]], t: float) -> list[tuple[CollisionClass, int, int]]:
        """Account for the pairs touching at time ``t`` s; returns new events (class, a, b).

        The pairs touching at the last update must be given again while they touch (an empty set may be
        left out only when none touched at the last update either)."""
        events: list[tuple[CollisionClass, int, int]] = []
        if pairs != self._prev:
            for pair in pairs - self._prev:
                cls = self.classify(*pair)
                self._active[pair] = cls
                if cls is None:
                    continue
                self._counted[pair] = cls
                last = self._last_seen.get(pair)
                if last is None or t - last >= self.debounce_s - 1e-12:
                    self.counts[cls.value] += 1
                    events.append((cls, pair[0], pair[1]))
            for pair in self._prev - pairs:  # last seen touching at the last update
                self._last_seen[pair] = self._t_prev
                self._active.pop(pair, None)
                self._counted.pop(pair, None)
            self._prev = pairs
        for cls in self._counted.values():
            self.time_s[cls.value] += self.dt
        self._t_prev = t
        return events

    def reclassify_all(self) -> None:
        """Classify every touching pair again (a body changed role: a box grasped or released); a pair
        that now counts accumulates contact time from here, it is not a new onset."""
        for pair in self._active:
            cls = self._active[pair] = self.classify(*pair)
            if cls is None:
                self._counted.pop(pair, None)
            else:
                self._counted[pair] = cls


class IncidentCounter:
    """Counts incidents: contact events that belong together count once.

    Two contact events belong to one incident when their onsets are at most ``window_s`` apart (the contact
    debounce interval) and they share a unit: an agent (its carried box counts as the agent) or a free box;
    the ground, walls, obstacles and placed boxes are no units (two agents touching the ground at one instant
    are two incidents). An incident is a chain of such events: an event joins the incident of every unit it
    touches that had an event within the window before it, else it starts a new one.

    Args:
        window_s: s, the largest gap between onsets of one incident.
    """

    def __init__(self, window_s: float) -> None:
        self.window_s = float(window_s)
        self.count = 0
        self._last: dict[str, float] = {}  # unit -> onset time of its latest event

    def add(self, t: float, units: tuple[str, ...]) -> bool:
        """Account for a contact event at ``t`` s touching ``units``; True when it starts a new incident."""
        new = not any(t - self._last.get(u, -math.inf) <= self.window_s + 1e-12 for u in units)
        if new:
            self.count += 1
        for u in units:
            self._last[u] = t
        return new


def proximity_episodes(distances: np.ndarray, threshold: float, dt: float) -> tuple[int, float]:
    """Episodes and total time (s) with a distance below ``threshold`` in a (m,) series sampled every ``dt`` s."""
    below = np.asarray(distances) < threshold
    if below.size == 0:
        return 0, 0.0
    onsets = int(below[0]) + int(np.count_nonzero(below[1:] & ~below[:-1]))
    return onsets, float(np.count_nonzero(below) * dt)
