"""Episodes: determinism, identical metrics to ``run``, rewards, collisions and crashes in infos, bad input."""

from __future__ import annotations

import numpy as np
import pytest

import pybullet_swarm as ps
from pybullet_swarm.envs import ActionType, HoverEnv, RewardWeights, SwarmParallelEnv, WaypointsEnv
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.planning.base import Action, CommandKind
from pybullet_swarm.planning.shortest_path import ShortestPath

WALL = ("wall_time_s", "real_time_factor")


def _without_wall_time(m: dict) -> dict:
    return {k: v for k, v in m.items() if k not in WALL}


def _fly_schedule(env: SwarmParallelEnv) -> dict:
    """Drive the env with the scenario's own set-points (what the waypoints planner would command)."""
    infos: dict = {}
    while env.agents:
        targets, _ = env.sim.task.targets(env.sim.time)
        _, _, _, _, infos = env.step({a: targets[i] for i, a in enumerate(env.agents)})
    return infos


# ------------------------------------------------------------------ determinism
def test_same_seed_same_actions_identical_observations() -> None:
    sc = ps.load_scenario("hover_swarm", {"agents.count": 3, "agents.start_jitter": 0.05})
    runs = []
    for _ in range(2):
        env = SwarmParallelEnv(sc)
        rng = np.random.default_rng(7)
        obs, _ = env.reset(seed=11)
        trace = [np.stack([obs[a] for a in env.possible_agents])]
        rewards = []
        for _ in range(15):
            acts = {a: rng.uniform(-1, 1, 3).astype(np.float32) for a in env.agents}
            obs, rew, _, _, _ = env.step(acts)
            trace.append(np.stack([obs[a] for a in env.possible_agents]))
            rewards.append([rew[a] for a in env.possible_agents])
        runs.append((np.stack(trace), np.array(rewards)))
        env.close()
    assert np.array_equal(runs[0][0], runs[1][0])
    assert np.array_equal(runs[0][1], runs[1][1])
    assert not np.array_equal(runs[0][0][0], runs[0][0][-1])  # the agents did move


def test_reset_seed_is_the_run_seed_and_unseeded_resets_follow_the_generator() -> None:
    sc = ps.load_scenario("hover_swarm", {"agents.count": 2, "agents.start_jitter": 0.05})
    env = SwarmParallelEnv(sc)
    try:
        a, _ = env.reset(seed=5)
        assert env.sim.seed == 5
        b, _ = env.reset()
        seed_b = env.sim.seed
        c, _ = env.reset(seed=5)
        assert np.array_equal(a["agent_0"], c["agent_0"])
        d, _ = env.reset()
        assert env.sim.seed == seed_b and np.array_equal(b["agent_0"], d["agent_0"])
        assert not np.array_equal(a["agent_0"][:3], b["agent_0"][:3])  # jittered starts differ by seed
    finally:
        env.close()


# ---------------------------------------------------------- metrics equal `run`
@pytest.mark.parametrize(
    "name,overrides,period",
    [
        ("hover", {}, "planner"),
        ("hover_swarm", {"agents.count": 3, "agents.start_jitter": 0.03}, "control"),
    ],
)
def test_episode_metrics_equal_the_plain_run(name: str, overrides: dict, period: str) -> None:
    sc = ps.load_scenario(name, overrides)
    plain = ps.run(sc, seed=4)
    env = SwarmParallelEnv(sc, action_type="waypoint", normalize_actions=False, period=period)
    try:
        env.reset(seed=4)
        infos = _fly_schedule(env)
        metrics = infos["agent_0"]["metrics"]
        assert metrics["exit_status"] == "completed"
        assert _without_wall_time(metrics) == _without_wall_time(plain.metrics)
        assert env.sim.all_events() == plain.events
        assert infos["agent_0"]["metrics"] is infos[env.possible_agents[-1]]["metrics"]
    finally:
        env.close()


@pytest.mark.slow
def test_construction_episode_with_scripted_grasps_equals_the_plain_run() -> None:
    """The shortest-path baseline as an outside policy (waypoints + gripper) reproduces `run` exactly."""
    sc = ps.load_scenario(
        "construction",
        {
            "agents.count": 2,
            "agents.start": [[0.12, 0.3, 0.011], [0.12, 0.5, 0.011]],
            "task.boxes": [[0.4, 0.3, 0.05], [0.4, 0.5, 0.05]],
            "task.structure": [[1.2, 0.3, 0.05], [1.2, 0.5, 0.05]],
            "task.time_limit_s": 80,
        },
    )
    plain = ps.run(sc, seed=1)
    env = SwarmParallelEnv(sc, action_type="waypoint", normalize_actions=False)
    try:
        env.reset(seed=1)
        policy = ShortestPath()
        policy.reset(env.sim.n, np.random.default_rng(0), env.sim.info)
        total = 0.0
        infos: dict = {}
        while env.agents:
            acts = {}
            for i, cmd in enumerate(policy.plan_all(env.sim.world_view())):
                target = env.sim.shaper.p[i].copy() if cmd.kind == CommandKind.HOLD else cmd.vector
                grip = {Action.GRASP: 1.0, Action.RELEASE: -1.0}.get(cmd.action, 0.0)
                acts[f"agent_{i}"] = np.array([*target, grip])
            _, rew, _, _, infos = env.step(acts)
            total += sum(rew.values())
        metrics = infos["agent_0"]["metrics"]
        assert metrics["exit_status"] == "completed" and metrics["boxes_placed"] == 2
        assert _without_wall_time(metrics) == _without_wall_time(plain.metrics)
        assert env.sim.all_events() == plain.events
        # shared rewards: 2 boxes placed, completion, and the box-to-goal distance gone to ~0
        w = RewardWeights()
        assert total > env.sim.n * (2 * w.box_placed + w.completion)
    finally:
        env.close()


# ---------------------------------------------------------------------- rewards
def _fly(env: HoverEnv, sign: float, steps: int) -> list[float]:
    obs, _ = env.reset(seed=0)
    goal = env.layout.slice("goal")
    rewards = []
    for _ in range(steps):
        g = obs[goal]
        action = sign * g / max(float(np.linalg.norm(g)), 1e-9)
        obs, r, term, trunc, _ = env.step(action.astype(np.float32))
        rewards.append(r)
        if term or trunc:
            break
    return rewards


def test_flying_to_the_waypoint_is_rewarded_and_away_is_punished() -> None:
    env = HoverEnv()
    try:
        towards = _fly(env, +1.0, 15)
        assert sum(towards) > 0.5 and min(towards) >= 0.0
        away = _fly(env, -1.0, 15)  # away from a set-point 1 m above: into the ground, then sideways
        assert sum(away) < 0.0
    finally:
        env.close()


def test_goal_progress_rewards_telescope_to_the_distance_covered() -> None:
    """With one fixed set-point, the summed goal-progress reward is d(start) - d(end) exactly."""
    env = HoverEnv(rewards={"completion": 0.0})
    try:
        obs, _ = env.reset(seed=0)
        d0 = float(np.linalg.norm(env.sim.task.points[0, 0] - env.sim.state_array[0, :3]))
        total, info = 0.0, {}
        for _ in range(40):
            obs, r, term, trunc, info = env.step(np.array([0.0, 0.0, 1.0], dtype=np.float32))
            total += r
        d_end = float(np.linalg.norm(env.sim.task.points[0, 0] - env.sim.state_array[0, :3]))
        assert total == pytest.approx(d0 - d_end, abs=1e-9)
        assert info["goal_distance_m"] == pytest.approx(d_end)
    finally:
        env.close()


def test_completion_terminates_in_the_step_that_completes() -> None:
    env = HoverEnv(action_type="waypoint", normalize_actions=False)
    try:
        env.reset(seed=0)
        target = env.sim.task.points[0, 0].copy()
        steps, term, trunc, info = 0, False, False, {}
        while not (term or trunc):
            _, r, term, trunc, info = env.step(target)
            steps += 1
        assert term and not trunc
        assert info["metrics"]["exit_status"] == "completed"
        # judged at the tick that ends the step: the run ends exactly where this step ended
        assert env.sim.time == pytest.approx(steps * env.dt)
        assert info["metrics"]["completion_time_s"] == pytest.approx(env.sim.time)
        assert r >= RewardWeights().completion - 0.1
        with pytest.raises(RuntimeError):
            env.step(target)
    finally:
        env.close()


def test_time_limit_truncates() -> None:
    env = HoverEnv(overrides={"task.time_limit_s": 1.0})
    try:
        env.reset(seed=0)
        steps, term, trunc, info = 0, False, False, {}
        while not (term or trunc):
            _, _, term, trunc, info = env.step(env.neutral_action())
            steps += 1
        assert trunc and not term and steps == 10
        assert info["metrics"]["exit_status"] == "timeout" and info["episode"]["length"] == 10
    finally:
        env.close()


# --------------------------------------------------------- collisions and crash
def _collision_env(penalty: float) -> SwarmParallelEnv:
    sc = ps.load_scenario(
        "hover_swarm", {"agents.count": 2, "agents.start": [[1.0, 1.0, 1.0], [1.4, 1.0, 1.0]], "collisions": "physical"}
    )
    return SwarmParallelEnv(
        sc,
        action_type="waypoint",
        normalize_actions=False,
        rewards={"collision_penalty": penalty, "goal_progress": 0.0},
    )


def test_a_collision_shows_in_infos_and_in_the_reward() -> None:
    runs = {}
    for penalty in (0.0, 2.5):
        env = _collision_env(penalty)
        env.reset(seed=0)
        mid = np.array([1.2, 1.0, 1.0])
        log = []
        for _ in range(40):
            _, rew, _, _, infos = env.step({a: mid for a in env.agents})
            log.append((rew, infos))
            if not env.agents:
                break
        runs[penalty] = log
        env.close()
    hits = [(k, info) for k, (_, info) in enumerate(runs[2.5]) if info["agent_0"]["collisions"]]
    assert hits, "the agents never touched"
    k, info = hits[0]
    ev = info["agent_0"]["collisions"][0]
    assert ev["kind"] == "agent_agent" and {ev["a"], ev["b"]} == {"agent0", "agent1"}
    assert info["agent_1"]["collisions"] == info["agent_0"]["collisions"]
    assert info["agent_0"]["metrics"]["collisions"]["agent_agent"] >= 1
    for agent in ("agent_0", "agent_1"):
        n_events = len(runs[2.5][k][1][agent]["collisions"])
        assert runs[2.5][k][0][agent] == pytest.approx(runs[0.0][k][0][agent] - 2.5 * n_events)


def test_a_crash_terminates_and_is_penalised() -> None:
    env = HoverEnv(
        overrides={"agents.start": [[1.5, 1.5, 1.5]]},
        action_type=ActionType.ROTOR_SPEED,
        normalize_actions=False,
        rewards={"goal_progress": 0.0, "crash_penalty": 7.0},
    )
    try:
        env.reset(seed=0)
        term, r, info = False, 0.0, {}
        for _ in range(200):
            _, r, term, trunc, info = env.step(np.zeros(4))  # rotors off: free fall from 1.5 m
            if term or trunc:
                break
        assert term and info["metrics"]["exit_status"] == "crashed"
        assert [e["kind"] for e in info["collisions"]] == ["agent_ground"]  # the impact itself is a contact
        assert r == pytest.approx(-7.0 - RewardWeights().collision_penalty)
    finally:
        env.close()


# -------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "kwargs,field",
    [
        ({"action_type": "rotor"}, "env.action_type"),
        ({"period": 0.1}, "env.period"),
        ({"rewards": {"collision": 1.0}}, "env.rewards.collision"),
        ({"rewards": {"crash_penalty": -1.0}}, "env.rewards.crash_penalty"),
        ({"neighbours": -1}, "env.neighbours"),
        ({"render_mode": "human"}, "env.render_mode"),
        ({"unknown_option": 1}, "env.unknown_option"),
    ],
)
def test_bad_options_are_one_line_config_errors(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError) as err:
        SwarmParallelEnv("hover_swarm", **kwargs)
    msg = str(err.value)
    assert msg.startswith(f"hover_swarm.yaml: {field}: ") and "\n" not in msg


def test_single_agent_envs_refuse_swarms_and_other_tasks() -> None:
    with pytest.raises(ConfigError, match=r"^hover_swarm.yaml: agents.count: must be 1"):
        WaypointsEnv("hover_swarm")
    with pytest.raises(ConfigError, match=r"^construction_single.yaml: task.kind: must be 'waypoints'"):
        WaypointsEnv("construction_single")


# ---------------------------------------------------------------------- render
def test_rgb_array_render_from_direct_mode() -> None:
    env = HoverEnv(render_mode="rgb_array", render_size=[160, 90])
    try:
        env.reset(seed=0)
        frame = env.render()
        assert isinstance(frame, np.ndarray) and frame.shape == (90, 160, 3) and frame.dtype == np.uint8
        assert frame.reshape(-1, 3).std(axis=0).max() > 1.0  # not a blank image
    finally:
        env.close()
