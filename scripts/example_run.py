#!/usr/bin/env python3
"""Run a scenario from Python and plot a metric: the hover step test, position vs reference.

    python scripts/example_run.py [--scenario hover] [--seed 0] [--out scripts/figures/hover.png]

Nothing is written but the figure: ``pybullet_swarm.run`` keeps results in memory unless
``out=`` is given.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import pybullet_swarm as ps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="hover")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("scripts/figures/hover.png"))
    args = ap.parse_args()

    scenario = ps.load_scenario(args.scenario)
    result = ps.run(scenario, seed=args.seed)
    m = result.metrics
    print(
        f"{scenario.name}: {m['exit_status']} at {m['sim_time_s']:.1f} s, "
        f"tracking RMS {m['tracking_rmse_m'] * 100:.2f} cm, {m['real_time_factor']:.0f}x real time"
    )

    ts = result.timeseries
    start = ts.positions[0, 0].astype(float)
    err = np.linalg.norm(ts.positions[:, 0] - ts.ref_positions[:, 0], axis=1) * 100
    fig = Figure(figsize=(8, 6), layout="constrained")
    ax1, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=[2, 1])
    for k, name in enumerate("xyz"):
        (line,) = ax1.plot(ts.t, ts.positions[:, 0, k] - start[k], label=f"{name}")
        ax1.plot(ts.t, ts.ref_positions[:, 0, k] - start[k], "--", color=line.get_color(), lw=0.9)
    ax1.set_ylabel("offset from start [m]")
    ax1.set_title(f"{scenario.name} ({result.metrics['vehicle']}): position (solid) vs shaped reference (dashed)")
    ax1.legend()
    ax1.grid(alpha=0.3)
    ax2.plot(ts.t, err, color="k", lw=1)
    ax2.set_ylabel("tracking error [cm]")
    ax2.set_xlabel("time [s]")
    ax2.grid(alpha=0.3)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=100)
    print(f"figure: {args.out}")


if __name__ == "__main__":
    main()
