"""Range sensors: fan geometry, noise, and batched casting against real Bullet bodies."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.sensing.range import RangeFan, RangeSensor, fan_angles
from pybullet_swarm.world import World


def test_fan_angles() -> None:
    np.testing.assert_allclose(np.degrees(fan_angles(8, 360.0)), np.arange(0, 360, 45))
    np.testing.assert_allclose(np.degrees(fan_angles(5, 90.0)), [-45, -22.5, 0, 22.5, 45])


def test_directions_turn_with_yaw() -> None:
    fan = RangeFan(fan_angles(4, 360.0), 0.5, 0.1)
    d = fan.directions(np.array([np.pi / 2]))
    np.testing.assert_allclose(d[0, 0], [0, 1, 0], atol=1e-12)  # body x now points along world y
    starts, ends = fan.segments(np.array([[1.0, 1.0, 1.0]]), np.zeros(1))
    np.testing.assert_allclose(starts[0], [1.1, 1.0, 1.0])
    np.testing.assert_allclose(ends[0], [1.6, 1.0, 1.0])


def test_readings_against_a_box_and_a_pillar_in_one_batch() -> None:
    with World() as w:
        w.add_box([2.0, 0.0, 1.0], [0.2, 2.0, 2.0])  # wall face at x = 1.9
        w.add_cylinder([0.0, 2.0, 1.0], 0.1, 2.0)  # pillar surface at y = 1.9
        fan = RangeFan(fan_angles(8, 360.0), 0.5, 0.1)
        sensor = RangeSensor(fan, 0.0, np.random.default_rng(0))
        pos = np.array([[1.5, 0.0, 1.0], [0.0, 1.6, 1.0]])
        r = sensor.read(w, pos, np.zeros(2))
    assert r.shape == (2, 8)
    assert r[0, 0] == pytest.approx(1.9 - 1.5 - 0.1, abs=1e-6)  # straight ahead at the wall
    assert r[0, 1] == pytest.approx((0.4 / np.cos(np.pi / 4)) - 0.1, abs=1e-6)  # 45 deg ray
    assert r[0, 4] == pytest.approx(0.5)  # behind: nothing
    assert r[1, 2] == pytest.approx(1.9 - 1.6 - 0.1, abs=1e-6)  # 90 deg ray at the pillar
    assert np.all(sensor.hit_bodies[0, [3, 4, 5]] == -1)


def test_noise_on_hits_only_and_reproducible() -> None:
    class Fake:
        def ray_cast(self, starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            m = len(starts)
            hits = np.where(np.arange(m) % 2 == 0, 7, -1)
            return hits, np.where(hits >= 0, 0.5, 1.0)

    fan = RangeFan(fan_angles(8, 360.0), 1.0, 0.1)
    pos = np.zeros((500, 3))
    a = RangeSensor(fan, 0.02, np.random.default_rng(3)).read(Fake(), pos, np.zeros(500))
    b = RangeSensor(fan, 0.02, np.random.default_rng(3)).read(Fake(), pos, np.zeros(500))
    np.testing.assert_array_equal(a, b)
    hit = a[:, 0::2]
    assert np.all(a[:, 1::2] == 1.0)  # a miss reads the full range
    assert hit.mean() == pytest.approx(0.5, abs=0.003)
    assert hit.std() == pytest.approx(0.02, rel=0.1)
