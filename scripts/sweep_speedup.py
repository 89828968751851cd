#!/usr/bin/env python3
"""Speed-up of a sweep on the local pool: the same command with 1 worker and with K workers.

    python scripts/sweep_speedup.py [--scenario construction] [--seeds 8] [--workers 2] [--repeats 1]
                                    [--set key.path=value ...] [--json out.json]

Each measurement is the whole command ``pybullet-swarm sweep SCENARIO --seeds N --workers W
--quiet --no-plots`` in a fresh process and a fresh sweep directory (nothing skipped), timed
from start to exit: imports, worker start-up, every run, the summary. With ``--repeats`` the
two are alternated and the fastest of each is kept. Prints the wall times, the speed-up
``T1 / TK``, the efficiency ``speed-up / K`` and the load average before and after, and checks
that both sweeps recorded the same numbers (runs are deterministic).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def timed_sweep(args: argparse.Namespace, out: Path, workers: int) -> tuple[float, dict[str, str]]:
    """Wall seconds of one sweep command into an empty directory, and each run's ``energy_j`` by id."""
    cmd = [
        sys.executable,
        "-m",
        "pybullet_swarm.cli.main",
        "sweep",
        args.scenario,
        "--seeds",
        str(args.seeds),
        "--workers",
        str(workers),
        "--out",
        str(out),
        "--quiet",
        "--no-plots",
    ]
    for o in args.overrides:
        cmd += ["--set", o]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"sweep failed ({done.returncode}): {done.stderr.strip()}")
    with open(out / "runs.csv", newline="") as fh:
        return wall, {r["run_id"]: r["energy_j"] for r in csv.DictReader(fh)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="construction")
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE")
    ap.add_argument("--json", type=Path, default=None, help="write the measurement here")
    args = ap.parse_args()

    load_before = os.getloadavg()
    times: dict[int, list[float]] = {1: [], args.workers: []}
    rows: dict[int, dict[str, str]] = {}
    with tempfile.TemporaryDirectory(prefix="sweep-speedup-") as tmp:
        for rep in range(args.repeats):
            order = (1, args.workers) if rep % 2 == 0 else (args.workers, 1)
            for w in order:
                wall, rows[w] = timed_sweep(args, Path(tmp) / f"r{rep}-w{w}", w)
                times[w].append(round(wall, 2))
    load_after = os.getloadavg()
    if rows[1] != rows[args.workers]:
        raise SystemExit("the two sweeps recorded different numbers")
    t1, tk = min(times[1]), min(times[args.workers])
    speedup = t1 / tk
    report = {
        "scenario": args.scenario,
        "overrides": args.overrides,
        "runs": len(rows[1]),
        "workers": args.workers,
        "wall_1_s": times[1],
        f"wall_{args.workers}_s": times[args.workers],
        "speedup": round(speedup, 3),
        "efficiency": round(speedup / args.workers, 3),
        "cores": os.cpu_count(),
        "load_before": [round(x, 2) for x in load_before],
        "load_after": [round(x, 2) for x in load_after],
    }
    print(json.dumps(report, indent=2))
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
