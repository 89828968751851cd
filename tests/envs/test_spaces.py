"""The documented observation layout and the action mapping, against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pybullet_swarm as ps
from pybullet_swarm.envs import SwarmParallelEnv


def test_own_block_and_neighbours_of_a_known_grid() -> None:
    # 4 cf2x agents on a 2 x 2 grid 0.4 m apart: each sees two at 0.4 m and one at 0.4 sqrt(2) m
    sc = ps.load_scenario("hover_swarm", {"agents.count": 4, "agents.spacing": 0.4})
    env = SwarmParallelEnv(sc, neighbours=3)
    try:
        obs, _ = env.reset(seed=0)
        lay = env.layout
        o = obs["agent_0"].astype(float)
        own = o[lay.slice("own")]
        starts = env.sim.starts
        assert np.allclose(own[0:3], starts[0], atol=1e-6)
        assert np.allclose(own[3:12], 0.0, atol=1e-6)  # at rest, level, no rates
        assert own[12] == 0.0 and own[13] == 0.0  # not carrying, t = 0
        nb = o[lay.slice("neighbours")].reshape(3, 7)
        dist = np.linalg.norm(nb[:, :3], axis=1)
        assert np.allclose(dist, [0.4, 0.4, 0.4 * math.sqrt(2)], atol=1e-6)
        assert np.all(nb[:, 6] == 1.0)
        expected = {tuple(np.round(starts[j] - starts[0], 6)) for j in (1, 2, 3)}
        assert {tuple(np.round(v, 6)) for v in nb[:, :3]} == expected
        goal = o[lay.slice("goal")]
        assert np.allclose(goal, env.sim.task.points[0, 0] - starts[0], atol=1e-6)
    finally:
        env.close()


def test_neighbours_outside_the_sensing_radius_are_absent() -> None:
    sc = ps.load_scenario("hover_swarm", {"agents.count": 4, "agents.spacing": 0.4, "agents.sensing_radius": 0.45})
    env = SwarmParallelEnv(sc, neighbours=3)
    try:
        obs, _ = env.reset(seed=0)
        nb = obs["agent_0"][env.layout.slice("neighbours")].reshape(3, 7)
        assert nb[:, 6].tolist() == [1.0, 1.0, 0.0]  # the diagonal one is out of range
        assert np.all(nb[2] == 0.0)
    finally:
        env.close()


def test_construction_observes_boxes_and_slots_in_view() -> None:
    env = SwarmParallelEnv("construction", boxes=2, slots=2)
    try:
        obs, _ = env.reset(seed=0)
        lay = env.layout
        assert lay.slice("boxes").stop - lay.slice("boxes").start == 8
        sim = env.sim
        c = sim.task
        pos = sim.state_array[:, :3]
        seen_any = False
        for i, a in enumerate(env.possible_agents):
            rel = c.positions - pos[i]
            in_view = c.in_view(rel + [0.0, 0.0, c.grasp_height])
            block = obs[a][lay.slice("boxes")].reshape(2, 4)
            expected = rel[in_view][np.argsort(np.einsum("ij,ij->i", rel[in_view], rel[in_view]))][:2]
            assert int(block[:, 3].sum()) == len(expected)  # exactly the boxes in view, nearest first
            assert np.allclose(block[: len(expected), :3], expected, atol=1e-6)
            seen_any |= len(expected) > 0
            # the structure (x = 2.7 m) is far from the depot edge where the agents start
            assert np.all(obs[a][lay.slice("slots")] == 0.0)
        # agents start 0.28 m in front of the depot's first row: in the thesis's max-norm view
        # (the nearest box's grasp point within view radius + grasp height on every axis)
        assert seen_any
        assert env.observation_space("agent_0").contains(obs["agent_0"])
    finally:
        env.close()


def test_normalised_waypoints_map_onto_the_arena() -> None:
    env = SwarmParallelEnv("hover_swarm", overrides={"agents.count": 1}, action_type="waypoint", waypoint_ceiling=3.0)
    try:
        m = env._episode.mapper
        cmd, grip = m.to_physical(np.array([[0.0, -1.0, 1.0]]))
        assert grip is None
        assert np.allclose(cmd, [[10.0, 0.0, 3.0]])  # 20 m x 20 m arena, 3 m ceiling
        cmd, _ = m.to_physical(np.array([[5.0, -5.0, 0.0]]))  # out of range: clipped
        assert np.allclose(cmd, [[20.0, 0.0, 1.5]])
        env.reset(seed=0)
        hold = env.neutral_actions()["agent_0"]
        back, _ = m.to_physical(hold[None, :])
        assert np.allclose(back[0], env.sim.state_array[0, :3], atol=1e-5)
    finally:
        env.close()


@pytest.mark.parametrize("normalize", [True, False])
def test_rotor_actions_centre_on_hover(normalize: bool) -> None:
    env = SwarmParallelEnv(
        "hover_swarm",
        overrides={"agents.count": 1},
        action_type="rotor_speed",
        normalize_actions=normalize,
        rotor_span=0.2,
    )
    try:
        m = env._episode.mapper
        w_hover = env.sim.params.hover_rotor_speed(env.sim.scenario.sim.gravity)
        if normalize:
            cmd, _ = m.to_physical(np.array([[0.0, 1.0, -1.0, 0.5]]))
            assert np.allclose(cmd, [[w_hover, 1.2 * w_hover, 0.8 * w_hover, 1.1 * w_hover]])
        else:
            cmd, _ = m.to_physical(np.array([[w_hover, 1e9, -5.0, 0.0]]))
            assert np.allclose(cmd, [[w_hover, env.sim.params.max_rotor_speed, 0.0, 0.0]])
    finally:
        env.close()


def test_gripper_column_thresholds() -> None:
    env = SwarmParallelEnv("construction", action_type="velocity")
    try:
        m = env._episode.mapper
        acts = np.zeros((5, 4))
        acts[:, 3] = [1.0, 0.6, 0.4, -0.6, -1.0]
        _, grip = m.to_physical(acts)
        assert grip.tolist() == [1, 1, 0, 2, 2]  # GRASP, GRASP, NONE, RELEASE, RELEASE
    finally:
        env.close()


def test_missing_agents_hold_and_unknown_agents_are_refused() -> None:
    env = SwarmParallelEnv(
        "hover_swarm", overrides={"agents.count": 2}, action_type="waypoint", normalize_actions=False
    )
    try:
        env.reset(seed=0)
        start = env.sim.state_array[:, :3].copy()
        for _ in range(10):
            env.step({"agent_0": start[0] + [0.0, 0.0, 0.5]})
        assert np.linalg.norm(env.sim.state_array[1, :3] - start[1]) < 0.05  # agent_1 held where it was
        assert env.sim.state_array[0, 2] > start[0, 2] + 0.3
        with pytest.raises(KeyError, match="unknown agent"):
            env.step({"agent_7": start[0]})
    finally:
        env.close()
