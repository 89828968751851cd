"""Watching a run: real-time pacing (with a fake clock), the GUI camera's framing, and that a watched
run is the same run (the viewer steps one control period at a time and changes nothing)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pybullet_swarm.experiment.gui import GUI_ASPECT, GUI_FOV_DEG, GuiViewer, Pacer, agent_rgb
from pybullet_swarm.experiment.runner import _watch
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.types import ExitStatus


class FakeClock:
    """A wall clock that only moves when slept on or advanced."""

    def __init__(self) -> None:
        self.now = 100.0
        self.slept: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.slept.append(seconds)
        self.now += seconds


@pytest.mark.parametrize("speed", [1.0, 2.0, 0.5])
def test_pacer_holds_simulated_time_to_speed_times_the_wall_clock(speed: float) -> None:
    clock = FakeClock()
    pacer = Pacer(speed, clock=clock, sleep=clock.sleep)
    assert pacer.wait(3.0) == 0.0  # the first call anchors the pace
    clock.now += 0.01  # the simulation took 10 ms of wall time
    slept = pacer.wait(3.0 + 1.0 / 48.0)  # one control period later
    assert slept == pytest.approx(1.0 / 48.0 / speed - 0.01)
    assert clock.now == pytest.approx(100.0 + 1.0 / 48.0 / speed)
    for k in range(2, 100):
        pacer.wait(3.0 + k / 48.0)
    assert clock.now == pytest.approx(100.0 + 99.0 / 48.0 / speed)


def test_pacer_does_not_rush_to_catch_up_after_falling_behind() -> None:
    clock = FakeClock()
    pacer = Pacer(1.0, clock=clock, sleep=clock.sleep)
    pacer.wait(0.0)
    clock.now += 2.0  # a slow stretch: 2 s of wall time for 0.1 s simulated
    assert pacer.wait(0.1) == 0.0  # behind by 1.9 s > max_lag_s: re-anchored here
    assert pacer.wait(0.3) == pytest.approx(0.2)  # then paced from the new anchor
    clock.now += 0.1
    assert pacer.wait(0.35) == 0.0  # behind by 0.05 s: tolerated, caught up by the next waits
    assert pacer.wait(0.5) == pytest.approx(0.1)


def test_bad_speeds_are_refused() -> None:
    for speed in (0.0, -1.0, math.inf, math.nan):
        with pytest.raises(ValueError):
            Pacer(speed)


def test_gui_camera_frames_the_arena_and_the_swarm(make_sim) -> None:
    from pybullet_swarm.plotting.replay import perspective

    sim = make_sim(load_scenario("flocking", {"task.time_limit_s": 1.0}))
    viewer = GuiViewer(sim, speed=1.0)
    cam = viewer.camera
    assert cam.pitch == -45.0 and cam.yaw == 0.0  # the long side (x) across the window
    w, h = 1024, 768
    assert w / h == pytest.approx(GUI_ASPECT)
    view = perspective(cam.target, cam.distance, cam.yaw, cam.pitch, (w, h))
    view = type(view)(
        view.eye, view.forward, view.right, view.up, 0.5 * h / math.tan(math.radians(GUI_FOV_DEG / 2)), view.centre
    )
    lx, ly = sim.scenario.arena.size
    corners = np.array([[x, y, z] for x in (0.0, lx) for y in (0.0, ly) for z in (0.0, viewer.height)])
    px, depth = view.project(np.vstack([corners, sim.state_array[:, :3]]))
    assert np.all(depth > 0)
    eps = 1e-6  # the flight volume's corners touch the window's sides
    assert np.all((px[:, 0] >= -eps) & (px[:, 0] <= w + eps) & (px[:, 1] >= -eps) & (px[:, 1] <= h + eps))
    floor = px[[0, 2, 4, 6]]  # the floor spans most of the window's width
    assert floor[:, 0].max() - floor[:, 0].min() > 0.75 * w


def test_watched_run_is_the_same_run(make_sim) -> None:
    sc = load_scenario("construction", {"task.time_limit_s": 1.5})
    plain = make_sim(sc, planner="stigmergy").run()
    watched_sim = make_sim(sc, planner="stigmergy")
    watched = _watch(watched_sim, speed=1e6)
    assert watched.exit_status is plain.exit_status is ExitStatus.TIMEOUT
    assert np.array_equal(watched.timeseries.positions, plain.timeseries.positions)
    assert np.array_equal(watched.timeseries.extra["box_carried_by"], plain.timeseries.extra["box_carried_by"])

    def events(result):
        return [(e.time_s, e.kind, e.a, e.b) for e in result.events]

    assert events(watched) == events(plain)


def test_heads_up_line_and_colours(make_sim) -> None:
    sim = make_sim(load_scenario("construction", {"task.time_limit_s": 1.0}), planner="stigmergy")
    viewer = GuiViewer(sim, speed=2.0)
    assert viewer.hud_text() == "t =    0.0 s   boxes placed 0/9   contacts 0   x2"
    assert viewer.colors == agent_rgb(5) and len(set(viewer.colors)) == 5
    assert len(set(agent_rgb(25))) == 25
    assert sim.world.debug_text("x", (0, 0, 0)) == -1  # DIRECT mode: nothing is drawn
    assert sim.world.debug_points(np.zeros((2, 3)), [(1, 0, 0)] * 2) == -1
