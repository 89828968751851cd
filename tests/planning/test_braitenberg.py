"""Braitenberg avoidance: turns away from obstacles left and right, resolves the head-on case, hysteresis."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.planning.braitenberg import Braitenberg, BraitenbergParams
from pybullet_swarm.sensing.range import fan_angles

ANGLES = fan_angles(8, 360.0)  # 0, 45, ..., 315 deg
R = 0.5
VMAX = np.full(3, 0.3)


def _rule(**kw: float) -> Braitenberg:
    return Braitenberg(BraitenbergParams(**kw), ANGLES, R, VMAX, 1)


def _readings(**hits: float) -> np.ndarray:
    """Readings (1, 8) m: every ray free except those given by bearing in degrees (e.g. d45=0.2)."""
    r = np.full((1, 8), R)
    for key, dist in hits.items():
        r[0, int(key[1:]) // 45] = dist
    return r


PREF = np.array([[0.2, 0.0, 0.0]])  # flying +x


def test_obstacle_on_the_left_pushes_right_and_vice_versa() -> None:
    v, active = _rule().step(_readings(d45=0.15), np.zeros(1), PREF, PREF)
    assert active[0] and v[0, 1] < -0.05  # left-front obstacle: to the right (-y)
    v, active = _rule().step(_readings(d315=0.15), np.zeros(1), PREF, PREF)
    assert active[0] and v[0, 1] > 0.05  # right-front obstacle: to the left (+y)
    assert v[0, 0] < PREF[0, 0]  # and it brakes


def test_heading_frame_follows_the_preferred_velocity() -> None:
    # flying +y, an obstacle at world bearing 135 deg is front-left of the heading: push to +x (its right)
    pref = np.array([[0.0, 0.2, 0.0]])
    v, active = _rule().step(_readings(d135=0.15), np.zeros(1), pref, pref)
    assert active[0] and v[0, 0] > 0.05


def test_free_readings_pass_the_command() -> None:
    v, active = _rule().step(_readings(), np.zeros(1), PREF, PREF)
    assert not active[0]


def test_hysteresis_between_the_thresholds() -> None:
    rule = _rule(on_threshold=0.5, off_threshold=0.2, reaction_time=0.0, memory_s=0.0)  # raw readings
    mid = R * (1 - 0.35)  # activation 0.35: between the thresholds
    assert not rule.step(_readings(d45=mid), np.zeros(1), PREF, PREF)[1][0]  # not on yet
    assert rule.step(_readings(d45=0.1), np.zeros(1), PREF, PREF)[1][0]  # on
    assert rule.step(_readings(d45=mid), np.zeros(1), PREF, PREF)[1][0]  # stays on
    assert not rule.step(_readings(d45=R * 0.9), np.zeros(1), PREF, PREF)[1][0]  # off below 0.2


def test_symmetric_head_on_correction_grows_with_memory_and_fades() -> None:
    rule = _rule()
    wall = _readings(d0=0.15, d45=0.25, d315=0.25)  # a wall straight ahead: left and right cancel
    side = []
    for _ in range(4):
        v, active = rule.step(wall, np.zeros(1), PREF, PREF)
        assert active[0]
        side.append(v[0, 1])
    assert side[0] < 0 and side[1] < side[0] and side[2] < side[1]  # to the right, more each tick
    c = rule.correction[0]
    rule.step(_readings(d45=0.3), np.zeros(1), PREF, PREF)  # no longer symmetric
    assert rule.correction[0] == pytest.approx(0.5 * c)


def _pillar_readings(p: np.ndarray, centre: np.ndarray, radius: float, offset: float) -> np.ndarray:
    """Exact readings of one agent at p (2,) of a pillar (ray-circle intersection)."""
    out = np.full((1, 8), R)
    for k, a in enumerate(ANGLES):
        d = np.array([np.cos(a), np.sin(a)])
        s = p + offset * d
        m = s - centre
        b = m @ d
        c = m @ m - radius * radius
        disc = b * b - c
        if disc >= 0:
            t = -b - np.sqrt(disc)
            if 0 <= t <= R:
                out[0, k] = t
    return out


@pytest.mark.parametrize("dy", [0.0, 0.05, -0.05])
def test_kinematic_agent_passes_a_pillar_head_on_and_off_axis(dy: float) -> None:
    """A kinematic agent flying +x at a pillar on its axis (or just off it) passes it without touching."""
    centre, radius, body = np.array([1.5, dy]), 0.15, 0.106
    rule = Braitenberg(BraitenbergParams(), ANGLES, R, VMAX, 1, offset=body)
    p = np.array([0.0, 0.0])
    dt = 0.1
    closest = np.inf
    vel = np.zeros(2)
    for _ in range(300):
        readings = _pillar_readings(p, centre, radius, body)
        to_goal = np.array([3.0, 0.0]) - p  # a waypoint beyond the pillar
        pref = 0.2 * to_goal / np.linalg.norm(to_goal)
        v, active = rule.step(
            readings, np.zeros(1), np.array([[*vel, 0.0]]), np.array([[*pref, 0.0]]), positions=np.array([[*p, 1.0]])
        )
        vel = v[0, :2] if active[0] else pref
        p = p + dt * vel
        closest = min(closest, np.linalg.norm(p - centre) - radius)
    assert closest > body  # never touched
    assert p[0] > 2.5  # and got past it


BODY = 0.106  # m, the rays' start offset (a quad150's enclosing radius)
AT_REST = np.zeros((1, 3))
HERE = np.array([[0.0, 0.0, 1.0]])


def _memory_rule(**kw: float) -> Braitenberg:
    return Braitenberg(BraitenbergParams(**kw), ANGLES, R, VMAX, 1, offset=BODY)


@pytest.mark.parametrize("memory_s", [2.0, 0.0])
def test_an_obstacle_that_slips_between_two_rays_is_remembered(memory_s: float) -> None:
    """The failure of flocking seed 3 and formation seed 3: an echo seen ahead, then lost between two
    rays when the agent turned, made the layer hand back to a planner that flew into it."""
    rule = _memory_rule(memory_s=memory_s)
    assert rule.step(_readings(d0=0.12), np.zeros(1), AT_REST, PREF, positions=HERE)[1][0]  # ahead: takes over
    # yawed by 22.5 deg: the rays now point at +-22.5 deg, the point 0.23 m ahead lies between two of them
    v, active = rule.step(_readings(), np.array([np.pi / 8]), AT_REST, PREF, positions=HERE)
    if memory_s > 0.0:
        assert active[0] and v[0, 0] < PREF[0, 0]  # still avoiding: brakes
    else:
        assert not active[0]  # without memory: handed back, flies on into it


def test_a_remembered_point_is_dropped_when_a_ray_sees_through_it() -> None:
    rule = _memory_rule()
    rule.step(_readings(d0=0.12), np.zeros(1), AT_REST, PREF, positions=HERE)
    assert rule.remembered.any()
    rule.step(_readings(), np.zeros(1), AT_REST, PREF, positions=HERE)  # ray 0 now free past the point
    assert not rule.remembered.any()


def test_a_fast_agent_takes_over_earlier_than_a_slow_one() -> None:
    ahead = _readings(d0=0.4)  # raw activation 0.2: below on_threshold 0.3
    assert not _memory_rule().step(ahead, np.zeros(1), AT_REST, PREF, positions=HERE)[1][0]
    fast = np.array([[0.4, 0.0, 0.0]])  # stopping distance 0.4 * 0.3 + 0.4^2 / 2 = 0.2 m
    assert _memory_rule().step(ahead, np.zeros(1), fast, PREF, positions=HERE)[1][0]


def test_a_mates_echo_weighs_only_when_it_is_about_to_be_touched() -> None:
    reading = 0.25  # an obstacle this close ahead-left takes over
    assert _memory_rule().step(_readings(d45=reading), np.zeros(1), AT_REST, PREF, positions=HERE)[1][0]
    d = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0])
    mate = HERE + (BODY + reading + 0.08) * d  # a flock mate's centre just behind that echo
    v, active = _memory_rule().step(
        _readings(d45=reading),
        np.zeros(1),
        AT_REST,
        PREF,
        positions=HERE,
        neighbour_positions=mate[None],
        neighbour_velocities=np.zeros((1, 1, 3)),
    )
    assert not active[0]  # the planner's separation deals with it
    rule = _memory_rule()
    near = HERE + 0.25 * np.array([[np.cos(np.pi / 8), np.sin(np.pi / 8), 0.0]])  # between two rays
    v, active = rule.step(
        _readings(),
        np.zeros(1),
        AT_REST,
        PREF,
        positions=HERE,
        neighbour_positions=near[None],
        neighbour_velocities=np.zeros((1, 1, 3)),
    )
    assert active[0] and v[0, 0] < PREF[0, 0]  # no ray sees it, 0.04 m from touching: brake
    assert not rule.remembered.any()  # and a mate is never remembered
