"""Construction figures are written as non-trivial PNG files."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from pybullet_swarm.metrics.collisions import CollisionClass
from pybullet_swarm.plotting.construction_plots import (
    plot_acceleration,
    plot_box_to_goal,
    plot_collision_timeline,
    plot_nn_distance,
    plot_top_view,
)

MIN_BYTES = 5_000


@dataclasses.dataclass(frozen=True)
class Event:
    time_s: float
    kind: str | CollisionClass
    a: int
    b: int


def _check(path: Path, written: Path) -> None:
    assert written == path
    assert path.stat().st_size > MIN_BYTES
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in path.parent.iterdir() if p.name.startswith(".")] == []  # no temporary left


@pytest.fixture
def run() -> dict[str, np.ndarray]:
    t = np.arange(200) * 0.1
    k = np.arange(5)
    x = 0.3 + 2.4 * (0.5 - 0.5 * np.cos(2 * np.pi * t[:, None] / 20.0 + 0.3 * k))
    y = 0.2 + 0.15 * k + 0.05 * np.sin(t[:, None] + k)
    pos = np.stack([x, np.broadcast_to(y, x.shape), np.full(x.shape, 0.3)], axis=2)  # (200, 5, 3)
    return {"t": t, "pos": pos}


def test_nn_distance_plot(tmp_path: Path, run: dict[str, np.ndarray]) -> None:
    nn = np.abs(np.sin(run["t"][:, None] / 3 + np.arange(5))) * 0.5 + 0.05
    path = tmp_path / "nn.png"
    _check(path, plot_nn_distance(run["t"], nn, 0.15, path))


def test_nn_distance_plot_many_agents(tmp_path: Path, run: dict[str, np.ndarray]) -> None:
    nn = np.random.default_rng(0).uniform(0.05, 0.6, size=(run["t"].size, 30))
    path = tmp_path / "nn_many.png"
    _check(path, plot_nn_distance(run["t"], nn, 0.15, path))


def test_box_to_goal_plot(tmp_path: Path, run: dict[str, np.ndarray]) -> None:
    total = np.maximum(0.0, 20.0 - run["t"])
    path = tmp_path / "box_to_goal.png"
    _check(path, plot_box_to_goal(run["t"], total, path, completion_time=18.5))


def test_top_view_plot(tmp_path: Path, run: dict[str, np.ndarray]) -> None:
    boxes = np.array([[0.15 + 0.12 * (i % 3), 0.35 + 0.12 * (i // 3), 0.05] for i in range(9)])
    slots = np.array([[2.6 + 0.1 * (i % 3), 0.45 + 0.1 * ((i % 6) // 3), 0.05 + 0.1 * (i // 6)] for i in range(9)])
    path = tmp_path / "sub" / "top.png"
    written = plot_top_view(
        run["pos"], (3.0, 1.0), boxes, slots, 0.1, path, obstacles=[(1.5, 0.5, 0.08), (2.0, 0.1, 2.2, 0.3)]
    )
    _check(path, written)


def test_acceleration_plot(tmp_path: Path, run: dict[str, np.ndarray]) -> None:
    acc = np.stack([np.sin(run["t"]), 0.2 * np.cos(run["t"]), 0.05 * np.sin(3 * run["t"])], axis=1)
    path = tmp_path / "acc.png"
    _check(path, plot_acceleration(run["t"], acc, path, agent=2))


def test_collision_timeline_plot(tmp_path: Path) -> None:
    events = [
        Event(1.0, "agent_agent", 0, 1),
        Event(2.5, CollisionClass.AGENT_BOX, 2, 7),
        Event(3.0, "agent_agent", 1, 3),
        Event(4.0, "something_else", 0, 0),
    ]
    path = tmp_path / "collisions.png"
    _check(path, plot_collision_timeline(events, 10.0, path))


def test_collision_timeline_plot_without_events(tmp_path: Path) -> None:
    path = tmp_path / "collisions_none.png"
    _check(path, plot_collision_timeline([], 10.0, path))
