"""Cost of the ORCA layer per planner tick, in a crowded swap of N agents (issue 5: <= 5 ms for 50).

Usage::

    python scripts/orca_bench.py                 # 50 quad150 agents swap antipodes on a 3 m circle
    python scripts/orca_bench.py --agents 100 --seconds 20

Runs the whole simulation (physics included) with ``--avoidance orca`` and reports the layer's
own wall time per planner tick (``orca_mean_solve_ms`` / ``orca_max_solve_ms``: neighbour search,
shapes, the compiled LPs, the commands), the contacts, and how many agents reached their goals.
The numba kernels run on one core.
"""

from __future__ import annotations

import argparse
import time
from typing import ClassVar

import numpy as np
import yaml
from pydantic import Field

import pybullet_swarm
from pybullet_swarm.planning.base import Command, TaskInfo, WorldView
from pybullet_swarm.planning.params import Params as PlannerParams
from pybullet_swarm.planning.registry import register_planner


class FixedTargets:
    """Every agent flies to its own fixed target (centralised; a benchmark set-up only)."""

    name: ClassVar[str] = "bench_fixed_targets"
    centralized: ClassVar[bool] = True

    class Params(PlannerParams):
        """The agents' targets."""

        targets: list[list[float]] = Field(default_factory=list, description="m, one [x, y, z] per agent")

    def __init__(self, params: Params) -> None:
        self.targets = np.asarray(params.targets, dtype=float)

    def reset(self, n: int, rng: np.random.Generator, info: TaskInfo) -> None:
        """Nothing to prepare."""

    def plan_all(self, view: WorldView) -> list[Command]:
        """Each agent's target."""
        return [Command.goto(t) for t in self.targets]


def main() -> None:
    """Run the benchmark and print the layer's cost."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agents", type=int, default=50)
    ap.add_argument("--radius", type=float, default=3.0, help="m, circle radius")
    ap.add_argument("--seconds", type=float, default=30.0, help="simulated time")
    ap.add_argument("--set", action="append", default=[], help="avoidance parameter name=value")
    args = ap.parse_args()
    register_planner(FixedTargets.name, FixedTargets, "benchmark only", ("waypoints",))
    n, c = args.agents, np.array([4.0, 4.0, 0.0])
    a = 2 * np.pi * np.arange(n) / n
    starts = np.column_stack([args.radius * np.cos(a), args.radius * np.sin(a), np.full(n, 1.0)]) + c
    goals = (starts - c) * [-1, -1, 1] + c
    sc = pybullet_swarm.load_scenario(
        "hover",
        {
            "arena.size": [8.0, 8.0],
            "agents.count": n,
            "agents.start": starts.tolist(),
            "collisions": "physical",
            "task.time_limit_s": args.seconds,
            "task.waypoints": [{"t_s": 0.0, "position": [0.0, 0.0, 500.0]}],
            "planner": {"name": FixedTargets.name, "params": {"targets": goals.tolist()}},
            "avoidance": "orca",
            **{f"avoidance_params.{k}": yaml.safe_load(v) for k, v in (kv.split("=", 1) for kv in args.set)},
        },
    )
    t0 = time.perf_counter()
    r = pybullet_swarm.run(sc)
    wall = time.perf_counter() - t0
    m = r.metrics
    final = r.timeseries.positions[-1].astype(float)
    arrived = int(np.sum(np.linalg.norm(final - goals, axis=1) < 0.05))
    print(f"{n} agents, {m['sim_time_s']:.0f} s simulated in {wall:.1f} s wall ({m['exit_status']})")
    print(
        f"layer per planner tick: mean {m['orca_mean_solve_ms']:.2f} ms, max {m['orca_max_solve_ms']:.2f} ms "
        f"over {m['orca_ticks']} ticks"
    )
    print(
        f"commands changed {100 * m['orca_changed_fraction']:.1f} % of agent-ticks, infeasible LPs "
        f"{m['orca_infeasible_agent_ticks']} agent-ticks"
    )
    print(
        f"contacts {m['collisions']}, closest approach {m.get('min_separation_m', float('nan')):.3f} m, "
        f"{arrived}/{n} within 5 cm of their goals"
    )


if __name__ == "__main__":
    main()
