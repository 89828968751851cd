"""The reference shaper's leash (``sim.reference_leash``): velocity targets do not wind the position reference up."""

from __future__ import annotations

import numpy as np

from pybullet_swarm.control.kernels import braking_speed
from pybullet_swarm.control.reference import ReferenceShaper


def test_the_leash_keeps_a_held_back_agents_reference_within_reach_and_leaves_position_targets_alone():
    dt = 1.0 / 48.0
    shaper = ReferenceShaper(2, np.full(3, 0.15), np.full(3, 1.0), dt)
    start = np.array([[0.0, 0.0, 0.3], [1.0, 0.0, 0.3]])
    shaper.reset(start)
    shaper.set_velocity_targets(np.array([[0.0, 0.0, 0.15], [0.0, 0.0, 0.15]]), np.array([True, False]))
    shaper.set_position_targets(np.array([[0.0, 0.0, 0.3], [1.0, 0.0, 1.3]]), np.array([False, True]))
    held = start.copy()  # both agents pinned where they are (under a wake, against a box)
    for _ in range(96):  # 2 s: unleashed, agent 0's reference runs 0.3 m ahead
        shaper.leash(held, 0.03)
        shaper.step()
    assert abs(shaper.p[0, 2] - held[0, 2]) <= 0.03 + 0.15 * dt + 1e-12  # a tick's motion past the leash at most
    assert shaper.v[0, 2] == 0.15  # the commanded velocity still stands
    free = ReferenceShaper(2, np.full(3, 0.15), np.full(3, 1.0), dt)
    free.reset(start)
    free.set_position_targets(np.array([[0.0, 0.0, 0.3], [1.0, 0.0, 1.3]]), np.array([False, True]))
    for _ in range(96):
        free.step()
    assert shaper.p[1, 2] == free.p[1, 2] > 0.5  # a position target's reference is not leashed


def test_position_targets_arrive_without_overshoot_from_any_start_velocity():
    """The braking curve counts the distance of the tick it sets: across limits, rates, distances and
    start velocities (towards and away from the target), no axis passes its target (the continuous
    curve sqrt(2 a |e|) passed it by ~3 mm at 0.15 m/s and 48 Hz) and each comes to rest on it."""
    rng = np.random.default_rng(7)
    for _ in range(300):
        dt = 1.0 / float(rng.choice([48.0, 100.0, 240.0]))
        vm = float(rng.uniform(0.05, 2.0))
        am = float(rng.uniform(0.2, 10.0))
        dist = float(rng.uniform(0.001, 1.0))
        # towards the target no faster than it can still stop from (half the distance to spare)
        v0 = float(rng.uniform(-vm, min(vm, braking_speed(0.5 * dist, am, dt))))
        shaper = ReferenceShaper(1, np.full(3, vm), np.full(3, am), dt)
        shaper.reset(np.zeros((1, 3)))
        shaper.v[0] = [v0, -v0, 0.0]  # y mirrors x
        shaper.set_position_targets(np.array([[dist, -dist, 0.0]]))
        lo = hi = 0.0
        steps = int((abs(v0) / am + 2.0 * (dist + v0 * v0 / am) / vm + 2.0 * np.sqrt(4.0 * dist / am)) / dt) + 50
        for _ in range(steps):
            shaper.step()
            hi = max(hi, float(shaper.p[0, 0]))
            lo = min(lo, float(shaper.p[0, 1]))
        bound = 1e-9
        assert hi - dist <= bound and -dist - lo <= bound
        assert abs(shaper.p[0, 0] - dist) < 1e-6 and abs(shaper.v[0, 0]) < 1e-6
