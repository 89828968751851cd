"""Scripted runs: load a scenario, simulate it, optionally write a run directory."""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Mapping, Sequence

from pybullet_swarm.experiment.rundir import write_events, write_json, write_yaml
from pybullet_swarm.experiment.scenario import Scenario, load_scenario
from pybullet_swarm.experiment.simulation import RunResult, Simulation


def run(
    scenario: Scenario | str | Path,
    *,
    planner: str | None = None,
    avoidance: str | None = None,
    seed: int | None = None,
    out: str | Path | None = None,
    overrides: Mapping[str, Any] | Sequence[str] = (),
    gui: bool = False,
    plots: bool = True,
    video: bool = False,
    quiet: bool = True,
) -> RunResult:
    """Run a scenario to its end and return the result.

    Args:
        scenario: a ``Scenario``, a YAML path or a bundled scenario name.
        planner: planner name (default: the scenario's; another planner than the scenario's drops
            the scenario's ``planner.params``, see ``scenario.apply_choices``).
        avoidance: avoidance layer (default: the scenario's; likewise for ``avoidance_params``).
        seed: seed of the run (default: the scenario's ``seed``).
        out: write the run directory here (nothing is written when None).
        overrides: ``key.path=value`` overrides applied to the scenario (after the choices above).
        gui: watch in the Bullet GUI.
        plots: draw the figures into ``out/plots`` (only with ``out``).
        video: render ``out/video.mp4`` (``.gif`` when no MP4 encoder is installed; needs ``out``).
        quiet: no progress bar.

    Returns:
        The exit status, metrics, events and time series.
    """
    # the choices and overrides are applied before validation: the resolved scenario names them
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario, overrides, planner=planner, avoidance=avoidance, seed=seed)
    else:
        scenario = scenario.with_choices(planner=planner, avoidance=avoidance, seed=seed, overrides=overrides)
    if video and out is None:
        raise ValueError("video needs an output directory (out=...)")
    if out is not None:
        from pybullet_swarm.experiment.rundir import check_run_dir

        check_run_dir(Path(out))   # before the simulation: a directory it could not write is refused now
    video_path = None
    if video and out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        video_path = Path(out) / "video.mp4"
    with Simulation(scenario, gui=gui, video=video_path, video_quiet=quiet) as sim:
        result = sim.run()
        written = sim.close_video()
    if written is not None:
        result.metrics["video"] = written.name
    if out is not None:
        result = dataclasses.replace(result, run_dir=write_run(result, Path(out), plots=plots))
    return result


def write_run(result: RunResult, out: Path, *, plots: bool = True) -> Path:
    """Write ``scenario.yaml``, ``metrics.json``, ``timeseries.npz``, ``events.csv`` and ``plots/``.

    A previous run's files in ``out`` are removed first (``rundir.clear_run_dir``): the directory
    then holds this run only.
    """
    from pybullet_swarm.experiment.rundir import atomic_write, clear_run_dir

    video = result.metrics.get("video")
    clear_run_dir(out, keep=frozenset({video}) if isinstance(video, str) else frozenset())
    out.mkdir(parents=True, exist_ok=True)
    write_yaml(out / "scenario.yaml", dict(result.scenario.data))   # resolved: planner, avoidance, seed, parameters
    atomic_write(out / "timeseries.npz", result.timeseries.save_to, binary=True)
    write_events(out / "events.csv", result.events)
    write_artefacts(out, result.artifacts)
    if plots:
        from pybullet_swarm.plotting.run_plots import plot_run, plot_saved_artifacts

        plot_run(result.timeseries, out / "plots", result.metrics, scenario=result.scenario.data,
                 events=result.events)
        plot_saved_artifacts(out, out / "plots")
    write_json(out / "metrics.json", result.metrics)   # last: its presence marks a finished run
    return out


def write_artefacts(out: Path, artefacts: dict[str, Any]) -> list[Path]:
    """Write a run's artefacts (data by file name: ``.json`` plain data, ``.npz`` arrays by name) atomically."""
    import numpy as np

    from pybullet_swarm.experiment.rundir import atomic_write

    written = []
    for name, data in artefacts.items():
        path = out / name
        if name.endswith(".npz"):
            atomic_write(path, lambda fh, d=data: np.savez_compressed(fh, **d), binary=True)
        elif name.endswith(".json"):
            write_json(path, data)
        else:
            raise ValueError(f"artefact {name!r}: expected a .json or .npz file name")
        written.append(path)
    return written
