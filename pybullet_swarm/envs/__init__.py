"""Learning interfaces: a PettingZoo parallel environment for the swarm, Gymnasium environments for one agent.

Needs the ``rl`` extra (``pip install "pybullet_swarm[rl]"``: gymnasium, pettingzoo). Importing
this package registers ``pybullet_swarm/Hover-v0`` and ``pybullet_swarm/Waypoints-v0``::

    import gymnasium as gym
    import pybullet_swarm.envs                      # registers the ids
    env = gym.make("pybullet_swarm/Hover-v0", action_type="velocity")

    from pybullet_swarm.envs import SwarmParallelEnv
    env = SwarmParallelEnv("construction", action_type="waypoint")
    obs, infos = env.reset(seed=0)
"""

from __future__ import annotations

try:
    import gymnasium
    import pettingzoo  # noqa: F401
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ImportError(
        "pybullet_swarm.envs needs the 'rl' extra (gymnasium, pettingzoo): pip install 'pybullet_swarm[rl]'"
    ) from exc

from pybullet_swarm.envs.actions import ActionMapper
from pybullet_swarm.envs.config import ActionType, EnvConfig, RewardWeights, StepPeriod
from pybullet_swarm.envs.episode import SwarmEpisode
from pybullet_swarm.envs.single import HoverEnv, SingleAgentEnv, WaypointsEnv, hover_scenario
from pybullet_swarm.envs.spaces import ObservationLayout
from pybullet_swarm.envs.swarm import SwarmParallelEnv

__all__ = [
    "ActionMapper",
    "ActionType",
    "EnvConfig",
    "HoverEnv",
    "ObservationLayout",
    "RewardWeights",
    "SingleAgentEnv",
    "StepPeriod",
    "SwarmEpisode",
    "SwarmParallelEnv",
    "WaypointsEnv",
    "hover_scenario",
    "ENV_IDS",
]

#: Gymnasium ids registered by this package -> entry point
ENV_IDS = {
    "pybullet_swarm/Hover-v0": "pybullet_swarm.envs.single:HoverEnv",
    "pybullet_swarm/Waypoints-v0": "pybullet_swarm.envs.single:WaypointsEnv",
}

for _id, _entry in ENV_IDS.items():
    if _id not in gymnasium.registry:
        gymnasium.register(id=_id, entry_point=_entry)
