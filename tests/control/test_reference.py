"""The reference shaper's leash (``sim.reference_leash``): velocity targets do not wind the position reference up."""

from __future__ import annotations

import numpy as np

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
