"""One run of a sweep as a self-contained job: its spec, the worker function and its ``runs.csv`` row.

Executors (``pybullet_swarm.experiment.executors``) run jobs; sweeps (``...sweep``) plan them.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import os
import shutil
import time
import traceback
from pathlib import Path
from typing import Any, Mapping

from pybullet_swarm.experiment.results import Row, RunStatus, metrics_row, one_line, plain_cell


@dataclasses.dataclass(frozen=True)
class RunSpec:
    """One run of a sweep, self-contained so that a worker on any machine can run it.

    Attributes:
        run_id: hash of the resolved scenario (without seed), planner, avoidance and seed.
        planner: resolved planner name.
        avoidance: resolved avoidance layer name.
        seed: seed of the run.
        grid: this run's grid values ``((key, value), ...)``.
        scenario_data: the resolved scenario (overrides and grid values applied), plain data.
        source: the scenario file's name (for error messages).
        run_dir: absolute path of the run directory.
        plots: draw the run's own figures and write its ``report.html``.
    """

    run_id: str
    planner: str
    avoidance: str
    seed: int
    grid: tuple[tuple[str, Any], ...]
    scenario_data: Mapping[str, Any]
    source: str
    run_dir: str
    plots: bool = False

    @property
    def rel_dir(self) -> str:
        """The run directory relative to the sweep directory."""
        return f"runs/{self.run_id}"

    def identity(self) -> Row:
        """The identity cells of this run's row: run_id, planner, avoidance, seed, grid values."""
        row: Row = {"run_id": self.run_id, "planner": self.planner, "avoidance": self.avoidance, "seed": self.seed}
        row.update({k: plain_cell(v) for k, v in self.grid})
        return row


# -------------------------------------------------------------------- worker
def make_row(
    spec: RunSpec,
    metrics: Mapping[str, Any] | None,
    *,
    error: str | None = None,
    worker_time_s: float | None = None,
    worker_cpu_s: float | None = None,
) -> Row:
    """The ``runs.csv`` row of a run: identity, outcome, flattened scalar metrics. ``worker_time_s`` is the
    run's wall time in its worker, ``worker_cpu_s`` the CPU time its process spent on it (what the run costs
    on an idle core, whatever the load of the machine)."""
    row = spec.identity()
    status = RunStatus.ERROR.value if metrics is None else str(metrics.get("exit_status", RunStatus.ERROR.value))
    row.update(
        {
            "exit_status": status,
            "error": None if error is None else one_line(error),
            "worker_time_s": None if worker_time_s is None else round(float(worker_time_s), 4),
            "run_dir": spec.rel_dir,
            "worker_cpu_s": None if worker_cpu_s is None else round(float(worker_cpu_s), 4),
        }
    )
    if metrics is not None:
        row.update(metrics_row(metrics))
    return row


def execute_run(spec: RunSpec) -> Row:
    """Run one spec in this process and write its run directory; returns only its row.

    Anything the run raises becomes a row with ``exit_status = error`` and the message (the
    traceback goes to ``error.txt`` in the run directory). The time series stays on disk.
    """
    from pybullet_swarm.experiment.rundir import atomic_write
    from pybullet_swarm.experiment.runner import run
    from pybullet_swarm.experiment.scenario import build_scenario

    t0, c0 = time.perf_counter(), time.process_time()
    run_dir = Path(spec.run_dir)
    try:
        if run_dir.exists():  # a run killed part-way: start it again from nothing
            shutil.rmtree(run_dir)
        scenario = build_scenario(copy.deepcopy(dict(spec.scenario_data)), source=spec.source)
        result = run(
            scenario,
            planner=spec.planner,
            avoidance=spec.avoidance,
            seed=spec.seed,
            out=run_dir,
            plots=spec.plots,
            report=spec.plots,
            quiet=True,
        )
        return make_row(
            spec, result.metrics, worker_time_s=time.perf_counter() - t0, worker_cpu_s=time.process_time() - c0
        )
    except Exception as exc:  # noqa: BLE001 - a failed run is a result, recorded with its error
        with contextlib.suppress(OSError):
            atomic_write(run_dir / "error.txt", lambda fh: fh.write(traceback.format_exc()))
        return make_row(spec, None, error=f"{type(exc).__name__}: {exc}", worker_time_s=time.perf_counter() - t0)


def failure_row(spec: RunSpec, message: str) -> Row:
    """The row of a run whose worker never returned (the process died, or every retry failed)."""
    return make_row(spec, None, error=message)


def cpu_count() -> int:
    """Cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1
