"""Closing figures of issue 6: fitness, route time and collisions of the flocking and formation courses.

Run: python scripts/flocking_table.py [--seeds 10]   (one process; each run takes a few seconds)
"""

from __future__ import annotations

import argparse

import numpy as np

from pybullet_swarm.experiment.runner import run


def row(label: str, scenario: str, avoidance: str, seeds: int, overrides: list[str]) -> None:
    ms = [run(scenario, seed=s, avoidance=avoidance, overrides=overrides).metrics for s in range(seeds)]
    done = [m["route_time_s"] for m in ms if m["route_time_s"] is not None]
    aa = sum(m["collisions"]["agent_agent"] for m in ms)
    ao = sum(m["collisions"]["agent_obstacle"] for m in ms)
    clean = sum(
        m["route_time_s"] is not None and m["collisions"]["agent_agent"] == 0 and m["collisions"]["agent_obstacle"] == 0
        for m in ms
    )
    fit = [m["fitness"] for m in ms if m["fitness"] is not None]
    print(
        f"| {label} | {len(done)}/{seeds} | {clean}/{seeds} | "
        f"{np.mean(done) if done else float('nan'):.1f} +- {np.std(done) if done else float('nan'):.1f} | "
        f"{np.mean(fit):.3f} | {aa} | {ao} |",
        flush=True,
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--radius-seeds", type=int, default=5)
    a = ap.parse_args()
    print("| configuration | route done | done, 0 contacts | route_time_s | fitness | agent_agent | agent_obstacle |")
    print("|---|---|---|---|---|---|---|")
    row("flocking 10, braitenberg", "flocking", "braitenberg", a.seeds, [])
    row("flocking 10, none", "flocking", "none", a.seeds, [])
    row("flocking 5, braitenberg", "flocking", "braitenberg", a.seeds, ["agents.count=5"])
    row("flocking 5, none", "flocking", "none", a.seeds, ["agents.count=5"])
    row("formation 5, braitenberg", "formation", "braitenberg", a.seeds, [])
    row("formation 5, none", "formation", "none", a.seeds, [])
    for r in (0.3, 0.6, 1.0, 3.0, 10.0):  # the seed's range of neighbourhood radii
        row(
            f"flocking 10, braitenberg, radius {r:g} m",
            "flocking",
            "braitenberg",
            a.radius_seeds,
            [f"planner.params.radius={r}"],
        )


if __name__ == "__main__":
    main()
