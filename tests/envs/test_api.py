"""The two API checkers: Gymnasium's ``check_env`` and PettingZoo's ``parallel_api_test``, warning-free."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test

import pybullet_swarm.envs as envs
from pybullet_swarm.envs import SwarmParallelEnv


def _no_warnings(fn, *args, allow: str = "\0", **kwargs) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fn(*args, **kwargs)
    messages = [str(w.message) for w in caught if "pybullet" not in str(w.filename) and allow not in str(w.message)]
    assert messages == []


@pytest.mark.parametrize("env_id", sorted(envs.ENV_IDS))
@pytest.mark.parametrize("action_type", ["velocity", "waypoint", "rotor_speed"])
def test_check_env_passes(env_id: str, action_type: str) -> None:
    env = gym.make(env_id, action_type=action_type)
    try:
        _no_warnings(check_env, env.unwrapped)
    finally:
        env.close()


def test_check_env_passes_with_si_actions() -> None:
    env = gym.make("pybullet_swarm/Waypoints-v0", action_type="waypoint", normalize_actions=False)
    try:
        assert env.action_space.dtype == np.float64
        # SI units are not a normalised space: the checker's only remark, by design
        _no_warnings(check_env, env.unwrapped, allow="we recommend using a symmetric and normalized space")
    finally:
        env.close()


def test_registered_ids_and_spaces() -> None:
    env = gym.make("pybullet_swarm/Hover-v0")
    try:
        assert env.spec is not None and env.spec.id == "pybullet_swarm/Hover-v0"
        assert env.observation_space.shape == (17,)  # own 14 + goal 3, one agent has no neighbours
        assert env.action_space.shape == (3,)
        rotor = gym.make("pybullet_swarm/Hover-v0", action_type="rotor_speed")
        assert rotor.action_space.shape == (4,)
        assert rotor.unwrapped.dt == pytest.approx(1.0 / 48.0)  # rotor speeds default to the control period
        rotor.close()
    finally:
        env.close()


def test_parallel_api_test_passes_on_the_swarm() -> None:
    env = SwarmParallelEnv("hover_swarm", overrides={"agents.count": 4, "task.time_limit_s": 12.0})
    try:
        _no_warnings(parallel_api_test, env, num_cycles=1000)
    finally:
        env.close()


def test_parallel_api_test_passes_on_construction() -> None:
    env = SwarmParallelEnv("construction", overrides={"task.time_limit_s": 5.0}, action_type="waypoint")
    try:
        assert env.action_space("agent_0").shape == (4,)  # waypoint + gripper
        names = [b["name"] for b in env.layout.describe()]
        assert names == ["own", "neighbours", "boxes", "slots"]
        _no_warnings(parallel_api_test, env, num_cycles=1000)
    finally:
        env.close()


def test_package_imports_without_the_rl_extra() -> None:
    code = (
        "import sys\n"
        "sys.modules['gymnasium'] = None\n"
        "sys.modules['pettingzoo'] = None\n"
        "import pybullet_swarm\n"
        "from pybullet_swarm.experiment.simulation import Simulation\n"
        "try:\n"
        "    import pybullet_swarm.envs\n"
        "except ImportError as exc:\n"
        "    print('HINT', exc)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "HINT" in out.stdout and "pybullet_swarm[rl]" in out.stdout
