"""Collision counting from Bullet contacts on constructed encounters."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.metrics.collisions import CollisionClass, ContactTracker
from pybullet_swarm.rng import named_rng


def _two_agents(mode: str, contact_hz: int | None = None):
    return load_scenario(
        "hover",
        {
            "sim.contact_hz": contact_hz,
            "agents.count": 2,
            "agents.start": [[1.0, 1.5, 0.011], [2.0, 1.5, 0.011]],
            "collisions": mode,
            "sim.downwash": False,  # agents crossing level on one line: a wake would part them vertically
            "limits.velocity": 0.3,
            "task.time_limit_s": 100.0,
            "task.waypoints": [{"t_s": 0.0, "position": [0.0, 0.0, 50.0]}],
        },
    )


def _encounter(make_sim, mode: str, half_gap: float, contact_hz: int | None = None):
    """Both agents take off to 1 m, then swap places along x, passing 2 * half_gap apart in y."""
    sim = make_sim(_two_agents(mode, contact_hz))
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


class _EagerTracker:
    """The tracker as first written: every touching pair's last sighting and contact time updated every
    update. ``ContactTracker`` keeps a pair's last sighting when it stops touching and loops over the pairs
    that count only; it must count and time exactly as this does."""

    def __init__(self, classify, dt: float, debounce_s: float) -> None:
        self.classify, self.dt, self.debounce_s = classify, dt, debounce_s
        self.counts = {c.value: 0 for c in CollisionClass}
        self.time_s = {c.value: 0.0 for c in CollisionClass}
        self._active: dict = {}
        self._last_seen: dict = {}
        self._prev: frozenset | set = frozenset()

    def update(self, pairs, t):
        events = []
        if pairs != self._prev:
            for pair in pairs - self._prev:
                cls = self._active[pair] = self.classify(*pair)
                if cls is None:
                    continue
                last = self._last_seen.get(pair)
                if last is None or t - last >= self.debounce_s - 1e-12:
                    self.counts[cls.value] += 1
                    events.append((cls, pair[0], pair[1]))
            for pair in self._prev - pairs:
                self._active.pop(pair, None)
            self._prev = pairs
        for pair, cls in self._active.items():
            self._last_seen[pair] = t
            if cls is not None:
                self.time_s[cls.value] += self.dt
        return events

    def reclassify_all(self):
        for pair in self._active:
            self._active[pair] = self.classify(*pair)


def test_tracker_counts_and_times_as_one_that_updates_every_pair_every_step():
    """Random flickering contacts of 6 bodies over 3,000 steps, the classes of pairs changing now and then
    (a body taking a load's role): the same events, counts and contact times as the eager tracker."""
    rng = named_rng(7, "test/contact_tracker")
    loads: set[int] = set()

    def classify(a: int, b: int):
        if a in loads or b in loads:
            return CollisionClass.LOAD_BOX
        return CollisionClass.AGENT_AGENT if (a + b) % 3 else None

    pairs_all = [(a, b) for a in range(6) for b in range(a + 1, 6)]
    lazy = ContactTracker(classify, dt=1 / 240, debounce_s=0.1)
    eager = _EagerTracker(classify, dt=1 / 240, debounce_s=0.1)
    touching: set[tuple[int, int]] = set()
    n_events = 0
    for k in range(3000):
        t = k / 240
        for pair in pairs_all:  # each pair touches for a few steps to a few tenths of a second at a time
            if rng.random() < (0.05 if pair in touching else 0.01):
                touching ^= {pair}
        if rng.random() < 0.005:  # a role changes between steps, as a grasp or release does at a planner tick
            loads ^= {int(rng.integers(6))}
            lazy.reclassify_all()
            eager.reclassify_all()
        if touching or lazy._prev:
            now = frozenset(touching)
            got, expected = lazy.update(now, t), eager.update(now, t)
            assert got == expected
            n_events += len(got)
    assert lazy.counts == eager.counts and lazy.time_s == eager.time_s
    assert n_events > 100 and lazy.counts["load_box"] > 0 and lazy.counts["agent_agent"] > 0


@pytest.mark.parametrize(
    ("mode", "half_gap"), [("ghost", 0.0), ("ghost", 0.06), ("physical", 0.06), ("ghost", 0.15), ("physical", 0.15)]
)
def test_contacts_read_at_the_control_rate_count_the_same_encounters(make_sim, mode, half_gap):
    """Read once per control period (48 Hz, about 21 ms) instead of every physics step: the same events of the
    same classes, each at most one period later, and contact time within one period of it per event. (Not
    asserted: physical agents meeting exactly on one line touch a second time, 0.87 s later, for less than a
    period; every step counts it, the control rate here missed it.)"""
    every = _encounter(make_sim, mode, half_gap)
    coarse = _encounter(make_sim, mode, half_gap, contact_hz=48)
    period = 1.0 / 48
    assert coarse.contacts.counts == every.contacts.counts
    a, b = every.all_events(), coarse.all_events()
    assert [e.kind for e in a] == [e.kind for e in b]
    assert all(0.0 <= eb.time_s - ea.time_s < period + 1e-9 for ea, eb in zip(a, b))
    n = sum(every.contacts.counts.values())
    for cls, t in every.contacts.time_s.items():
        assert coarse.contacts.time_s[cls] == pytest.approx(t, abs=n * period + 1e-9)


def test_incidents_count_events_that_share_a_unit_within_the_window_once():
    """An incident is a chain of contact events with onsets at most the window apart that share a unit; static
    bodies are no units, so two agents touching the ground at once are two incidents."""
    from pybullet_swarm.metrics.collisions import IncidentCounter

    inc = IncidentCounter(0.1)
    assert inc.add(1.0, ("agent0", "agent1"))  # agent-agent
    assert not inc.add(1.05, ("agent0",))  # its carried box hits the ground (counted as agent0): same incident
    assert not inc.add(1.09, ("agent1", "box3"))  # agent1 again within the window: same incident
    assert not inc.add(1.17, ("box3",))  # chained: within the window of box3's event, 0.17 s after the first
    assert inc.add(1.25, ("agent1",))  # later than the window after agent1's last event: a new one
    assert inc.add(1.25, ("agent2",))  # at once, but nothing shared
    assert inc.add(1.26, ())  # a body with the arena alone shares nothing
    assert inc.count == 4
