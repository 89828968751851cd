"""Write the flocking result tables (docs/results/data/flocking_*.json) from finished sweeps and a study.

Each input is the output directory of a ``pybullet-swarm sweep`` (its ``runs.csv``) or of a
``pybullet-swarm tune`` (its ``trials.csv``); the command that made it is passed beside it and
recorded in the table. Tables (each only when its input is given):

* ``flocking_headline``: one row per seed of ``vasarhelyi`` on ``flocking_confined``, then the
  worst case over the seeds, and the issue's targets checked in the notes;
* ``flocking_compare``: per scenario and planner, the mean over seeds of the flock's metrics;
* ``flocking_grid``: per communication delay and radio range, collisions and closeness;
* ``flocking_tuning``: the CMA-ES study's trials, best first.

    python scripts/flocking_results.py --headline DIR "CMD" --compare DIR "CMD" [--compare ...] \
        --grid DIR "CMD" --tuning DIR "CMD" [--bench-wall-s S] [--note NAME TEXT ...]
"""

from __future__ import annotations

import argparse
import csv
import datetime
import json
import math
import subprocess
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "docs" / "results" / "data"
#: m, the scenarios' r_coll and arena side (the targets are judged against these)
R_COLL = 0.3
ARENA_M = 25.0


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _f(row: dict[str, str], key: str) -> float:
    v = row.get(key, "")
    return float(v) if v not in ("", None) else math.nan


def _r(x: float, nd: int = 4) -> float | str:
    return "-" if math.isnan(x) else round(x, nd)


def _ended_early(runs: list[dict[str, str]]) -> list[str]:
    """A note per run that did not fly to its time limit (a flock run ends with timeout)."""
    return [
        f"run {r['planner']} seed {r['seed']}"
        + "".join(f", {k} {r[k]}" for k in ("comm.delay_s", "comm.radio_range_m") if r.get(k))
        + f" ended {r['exit_status']} at {_f(r, 'sim_time_s'):g} s"
        + (f" (agent {r['crashed_agent']}, cause {r['crash_cause']})" if r.get("crashed_agent") else "")
        + "; its averages are up to then."
        for r in runs
        if r["exit_status"] != "timeout"
    ]


def _commit() -> str:
    return subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.strip()


def _table(title: str, command: str, columns: list[str], rows: list[list[Any]], notes: list[str]) -> dict[str, Any]:
    return {
        "title": title,
        "command": command,
        "commit": _commit(),
        "date": datetime.date.today().isoformat(),
        "columns": columns,
        "rows": rows,
        "notes": notes,
    }


def headline(sweep: Path, command: str, bench_wall_s: float | None) -> dict[str, Any]:
    """One row per seed, the worst case, and the targets in the notes."""
    runs = sorted((r for r in _rows(sweep / "runs.csv") if r["exit_status"] != "error"), key=lambda r: int(r["seed"]))
    cols = [
        "seed",
        "velocity correlation",
        "closest pair after warm-up [m]",
        "closest pair, whole run [m]",
        "collision ratio",
        "distance outside [m]",
        "disconnected agents",
        "max cluster",
        "mean speed [m/s]",
        "order",
        "connectivity",
        "fitness",
        "agent-agent contacts",
        "wall time [s]",
    ]
    keys = [
        "flock.velocity_correlation",
        "flock_min_distance_m",
        "min_separation_m",
        "flock.collision_ratio",
        "flock.distance_outside_m",
        "flock.disconnected_agents",
        "flock.max_cluster",
        "flock.mean_speed",
        "flock.order",
        "flock.connectivity",
        "flock.fitness",
        "collisions.agent_agent",
        "wall_time_s",
    ]
    rows = [[int(r["seed"]), *[_r(_f(r, k)) for k in keys]] for r in runs]
    worst_of = [min, min, min, max, max, max, min, min, min, min, min, max, max]
    worst = ["worst"] + [_r(fn(_f(r, k) for r in runs)) for fn, k in zip(worst_of, keys)] if runs else []
    if runs:
        rows.append(worst)
    corr = min(_f(r, "flock.velocity_correlation") for r in runs)
    closest = min(_f(r, "flock_min_distance_m") for r in runs)
    outside = max(_f(r, "flock.distance_outside_m") for r in runs)
    disc = max(_f(r, "flock.disconnected_agents") for r in runs)
    sim_s = {_f(r, "sim_time_s") for r in runs}
    ok = lambda b: "met" if b else "NOT met"  # noqa: E731
    notes = [
        *_ended_early(runs),
        f"{len(runs)} seeds of {', '.join(f'{s:g}' for s in sorted(sim_s))} simulated seconds each; averages after "
        "the 30 s warm-up; r_coll 0.3 m; arena 25 m x 25 m with walls.",
        f"target velocity correlation >= 0.9 on every seed: {ok(corr >= 0.9)} (lowest {corr:.4f}).",
        f"target no pair closer than r_coll = {R_COLL} m: {ok(closest >= R_COLL)} (closest pair after the warm-up "
        f"{closest:.3f} m).",
        f"target distance outside < 1 % of the arena ({0.01 * ARENA_M:g} m): {ok(outside < 0.01 * ARENA_M)} "
        f"(largest {outside:.4f} m).",
        f"target 0 disconnected agents: {ok(disc == 0.0)} (largest time average {disc:g}; 0 means none at any sample).",
        "wall time: each run's own, measured while other jobs shared the machine's 2 cores (not a benchmark).",
    ]
    if bench_wall_s is not None:
        notes.append(
            f"target a 30-agent 10-minute run under 2 minutes of wall time: {ok(bench_wall_s < 120.0)} "
            f"({bench_wall_s:.1f} s)."
        )
    return _table("vasarhelyi on flocking_confined: the issue's targets, per seed", command, cols, rows, notes)


#: (column, metric) of the comparison and grid tables
FLOCK_COLUMNS = [
    ("velocity correlation", "flock.velocity_correlation"),
    ("closest pair [m]", "flock_min_distance_m"),
    ("collision ratio", "flock.collision_ratio"),
    ("distance outside [m]", "flock.distance_outside_m"),
    ("disconnected agents", "flock.disconnected_agents"),
    ("min cluster", "flock.min_cluster"),
    ("max cluster", "flock.max_cluster"),
    ("mean speed [m/s]", "flock.mean_speed"),
    ("safety", "flock.safety"),
    ("order", "flock.order"),
    ("union", "flock.union"),
    ("connectivity", "flock.connectivity"),
    ("fitness", "flock.fitness"),
    ("agent-agent contacts", "collisions.agent_agent"),
    ("agent-obstacle contacts", "collisions.agent_obstacle"),
]


def _mean(rows: list[dict[str, str]], key: str) -> float:
    vals = [_f(r, key) for r in rows]
    vals = [v for v in vals if not math.isnan(v)]
    if key == "flock_min_distance_m":  # the closest any seed came
        return min(vals) if vals else math.nan
    return sum(vals) / len(vals) if vals else math.nan


def compare(sweeps: list[tuple[Path, str]]) -> dict[str, Any]:
    """Per scenario and planner, the mean over seeds (the closest pair: the minimum)."""
    rows, commands, seeds, early = [], [], set(), []
    for sweep, command in sweeps:
        commands.append(command)
        runs = [r for r in _rows(sweep / "runs.csv") if r["exit_status"] != "error"]
        early += [f"{runs[0]['scenario']}: {n}" for n in _ended_early(runs)] if runs else []
        for planner in dict.fromkeys(r["planner"] for r in runs):
            mine = [r for r in runs if r["planner"] == planner]
            seeds.add((len(mine), _f(mine[0], "sim_time_s")))
            rows.append([mine[0]["scenario"], planner, len(mine), *[_r(_mean(mine, k)) for _, k in FLOCK_COLUMNS]])
    notes = [
        "runs per row and simulated seconds: "
        + ", ".join(f"{n} x {t:g} s" for n, t in sorted(seeds))
        + "; means over the seeds, except the closest pair (the minimum); averages after the 30 s warm-up.",
        "each planner with its defaults; reynolds follows the task's circuit with its route defaults.",
        *early,
    ]
    cols = ["scenario", "planner", "seeds", *[c for c, _ in FLOCK_COLUMNS]]
    return _table(
        "Flocking planners side by side (same scenarios, same metrics)", " && ".join(commands), cols, rows, notes
    )


def grid(sweep: Path, command: str) -> dict[str, Any]:
    """Per delay and radio range: collisions and closeness, means over the seeds."""
    runs = [r for r in _rows(sweep / "runs.csv") if r["exit_status"] != "error"]
    cells: dict[tuple[float, float], list[dict[str, str]]] = {}
    for r in runs:
        cells.setdefault((_f(r, "comm.delay_s"), _f(r, "comm.radio_range_m")), []).append(r)
    cols = [
        "delay [s]",
        "radio range [m]",
        "seeds",
        "collision ratio",
        "closest pair [m]",
        "agent-agent contacts",
        "velocity correlation",
        "disconnected agents",
        "fitness",
    ]
    keys = [
        "flock.collision_ratio",
        "flock_min_distance_m",
        "collisions.agent_agent",
        "flock.velocity_correlation",
        "flock.disconnected_agents",
        "flock.fitness",
    ]
    rows = [[d, rr, len(v), *[_r(_mean(v, k), 5) for k in keys]] for (d, rr), v in sorted(cells.items())]
    sim = sorted({_f(r, "sim_time_s") for r in runs if r["exit_status"] == "timeout"})
    notes = [
        f"vasarhelyi on flocking_confined, {', '.join(f'{s:g}' for s in sim)} simulated seconds per run (a shortened "
        "run, not the 10-minute setting), averages after the 30 s warm-up; means over the seeds (closest pair: minimum).",
        "comm.delay_s is counted in whole planner periods (0.1 s); comm.radio_range_m limits who is heard "
        "(agents.sensing_radius is 8 m).",
        *_ended_early(runs),
    ]
    return _table("Collisions against communication delay and radio range (grid sweep)", command, cols, rows, notes)


def tuning(study: Path, command: str, top: int = 12) -> dict[str, Any]:
    """The study's trials, best first."""
    trials = [t for t in _rows(study / "trials.csv") if t.get("state") == "complete"]
    value = next(k for k in trials[0] if k.startswith("value")) if trials else "value"
    params = [k for k in (trials[0] if trials else {}) if k.startswith("planner.params.")]
    trials.sort(key=lambda t: -_f(t, value))
    cols = ["trial", "fitness", *[p.removeprefix("planner.params.") for p in params]]
    rows = [
        [
            f"{t['trial']} (defaults)" if t.get("baseline") == "true" else int(t["trial"]),
            _r(_f(t, value)),
            *[_r(_f(t, p), 4) for p in params],
        ]
        for t in trials[:top]
    ]
    notes = [
        f"{len(trials)} completed trials of CMA-ES (Optuna's CmaEsSampler) over vasarhelyi's eleven parameters; "
        "one seed per trial and a shortened run (see the command): a small-budget study, not a converged one.",
        "fitness: robotsim's product of transfer functions of the time-averaged order parameters (flock.fitness).",
    ]
    return _table("CMA-ES tuning study of vasarhelyi on flocking_confined (small budget)", command, cols, rows, notes)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--headline", nargs=2, metavar=("DIR", "CMD"))
    p.add_argument("--compare", nargs=2, action="append", default=[], metavar=("DIR", "CMD"))
    p.add_argument("--grid", nargs=2, metavar=("DIR", "CMD"))
    p.add_argument("--tuning", nargs=2, metavar=("DIR", "CMD"))
    p.add_argument("--bench-wall-s", type=float, default=None, help="wall time s of one 30-agent 10-minute run")
    p.add_argument(
        "--note", nargs=2, action="append", default=[], metavar=("NAME", "TEXT"), help="add a note to a table"
    )
    p.add_argument("--out", type=Path, default=DATA)
    a = p.parse_args()
    tables: dict[str, dict[str, Any]] = {}
    if a.headline:
        tables["flocking_headline"] = headline(Path(a.headline[0]), a.headline[1], a.bench_wall_s)
    if a.compare:
        tables["flocking_compare"] = compare([(Path(d), c) for d, c in a.compare])
    if a.grid:
        tables["flocking_grid"] = grid(Path(a.grid[0]), a.grid[1])
    if a.tuning:
        tables["flocking_tuning"] = tuning(Path(a.tuning[0]), a.tuning[1])
    for name, text in a.note:
        tables[name]["notes"].append(text)
    a.out.mkdir(parents=True, exist_ok=True)
    for name, data in tables.items():
        path = a.out / f"{name}.json"
        path.write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n")
        print(path)


if __name__ == "__main__":
    main()
