#!/usr/bin/env python3
"""Profile one run with cProfile: where the time of the simulation loop goes.

    python scripts/profile_run.py construction --planner stigmergy --avoidance orca --seconds 60 \\
        --share ghost_overlaps --share stepSimulation --share contact_pairs

Only ``Simulation.run`` is profiled (not the set-up or the results). Prints the real-time factor of the
profiled run (by wall clock and by process CPU time; cProfile slows Python calls down, so both are below
an unprofiled run's), the functions with the most own time, and for each ``--share NAME`` the cumulative
time of the functions whose name contains NAME as a share of the run. ``--out FILE`` keeps the profile for
``python -m pstats FILE``. ``--timing N`` first runs it N times unprofiled and prints the best real-time
factor by wall clock and by CPU time (on a shared machine the CPU figure is the steadier one). Figures
depend on the machine; nothing here is asserted.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time

from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.experiment.simulation import Simulation


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenario", help="bundled scenario name or YAML file")
    ap.add_argument("--planner", default=None)
    ap.add_argument("--avoidance", default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated time limit, s")
    ap.add_argument("--top", type=int, default=20, help="functions listed by own time")
    ap.add_argument("--share", action="append", default=[], metavar="NAME", help="report this function's share")
    ap.add_argument("--out", default=None, help="write the profile to this file")
    ap.add_argument("--timing", type=int, default=0, metavar="N", help="first time N unprofiled runs")
    args = ap.parse_args()

    sc = load_scenario(args.scenario, {"task.time_limit_s": args.seconds})
    if args.timing > 0:
        best_wall = best_cpu = 0.0
        for _ in range(args.timing):
            with Simulation(sc, planner=args.planner, avoidance=args.avoidance, seed=args.seed) as sim:
                wall, cpu = time.perf_counter(), time.process_time()
                sim.run()
                wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
                best_wall, best_cpu = max(best_wall, sim.time / wall), max(best_cpu, sim.time / cpu)
        print(f"unprofiled, best of {args.timing}: {best_wall:.1f}x real time by wall clock, {best_cpu:.1f}x by CPU")
    with Simulation(sc, planner=args.planner, avoidance=args.avoidance, seed=args.seed, record=True) as sim:
        prof = cProfile.Profile()
        wall, cpu = time.perf_counter(), time.process_time()
        prof.enable()
        sim.run()
        prof.disable()
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        sim_time = sim.time
    stats = pstats.Stats(prof)
    if args.out:
        stats.dump_stats(args.out)
    total = stats.total_tt  # type: ignore[attr-defined]
    print(
        f"{sim_time:.1f} s simulated; profiled: {sim_time / wall:.1f}x real time by wall clock, {sim_time / cpu:.1f}x by CPU"
    )
    rows = sorted(stats.stats.items(), key=lambda kv: -kv[1][2])[: args.top]  # type: ignore[attr-defined]
    print(f"{'own s':>7} {'own %':>6} {'cum s':>7} {'calls':>9}  function")
    for (path, line, name), (_, calls, own, cum, _) in rows:
        where = f"{path.rsplit('/', 1)[-1]}:{line} " if path != "~" else ""
        print(f"{own:7.3f} {100 * own / total:5.1f}% {cum:7.3f} {calls:9d}  {where}{name}")
    for name in args.share:
        # the cumulative times of every function whose name contains NAME (one calling another counts twice)
        cum = sum(v[3] for k, v in stats.stats.items() if name in k[2])  # type: ignore[attr-defined]
        print(f"share of {name!r}: {cum:.3f} s, {100 * cum / total:.1f} %")


if __name__ == "__main__":
    main()
