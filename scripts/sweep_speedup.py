#!/usr/bin/env python3
"""Speed-up of a sweep on the local pool: the same command with 1 worker and with K workers.

    python scripts/sweep_speedup.py [--scenario construction] [--seeds 8] [--workers 2] [--repeats 1]
                                    [--set key.path=value ...] [--json out.json]

Each measurement is the whole command ``pybullet-swarm sweep SCENARIO --seeds N --workers W
--no-plots`` in a fresh process and a fresh sweep directory (nothing skipped), timed from start
to exit: imports, worker start-up, every run, the summary. With ``--repeats`` the two are
alternated and the fastest of each is kept. Prints the wall times, the speed-up ``T1 / TK``, the
efficiency ``speed-up / K`` and the load average before and after, and checks that both sweeps
recorded the same numbers (runs are deterministic).

Where the time went, per measurement (the command's own ``time:`` line and ``runs.csv``):
``serial_s`` is the command's wall time outside the runs phase (interpreter and imports,
planning, the summary, the report page), ``runs_s`` the runs phase (first run submitted to
last row received), ``busy_s`` the runs' own time in their workers summed, and ``busy_share``
= busy / (K x runs_s): what is left of it is worker start-up and load imbalance at the end.
The machine's other load shows in the load averages: on a shared machine wall times are noisy.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path


TIME_LINE = re.compile(
    r"time: planning (?P<plan_s>[\d.]+) s, runs (?P<runs_s>[\d.]+) s \(the runs themselves "
    r"(?P<busy_s>[\d.]+) s in their workers\), summary and figures (?P<finish_s>[\d.]+) s"
)


def timed_sweep(args: argparse.Namespace, out: Path, workers: int) -> tuple[float, dict[str, str], dict[str, float]]:
    """Wall seconds of one sweep command into an empty directory, each run's ``energy_j`` by id, and
    the command's own timings (its ``time:`` line)."""
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
        "--no-plots",
    ]
    for o in args.overrides:
        cmd += ["--set", o]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"sweep failed ({done.returncode}): {done.stderr.strip()}")
    found = TIME_LINE.search(done.stdout)
    timings = {k: float(v) for k, v in found.groupdict().items()} if found else {}
    with open(out / "runs.csv", newline="") as fh:
        return wall, {r["run_id"]: r["energy_j"] for r in csv.DictReader(fh)}, timings


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
    parts: dict[int, list[dict[str, float]]] = {1: [], args.workers: []}
    rows: dict[int, dict[str, str]] = {}
    with tempfile.TemporaryDirectory(prefix="sweep-speedup-") as tmp:
        for rep in range(args.repeats):
            order = (1, args.workers) if rep % 2 == 0 else (args.workers, 1)
            for w in order:
                wall, rows[w], t = timed_sweep(args, Path(tmp) / f"r{rep}-w{w}", w)
                times[w].append(round(wall, 2))
                if t:
                    t = {**t, "serial_s": wall - t["runs_s"], "busy_share": t["busy_s"] / (w * t["runs_s"])}
                parts[w].append({k: round(v, 3) for k, v in t.items()})
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
        "parts_1": parts[1],
        f"parts_{args.workers}": parts[args.workers],
        "cores": os.cpu_count(),
        "load_before": [round(x, 2) for x in load_before],
        "load_after": [round(x, 2) for x in load_after],
    }
    print(json.dumps(report, indent=2))
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
