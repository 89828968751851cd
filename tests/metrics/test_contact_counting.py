"""Collision counting from Bullet contacts on constructed encounters."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.metrics.collisions import CollisionClass, ContactTracker


def _two_agents(mode: str):
    return load_scenario(
        "hover",
        {
            "agents.count": 2,
            "agents.start": [[1.0, 1.5, 0.011], [2.0, 1.5, 0.011]],
            "collisions": mode,
            "sim.downwash": False,  # agents crossing level on one line: a wake would part them vertically
            "limits.velocity": 0.3,
            "task.time_limit_s": 100.0,
            "task.waypoints": [{"t_s": 0.0, "position": [0.0, 0.0, 50.0]}],
        },
    )


def _encounter(make_sim, mode: str, half_gap: float):
    """Both agents take off to 1 m, then swap places along x, passing 2 * half_gap apart in y."""
    sim = make_sim(_two_agents(mode))
    start = sim.state.positions.copy()
    sim.set_targets(start * [1, 1, 0] + [0, 0, 1.0])
    sim.step(5 * sim.physics_hz)
    assert sum(sim.contacts.counts.values()) == 0  # take-off from the ground is not a collision
    sim.set_targets(np.array([[1.0, 1.5 + half_gap, 1.0], [2.0, 1.5 - half_gap, 1.0]]))
    sim.step(2 * sim.physics_hz)
    sim.set_targets(np.array([[2.0, 1.5 + half_gap, 1.0], [1.0, 1.5 - half_gap, 1.0]]))
    sim.step(10 * sim.physics_hz)
    return sim


@pytest.mark.parametrize("mode", ["physical", "ghost"])
def test_head_on_swap_is_one_agent_agent_event(make_sim, mode):
    # 12 cm apart in y, the 15 cm airframes overlap by 3 cm: the contact itself pushes them apart
    # sideways. Exactly on one line the way they get past each other is left to rounding, and
    # whether they touch once or twice (apart for just over the 0.1 s debounce) with it.
    sim = _encounter(make_sim, mode, half_gap=0.06)
    assert sim.contacts.counts["agent_agent"] == 1
    assert sim.contacts.time_s["agent_agent"] > 0.0
    assert sum(v for k, v in sim.contacts.counts.items() if k != "agent_agent") == 0
    assert [e.kind for e in sim.all_events()] == ["agent_agent"]
    assert sim.exit_status.value == "running"
    # both got past each other
    assert sim.state.positions[0, 0] > 1.9 and sim.state.positions[1, 0] < 1.1


@pytest.mark.parametrize("mode", ["physical", "ghost"])
def test_passing_30cm_apart_is_no_event(make_sim, mode):
    sim = _encounter(make_sim, mode, half_gap=0.15)
    assert sum(sim.contacts.counts.values()) == 0
    assert sim.contacts.time_s["agent_agent"] == 0.0


def test_ghost_mode_passes_through_and_counts_the_same_overlap(make_sim):
    ghost = _encounter(make_sim, "ghost", half_gap=0.0)
    # in ghost mode nothing deflects them: they cross exactly on the line, overlapping
    assert ghost.contacts.counts["agent_agent"] == 1
    t_overlap = ghost.contacts.time_s["agent_agent"]
    # two 15 cm airframes crossing at a closing speed of 0.6 m/s overlap for about 2 * 0.15 / 0.6 s
    assert t_overlap == pytest.approx(2 * 0.15 / 0.6, rel=0.25)
    assert abs(ghost.state.positions[0, 1] - 1.5) < 0.01


def test_debounce_merges_flicker_and_counts_separate_touches():
    tracker = ContactTracker(lambda a, b: CollisionClass.AGENT_AGENT, dt=0.01, debounce_s=0.1)
    pair = {(1, 2)}
    timeline = [pair, pair, set(), pair, set(), set(), set(), set(), set(), set(), set(), set(), set(), pair]
    events = [tracker.update(p, 0.01 * k) for k, p in enumerate(timeline)]
    assert sum(len(e) for e in events) == 2  # the re-touch after 0.02 s is the same collision
    assert tracker.counts["agent_agent"] == 2
    assert tracker.time_s["agent_agent"] == pytest.approx(0.04)
