"""Watching a run in the Bullet GUI: a camera that frames the arena, real-time pacing, overlays.

``runner.run(gui=True)`` steps the simulation one control period at a time and calls
``GuiViewer.update`` after each step: the viewer sleeps so that simulated time advances at
``speed`` x the wall clock, and draws what Bullet's GUI can show of the replay's overlays:
the arena's outline, agents coloured as in the replay (tab10), short dotted trails, a carried box
in its carrier's colour (a placed box green), contacts flashing as large red points at the agents
involved, and a heads-up line with simulated time, boxes placed and contacts so far. Every
overlay is drawn with few calls (points of all agents at once): in GUI mode each call to Bullet
waits for the GUI's thread.
"""

from __future__ import annotations

import colorsys
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.planning.views.construction import PLACED, boxes_of

#: matplotlib's tab10, the replay's agent colours up to 10 agents (RGB in [0, 1])
TAB10 = (
    (0.122, 0.467, 0.706),
    (1.0, 0.498, 0.055),
    (0.173, 0.627, 0.173),
    (0.839, 0.153, 0.157),
    (0.580, 0.404, 0.741),
    (0.549, 0.337, 0.294),
    (0.890, 0.467, 0.761),
    (0.498, 0.498, 0.498),
    (0.737, 0.741, 0.133),
    (0.090, 0.745, 0.812),
)
BOX_FREE = (0.76, 0.60, 0.42)
BOX_PLACED = (0.42, 0.62, 0.33)
GUI_ASPECT = 4.0 / 3.0  # width / height of Bullet's default GUI window
GUI_FOV_DEG = 90.0  # vertical field of view of Bullet's GUI camera (its frustum's top is its near distance)
TRAIL_S = 3.0  # s of simulated time a trail point stays
TRAIL_STEP_S = 0.25  # s of simulated time between trail points
HUD_STEP_S = 1.0  # s of simulated time between updates of the heads-up line
FLASH_S = 0.6  # s of simulated time a contact mark stays


def agent_rgb(n: int) -> list[tuple[float, float, float]]:
    """One RGB colour per agent: tab10 up to 10 agents, else evenly spaced hues."""
    if n <= len(TAB10):
        return list(TAB10[:n])
    return [colorsys.hsv_to_rgb(i / n, 1.0, 1.0) for i in range(n)]


class Pacer:
    """Sleeps so that simulated time advances at ``speed`` x the wall clock.

    When the simulation falls behind by more than ``max_lag_s`` (it cannot keep up), the pace is
    re-anchored at the present instead of rushing to catch up.

    Args:
        speed: simulated seconds per wall-clock second, > 0.
        clock: wall clock, s (``time.perf_counter``).
        sleep: sleeps for a number of seconds (``time.sleep``).
        max_lag_s: s of wall-clock lag tolerated before re-anchoring.
    """

    def __init__(
        self,
        speed: float,
        *,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], Any] = time.sleep,
        max_lag_s: float = 0.25,
    ) -> None:
        if not (math.isfinite(speed) and speed > 0):
            raise ValueError(f"speed: expected a positive number, got {speed!r}")
        self.speed = float(speed)
        self._clock = clock
        self._sleep = sleep
        self.max_lag_s = float(max_lag_s)
        self._anchor: tuple[float, float] | None = None  # (wall s, simulated s)

    def wait(self, sim_time: float) -> float:
        """Sleep until the wall clock is due for simulated time ``sim_time`` s; returns the seconds slept."""
        now = self._clock()
        if self._anchor is None:
            self._anchor = (now, float(sim_time))
            return 0.0
        wall0, sim0 = self._anchor
        delay = wall0 + (float(sim_time) - sim0) / self.speed - now
        if delay > 0.0:
            self._sleep(delay)
            return delay
        if -delay > self.max_lag_s:
            self._anchor = (now, float(sim_time))
        return 0.0


class GuiViewer:
    """Camera, pacing and overlays of a simulation shown in the Bullet GUI (in DIRECT mode only the
    pacing acts).

    Args:
        sim: the simulation (a ``Simulation``); read, never changed.
        speed: simulated seconds per wall-clock second (1: real time).
    """

    def __init__(self, sim: Any, *, speed: float = 1.0) -> None:
        from pybullet_swarm.experiment.video import camera_for_arena

        self.sim = sim
        self.world = sim.world
        self.pacer = Pacer(speed)
        self.colors = agent_rgb(sim.n)
        arena = tuple(float(v) for v in sim.scenario.arena.size)
        self.arena = arena
        framing = sim.task.framing()
        self.height = (
            framing.height if framing.height is not None else max(1.0, float(np.max(sim.state_array[:, 2])) + 0.5)
        )
        self.camera = camera_for_arena(arena, self.height, aspect=GUI_ASPECT, fov_deg=GUI_FOV_DEG)
        self.world.set_camera(self.camera.target, self.camera.distance, self.camera.yaw, self.camera.pitch)
        corners = [(0.0, 0.0, 0.0), (arena[0], 0.0, 0.0), (arena[0], arena[1], 0.0), (0.0, arena[1], 0.0)]
        for a, b in zip(corners, corners[1:] + corners[:1]):
            self.world.debug_line(a, b, color=(0.2, 0.2, 0.2), width=2.0)
        for body, rgb in zip(self.world.agent_bodies, self.colors):
            self.world.set_color(body, (*rgb, 1.0))
        self._next_trail = sim.time + TRAIL_STEP_S
        self._next_hud = sim.time
        self._hud_id = -1
        self._events_seen = 0
        self._box_color: dict[int, tuple[float, ...]] = {}

    def update(self) -> None:
        """Draw the overlays of the present instant, then wait until the wall clock is due for it."""
        sim = self.sim
        t = sim.time
        if self.world.gui:
            pos = sim.state_array[:, :3]
            if t >= self._next_trail - 1e-9:
                self.world.debug_points(pos, self.colors, size=4.0, lifetime=TRAIL_S / self.pacer.speed)
                self._next_trail = t + TRAIL_STEP_S
            self._flash_contacts(pos)
            self._colour_boxes()
            if t >= self._next_hud - 1e-9:
                self._hud_id = self.world.debug_text(
                    self.hud_text(), (0.0, self.arena[1], self.height + 0.15), size=1.3, replace=self._hud_id
                )
                self._next_hud = t + HUD_STEP_S
        self.pacer.wait(t)

    def hud_text(self) -> str:
        """Simulated time, boxes placed, contacts so far and the pace."""
        sim = self.sim
        parts = [f"t = {sim.time:6.1f} s"]
        status = sim.task.framing().status
        if status:
            parts.append(status)
        parts.append(f"contacts {sum(int(v) for v in sim.contacts.counts.values())}")
        parts.append(f"x{self.pacer.speed:g}")
        return "   ".join(parts)

    def _flash_contacts(self, pos: NDArray[np.float64]) -> None:
        from pybullet_swarm.metrics.collisions import COLLISION_CLASSES

        events = self.sim.events
        new, self._events_seen = events[self._events_seen :], len(events)
        hit = sorted(
            {
                int(name[5:])
                for e in new
                if e.kind in COLLISION_CLASSES
                for name in (e.a, e.b)
                if name.startswith("agent") and name[5:].isdigit() and int(name[5:]) < len(pos)
            }
        )
        if hit:
            self.world.debug_points(
                pos[hit] + [0.0, 0.0, 0.05],
                [(0.9, 0.05, 0.05)] * len(hit),
                size=14.0,
                lifetime=FLASH_S / self.pacer.speed,
            )

    def _colour_boxes(self) -> None:
        """The task's bodies in their carrier's colour, placed ones green, free ones brown."""
        bodies = self.sim.task.framing().bodies
        if not bodies:
            return
        view = self.sim.task_view
        carrier = np.full(len(bodies), -1)
        holding = np.nonzero((view.carrying >= 0) & (view.carrying < len(bodies)))[0]
        carrier[view.carrying[holding]] = holding
        placed = boxes_of(view).object_state == PLACED
        for i, body in enumerate(bodies):
            c = int(carrier[i])
            rgb = self.colors[c] if c >= 0 else BOX_PLACED if i < len(placed) and placed[i] else BOX_FREE
            if self._box_color.get(i) != rgb:
                self.world.set_color(body, (*rgb, 1.0))
                self._box_color[i] = rgb
