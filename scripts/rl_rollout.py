#!/usr/bin/env python3
"""Roll out the swarm environment with a scripted or a random policy and print the episode metrics.

Nothing is trained (no learning library is needed beyond the ``rl`` extra). The scripted policy
flies every agent towards its active set-point (the ``goal`` block of its observation) with
velocity actions; the random policy samples the action spaces.

    python scripts/rl_rollout.py                                   # hover_swarm, scripted policy
    python scripts/rl_rollout.py --policy random --episodes 2 --seed 3
    python scripts/rl_rollout.py --scenario hover --set agents.count=1 --json metrics.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from pybullet_swarm.envs import SwarmParallelEnv
from pybullet_swarm.errors import ConfigError


def scripted_actions(env: SwarmParallelEnv, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Velocity towards the active set-point, slowing down within 0.3 m of it (normalised actions)."""
    goal = env.layout.slice("goal")
    out = {}
    for a in env.agents:
        g = obs[a][goal].astype(float)
        out[a] = np.clip(g / 0.3, -1.0, 1.0).astype(np.float32)
    return out


def rollout(env: SwarmParallelEnv, policy: str, seed: int) -> tuple[dict[str, Any], dict[str, float]]:
    """One episode; returns the final metrics and the return of each agent."""
    obs, infos = env.reset(seed=seed)
    for a in env.possible_agents:  # the random policy's own generator, derived from the seed
        env.action_space(a).seed(seed + int(a.rsplit("_", 1)[1]))
    returns = dict.fromkeys(env.possible_agents, 0.0)
    while env.agents:
        if policy == "random":
            actions = {a: env.action_space(a).sample() for a in env.agents}
        else:
            actions = scripted_actions(env, obs)
        obs, rewards, _, _, infos = env.step(actions)
        for a, r in rewards.items():
            returns[a] += r
    return infos[env.possible_agents[0]]["metrics"], returns


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="hover_swarm", help="scenario name or YAML path (a waypoints task)")
    ap.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scenario override, repeatable",
    )
    ap.add_argument("--policy", choices=("scripted", "random"), default="scripted")
    ap.add_argument("--episodes", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0, help="seed of the first episode (then seed+1, ...)")
    ap.add_argument("--json", type=Path, default=None, metavar="FILE", help="write the episodes' metrics as JSON")
    args = ap.parse_args(argv)
    try:
        env = SwarmParallelEnv(args.scenario, overrides=args.overrides, action_type="velocity")
    except ConfigError as exc:
        print(f"rl_rollout: error: {exc}", file=sys.stderr)
        return 2
    if args.policy == "scripted" and not any(b == "goal" for b, _, _ in env.layout.blocks):
        print(
            "rl_rollout: error: the scripted policy needs a waypoints scenario (observations with a goal block)",
            file=sys.stderr,
        )
        return 2
    episodes = []
    try:
        for k in range(args.episodes):
            metrics, returns = rollout(env, args.policy, args.seed + k)
            episodes.append({"seed": args.seed + k, "returns": returns, "metrics": metrics})
            mean_return = float(np.mean(list(returns.values())))
            print(
                f"episode {k} seed {args.seed + k}: {metrics['exit_status']} after {metrics['sim_time_s']:.1f} s, "
                f"mean return {mean_return:.3f}, collisions {sum(metrics['collisions'].values())}, "
                f"tracking rmse {metrics.get('tracking_rmse_m', float('nan')):.3f} m, "
                f"min separation {metrics.get('min_separation_m', float('nan')):.3f} m"
            )
    finally:
        env.close()
    if args.json is not None:
        args.json.write_text(json.dumps(episodes, indent=2, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
