"""Replay frames: frame times, frame size, where agents are drawn, carried boxes, contact flashes, the
heads-up line, the pheromone overlay and the cameras (on synthetic series)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pybullet_swarm.plotting.replay import (
    BOX_FREE,
    LIGHT,
    PheromoneHistory,
    ReplayData,
    ReplayOptions,
    ReplayRenderer,
    View,
    _carried_from_events,
    agent_colors,
    frame_times,
)
from pybullet_swarm.types import Event

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def synthetic(
    *, events: tuple[Event, ...] = (), carried: int = -1, pheromone: PheromoneHistory | None = None
) -> ReplayData:
    """Three agents flying straight along +x over 10 s in a 3 m x 1 m arena; one box (carried by
    ``carried`` from the start, hanging under it), one slot."""
    t = np.arange(0.0, 10.0 + 1e-9, 0.05)
    m = t.size
    start = np.array([[0.5, 0.25, 0.5], [0.5, 0.5, 0.6], [0.5, 0.75, 0.4]])
    pos = start[None] + np.outer(t * 0.2, [1.0, 0.0, 0.0])[:, None, :]  # 0.2 m/s along +x
    box = np.tile([2.0, 0.5, 0.05], (m, 1, 1)).astype(float)
    if carried >= 0:
        box[:, 0] = pos[:, carried] - [0.0, 0.0, 0.07]
    return ReplayData(
        t=t,
        positions=pos,
        quaternions=np.tile(IDENTITY, (m, 3, 1)),
        box_positions=box,
        box_quaternions=np.tile(IDENTITY, (m, 1, 1)),
        box_carried_by=np.full((m, 1), carried, dtype=np.int64),
        box_size=0.1,
        slots=np.array([[2.7, 0.5, 0.05]]),
        targets=np.zeros((0, 3)),
        arena=(3.0, 1.0),
        obstacles=(),
        rotor_xy=0.053 * np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]]) / math.sqrt(2),
        rotor_radius=0.0375,
        events=events,
        pheromone=pheromone,
        title="synthetic",
    )


def close_to(pixel: np.ndarray, rgba: np.ndarray, tol: int = 6) -> bool:
    return bool(np.all(np.abs(pixel.astype(int) - np.round(np.asarray(rgba[:3]) * 255).astype(int)) <= tol))


# ------------------------------------------------------------------------------ frame times
@pytest.mark.parametrize(
    "speed, fps, count, last",
    [(1.0, 25, 251, 10.0), (2.0, 25, 126, 10.0), (4.0, 25, 63, 9.92), (3.0, 25, 84, 9.96), (0.5, 10, 201, 10.0)],
)
def test_frame_count_follows_speed_and_fps(speed: float, fps: int, count: int, last: float) -> None:
    times = frame_times(0.0, 10.0, speed, fps)
    assert times.size == count == math.floor(10.0 * fps / speed + 1e-9) + 1
    assert times[0] == 0.0 and times[-1] == pytest.approx(last)
    assert np.allclose(np.diff(times), speed / fps)
    r = ReplayRenderer(synthetic(), ReplayOptions(view=View.TOP, speed=speed, fps=fps, size=(320, 180)))
    assert r.times().size == count


def test_bad_options_are_refused() -> None:
    for kw in (
        {"size": (321, 180)},
        {"size": (32, 32)},
        {"speed": 0.0},
        {"speed": -1.0},
        {"fps": 0},
        {"view": "sideways"},
    ):
        with pytest.raises(ValueError):
            ReplayOptions(**kw)


@pytest.mark.parametrize("view", list(View))
@pytest.mark.parametrize("size", [(320, 180), (640, 480)])
def test_frame_size_and_type(view: View, size: tuple[int, int]) -> None:
    r = ReplayRenderer(synthetic(), ReplayOptions(view=view, size=size))
    for t in (0.0, 3.3, 10.0):
        frame = r.frame(t)
        assert frame.shape == (size[1], size[0], 3) and frame.dtype == np.uint8
        assert frame.std() > 5.0  # not blank


# ------------------------------------------------------------------------------ where things are drawn
@pytest.mark.parametrize("view", [View.TOP, View.THREE_D])
@pytest.mark.parametrize("t", [0.0, 2.5, 7.0])
def test_agents_are_drawn_where_the_series_puts_them(view: View, t: float) -> None:
    data = synthetic()
    r = ReplayRenderer(data, ReplayOptions(view=view))
    frame = r.frame(t)
    pos = r.state(t)["positions"]
    assert np.allclose(pos, data.positions[int(round(t / 0.05))])
    px, _ = r.camera(t).project(pos)
    colors = agent_colors(3)
    for i in range(3):
        u, v = (int(round(c)) for c in px[i])
        assert close_to(frame[v, u], colors[i]), (i, frame[v, u], colors[i])
    # half-way between two samples the agents are drawn at the interpolated position
    mid = r.state(t + 0.025)["positions"]
    assert np.allclose(mid, 0.5 * (data.positions[int(round(t / 0.05))] + data.positions[int(round(t / 0.05)) + 1]))


def test_top_view_is_to_scale_and_x_runs_right_y_up() -> None:
    r = ReplayRenderer(synthetic(), ReplayOptions(view=View.TOP))
    cam = r.camera(0.0)
    px, _ = cam.project(np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 5.0]]))
    assert px[1, 0] - px[0, 0] == pytest.approx(3.0 * cam.focal)
    assert px[0, 1] - px[2, 1] == pytest.approx(1.0 * cam.focal)  # y up: smaller row index
    assert np.allclose(px[3], px[0])  # orthographic from above
    assert 0.0 < px[0, 0] < px[1, 0] < 1280 and r.hud_px < px[2, 1] < px[0, 1] < 720


def test_chase_camera_looks_at_the_centroid_along_the_heading() -> None:
    data = synthetic()
    r = ReplayRenderer(data, ReplayOptions(view=View.CHASE))
    t = 5.0
    cam = r.camera(t)
    centroid = r.state(t)["positions"].mean(axis=0)
    px, depth = cam.project(centroid[None])
    assert np.allclose(px[0], (640.0, 360.0), atol=1.0) and depth[0] > 1.0
    assert cam.forward[0] == pytest.approx(math.cos(math.radians(30.0)), abs=1e-6)  # flying along +x
    assert r.frame(t).std() > 5.0


def test_orbit_camera_turns_once_per_period() -> None:
    r = ReplayRenderer(synthetic(), ReplayOptions(view=View.ORBIT, speed=1.0))
    a, b = r.camera(0.0), r.camera(6.0)  # 6 s of video at 1x: a quarter of the 24 s period
    assert np.dot(a.right, b.right) == pytest.approx(0.0, abs=1e-9)
    centre = np.array([[1.5, 0.5, 0.0]])
    assert np.allclose(a.project(centre)[0], b.project(centre)[0], atol=1e-6)  # circles the arena's centre


def test_carried_box_is_drawn_with_its_carrier() -> None:
    data = synthetic(carried=1)
    r = ReplayRenderer(data, ReplayOptions(view=View.TOP))
    frame = r.frame(4.0)
    colors = agent_colors(3)
    edges = r.carried.get_edgecolor()
    assert len(r.carried.get_paths()) == 1 and len(r.boxes.get_paths()) == 0  # top view: the top face only
    assert np.allclose(edges[0], colors[1])
    verts = r.carried.get_paths()[0].vertices[:4]
    centre_px = r.camera(4.0).project(r.state(4.0)["positions"][1:2])[0][0]
    assert np.allclose(verts.mean(axis=0), centre_px, atol=0.5)
    # between the body disc and the box's edge, the box's face shows (lit from above)
    u, v = (int(round(c)) for c in centre_px - [0.039 * r.camera(4.0).focal, 0.0])
    lit = np.array(BOX_FREE) * (0.62 + 0.38 * LIGHT[2])
    assert close_to(frame[v, u], lit, tol=8), frame[v, u]
    free = ReplayRenderer(synthetic(carried=-1), ReplayOptions(view=View.THREE_D))
    free.frame(4.0)
    assert len(free.carried.get_paths()) == 0 and len(free.boxes.get_paths()) == 3  # three faces seen


def test_contacts_flash_at_the_pair_then_fade() -> None:
    events = (Event(2.0, "agent_agent", "agent0", "agent1"), Event(6.0, "agent_obstacle", "agent2", "obstacle0"))
    r = ReplayRenderer(synthetic(events=events), ReplayOptions(view=View.TOP))
    r.frame(2.1)
    cam = r.camera(2.1)
    pos = r.state(2.1)["positions"]
    rings = r.rings.get_offsets()
    assert rings.shape == (2, 2)
    assert np.allclose(rings, cam.project(pos[:2])[0])
    assert np.allclose(r.stars.get_offsets()[0], cam.project(pos[:2].mean(axis=0)[None])[0][0])
    assert r.rings.get_edgecolor()[0][3] == pytest.approx(1.0 - 0.1 / r._flash_life)
    r.frame(4.0)
    assert len(r.rings.get_offsets()) == 0
    r.frame(6.0)
    assert np.allclose(r.rings.get_offsets(), cam.project(r.state(6.0)["positions"][2:3])[0])


def test_heads_up_line_counts_time_boxes_and_contacts() -> None:
    events = (
        Event(1.0, "agent_agent", "agent0", "agent1"),
        Event(3.0, "placed", "box0", "slot0"),
        Event(4.0, "agent_box", "agent2", "box0"),
        Event(5.0, "unplaced", "box0", "slot0"),
    )
    r = ReplayRenderer(synthetic(events=events), ReplayOptions(view=View.TOP, speed=2.0))
    assert r.hud_text(0.5) == "t =    0.50 s / 10.0 s   boxes placed 0/1   contacts 0   x2"
    assert "boxes placed 1/1   contacts 1" in r.hud_text(3.5)
    assert "boxes placed 1/1   contacts 2" in r.hud_text(4.5)
    assert "boxes placed 0/1   contacts 2" in r.hud_text(5.0)
    r.frame(3.5)
    assert r._placed_boxes(3.5) == {0} and r._placed_boxes(5.5) == set()


def test_pheromone_field_is_drawn_on_the_floor() -> None:
    values = np.zeros((2, 30, 10), dtype=np.float32)
    values[1, 20, 2] = 1.0  # from t = 5 s, one marked cell at x in [2.0, 2.1], y in [0.2, 0.3]
    ph = PheromoneHistory("task", np.array([0.0, 5.0]), values, 0.1)
    r = ReplayRenderer(synthetic(pheromone=ph), ReplayOptions(view=View.TOP))
    cam = r.camera(0.0)
    u, v = (int(round(c)) for c in cam.project(np.array([[2.05, 0.25, 0.0]]))[0][0])
    before, after = r.frame(4.9)[v, u], r.frame(5.0)[v, u]
    from matplotlib import colormaps

    floor = np.array([0.90, 0.90, 0.87])
    assert close_to(before, floor, tol=3)
    red = np.asarray(colormaps["RdBu_r"](1.0))[:3]  # the largest value: the red end, 80 % opaque
    assert close_to(after, 0.8 * red + 0.2 * floor, tol=3)


def test_carrier_is_read_from_events_for_runs_recorded_without_it() -> None:
    t = np.arange(0.0, 2.0, 0.5)
    events = [
        Event(0.5, "grasp", "agent3", "box1"),
        Event(1.2, "release", "agent3", "box1"),
        Event(1.0, "agent_agent", "agent0", "agent1"),
    ]
    carried = _carried_from_events(t, 2, events)
    assert carried.tolist() == [[-1, -1], [-1, -1], [-1, 3], [-1, -1]]  # the samples after each event
