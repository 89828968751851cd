"""``SwarmParallelEnv``: the swarm as a PettingZoo parallel environment.

Agents ``agent_0 ... agent_{n-1}`` are the scenario's agents. Each observes its own local
observation flattened into a ``Box`` (layout in ``pybullet_swarm.envs.spaces``) and acts with
velocity set-points, waypoints or rotor speeds (``pybullet_swarm.envs.actions``). Rewards are in
``pybullet_swarm.envs.rewards``. The episode ends for every agent at once: terminated when the
task is completed or an agent crashes (the run ends, as ``pybullet-swarm run`` does), truncated
at the scenario's time limit.

``infos[agent]`` holds ``collisions`` (the contact events of this step the agent was part of,
as ``{time_s, kind, a, b, detail}``), ``metrics`` (running counts; at the episode's end the full
metrics of the run, the same as ``metrics.json`` of ``pybullet-swarm run``, one dict shared by
all agents), ``goal_distance_m`` on waypoint tasks, and at the end ``episode``
(``{"return": float, "length": steps}``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from gymnasium import logger, spaces
from numpy.typing import NDArray
from pettingzoo import ParallelEnv

from pybullet_swarm.envs.config import EnvConfig, make_config
from pybullet_swarm.envs.episode import SwarmEpisode
from pybullet_swarm.envs.spaces import ObservationLayout
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import Scenario, load_scenario
from pybullet_swarm.experiment.simulation import Simulation

RENDER_MODES = ("rgb_array",)
SEED_BOUND = 2**63 - 1  # exclusive bound of the run seeds drawn by an unseeded reset


def resolve_scenario(scenario: Scenario | str | Path, overrides: Mapping[str, Any] | Sequence[str]) -> Scenario:
    """A validated scenario from a ``Scenario``, a YAML path or a bundled name, with overrides applied."""
    if isinstance(scenario, Scenario):
        return scenario.with_overrides(overrides) if overrides else scenario
    return load_scenario(scenario, overrides)


def check_render_mode(render_mode: str | None, source: str) -> None:
    """Refuse render modes other than None and ``rgb_array``."""
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise ConfigError(
            f"must be None or one of {', '.join(RENDER_MODES)}, got {render_mode!r}",
            source=source,
            field="env.render_mode",
        )


class SwarmParallelEnv(ParallelEnv):
    """The scenario's swarm as a PettingZoo ``ParallelEnv``.

    Args:
        scenario: a ``Scenario``, a YAML path or a bundled scenario name.
        overrides: ``key.path=value`` scenario overrides.
        config: an ``EnvConfig`` or a mapping of its options.
        render_mode: None or ``"rgb_array"``.
        **options: ``EnvConfig`` options (``action_type``, ``period``, ``neighbours``, ``rewards``, ...).

    Raises:
        ConfigError: a bad scenario or option (one line naming the file and the field).

    Seeding: ``reset(seed=s)`` runs the scenario with seed ``s``, exactly as ``pybullet-swarm run
    --seed s``; ``reset()`` draws the next run's seed from the environment's generator (seeded by
    the last ``reset(seed=...)``, else from fresh entropy).
    """

    metadata = {
        "name": "pybullet_swarm_v0",
        "render_modes": list(RENDER_MODES),
        "is_parallelizable": True,
        "render_fps": 10,
    }

    def __init__(
        self,
        scenario: Scenario | str | Path = "hover_swarm",
        *,
        overrides: Mapping[str, Any] | Sequence[str] = (),
        config: EnvConfig | Mapping[str, Any] | None = None,
        render_mode: str | None = None,
        **options: Any,
    ) -> None:
        sc = resolve_scenario(scenario, overrides)
        check_render_mode(render_mode, sc.source)
        self.scenario = sc
        self.config = make_config(config, options, source=sc.source)
        self.render_mode = render_mode
        self._episode = SwarmEpisode(sc, self.config)
        ep = self._episode
        self.metadata = {**type(self).metadata, "render_fps": 1.0 / ep.dt}
        self.possible_agents: list[str] = [f"agent_{i}" for i in range(ep.n)]
        self.agents: list[str] = []
        self.layout: ObservationLayout = ep.layout
        self._obs_spaces = {
            a: spaces.Box(ep.layout.low, ep.layout.high, dtype=np.float32) for a in self.possible_agents
        }
        m = ep.mapper
        self._act_spaces = {a: spaces.Box(m.low, m.high, dtype=m.dtype) for a in self.possible_agents}
        self._np_random: np.random.Generator | None = None

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent: str) -> spaces.Box:
        """The observation space of ``agent`` (the same object on every call)."""
        return self._obs_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        """The action space of ``agent`` (the same object on every call)."""
        return self._act_spaces[agent]

    @property
    def sim(self) -> Simulation:
        """The simulation of the current episode (read its state, events, contacts; do not step it)."""
        return self._episode.sim

    @property
    def dt(self) -> float:
        """Simulated seconds per environment step."""
        return self._episode.dt

    def neutral_actions(self) -> dict[str, NDArray[Any]]:
        """Actions that hold every live agent where it is (zero velocity, its own position, hover speed)."""
        rows = self._episode.mapper.hover_action(self.sim)
        return {a: rows[int(a.rsplit("_", 1)[1])] for a in self.agents}

    # ------------------------------------------------------------------- API
    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float32]], dict[str, dict[str, Any]]]:
        """Start an episode; returns observations and infos by agent."""
        if seed is not None:
            self._np_random = np.random.default_rng(seed)
            run_seed = int(seed)
        else:
            if self._np_random is None:
                self._np_random = np.random.default_rng()
            run_seed = int(self._np_random.integers(SEED_BOUND))
        obs = self._episode.reset(run_seed)
        self.agents = list(self.possible_agents)
        metrics = self._episode.running_metrics()
        infos = {a: {"collisions": [], "metrics": metrics} for a in self.agents}
        return {a: obs[i] for i, a in enumerate(self.agents)}, infos

    def step(
        self, actions: Mapping[str, Any]
    ) -> tuple[
        dict[str, NDArray[np.float32]], dict[str, float], dict[str, bool], dict[str, bool], dict[str, dict[str, Any]]
    ]:
        """Advance one period with the agents' actions (a missing agent holds where it is)."""
        if not self.agents:
            raise RuntimeError("the episode has ended (no live agents); call reset() first")
        ep = self._episode
        names = self.possible_agents
        try:
            if len(actions) != len(names):
                raise KeyError
            rows = np.stack([actions[a] for a in names])
        except KeyError:
            rows = self._fill_actions(actions)
        obs, out, terminated, truncated = ep.step(rows)
        metrics = ep.running_metrics()
        obs_d = dict(zip(names, obs))
        rew_d = dict(zip(names, out.rewards.tolist()))
        term_d = dict.fromkeys(names, terminated)
        trunc_d = dict.fromkeys(names, truncated)
        infos: dict[str, dict[str, Any]] = {
            a: {"collisions": c, "metrics": metrics} for a, c in zip(names, out.collisions)
        }
        if out.goal_distance is not None:
            for a, d in zip(names, out.goal_distance.tolist()):
                infos[a]["goal_distance_m"] = d
        if terminated or truncated:
            for a, ret in zip(names, ep.returns.tolist()):
                infos[a]["episode"] = {"return": ret, "length": ep.steps}
            self.agents = []
        return obs_d, rew_d, term_d, trunc_d, infos

    def _fill_actions(self, actions: Mapping[str, Any]) -> NDArray[np.float64]:
        """Action rows (n, dim) from a partial mapping: agents without an action hold where they are."""
        ep = self._episode
        rows = ep.mapper.hover_action(ep.sim).astype(np.float64)
        for a, act in actions.items():
            if a not in self._act_spaces:
                raise KeyError(f"unknown agent {a!r}; agents: {', '.join(self.agents)}")
            rows[int(a.rsplit("_", 1)[1])] = np.asarray(act, dtype=np.float64).reshape(-1)
        return rows

    def render(self) -> NDArray[np.uint8] | None:
        """An RGB frame (height, width, 3) uint8 with ``render_mode="rgb_array"`` (DIRECT mode), else None."""
        if self.render_mode is None:
            logger.warn("render() called without a render mode; create the environment with render_mode='rgb_array'")
            return None
        return self._episode.render()

    def state(self) -> NDArray[np.float32]:
        """The global state: every agent's observation row, concatenated (n * dim,)."""
        return self._episode.observe().reshape(-1)

    def close(self) -> None:
        """Release the simulation (idempotent)."""
        self._episode.close()
