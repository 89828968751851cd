"""Scripted runs: load a scenario, simulate it, optionally write a run directory."""

from __future__ import annotations

import dataclasses
import functools
import math
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
    speed: float | None = None,
    report: bool = False,
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
        gui: watch in the Bullet GUI: the camera frames the arena, the run is paced to ``speed`` x
            real time, agents are coloured as in the replay and a heads-up line is shown.
        plots: draw the figures into ``out/plots`` (only with ``out``).
        video: render ``out/video.mp4`` after the run, a replay of the saved results
            (``experiment.replay``; ``.gif`` when no MP4 encoder is installed; needs ``out``).
        speed: with ``gui``, simulated seconds per wall-clock second (default 1: real time); with
            ``video``, simulated seconds per second of video (default ``replay.DEFAULT_SPEED``).
        report: write ``out/report.html`` (``experiment.report``).
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

        check_run_dir(Path(out))  # before the simulation: a directory it could not write is refused now
    if speed is not None and not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed: expected a positive number, got {speed!r}")
    with Simulation(scenario, gui=gui) as sim:
        result = _watch(sim, 1.0 if speed is None else speed) if gui else sim.run()
    if out is not None:
        run_dir = write_run(result, Path(out), plots=plots, video=video, video_speed=speed, report=report, quiet=quiet)
        result = dataclasses.replace(result, run_dir=run_dir)
    return result


def build_run(scenario: Scenario) -> None:
    """Build the run ``scenario`` describes (world, task, controller, planner, avoidance layer) and
    close it without stepping: what a run refuses when it starts (a planner's rule that needs the
    task's geometry, say) is refused here too. ``pybullet-swarm check`` calls it.

    Raises:
        ConfigError: one line naming the file and the field.
    """
    with Simulation(scenario):
        pass


def _watch(sim: Simulation, speed: float) -> RunResult:
    """Run in the Bullet GUI, one control period at a time, paced to ``speed`` x real time."""
    from pybullet_swarm.experiment.gui import GuiViewer
    from pybullet_swarm.types import ExitStatus

    viewer = GuiViewer(sim, speed=speed)
    while sim.exit_status is ExitStatus.RUNNING:
        sim.step()
        viewer.update()
    return sim.result()


def write_run(
    result: RunResult,
    out: Path,
    *,
    plots: bool = True,
    video: bool = False,
    video_speed: float | None = None,
    report: bool = False,
    quiet: bool = True,
) -> Path:
    """Write ``scenario.yaml``, ``timeseries.npz``, ``events.csv``, the artefacts' files, ``plots/``,
    ``video.mp4`` (with ``video``), ``metrics.json`` (it marks a finished run), then ``report.html``
    (with ``report``).

    A previous run's files in ``out`` are removed first (``rundir.clear_run_dir``): the directory
    then holds this run only.
    """
    from pybullet_swarm.experiment.rundir import atomic_write, clear_run_dir

    clear_run_dir(out)
    out.mkdir(parents=True, exist_ok=True)
    write_yaml(out / "scenario.yaml", dict(result.scenario.data))  # resolved: planner, avoidance, seed, parameters
    atomic_write(out / "timeseries.npz", result.timeseries.save_to, binary=True)
    write_events(out / "events.csv", result.events)
    write_artefacts(out, result.artifacts)
    if plots:
        from pybullet_swarm.plotting.run_plots import plot_run, plot_saved_artifacts

        plot_run(result.timeseries, out / "plots", result.metrics, scenario=result.scenario.data, events=result.events)
        plot_saved_artifacts(out, out / "plots")
    if video:
        from pybullet_swarm.experiment.replay import render_replay
        from pybullet_swarm.plotting.replay import DEFAULT_SPEED

        written = render_replay(
            out, out / "video.mp4", speed=video_speed or DEFAULT_SPEED, metrics=result.metrics, quiet=quiet
        )
        result.metrics["video"] = written.name
    write_json(out / "metrics.json", result.metrics)  # its presence marks a finished run
    if report:
        from pybullet_swarm.experiment.report import write_run_report

        write_run_report(out)
    return out


def _savez(data: Mapping[str, Any], fh: Any) -> None:
    import numpy as np

    np.savez_compressed(fh, **data)


def write_artefacts(out: Path, artefacts: dict[str, Any]) -> list[Path]:
    """Write a run's artefacts (data by file name: ``.json`` plain data, ``.npz`` arrays by name) atomically."""

    from pybullet_swarm.experiment.rundir import atomic_write

    written = []
    for name, data in artefacts.items():
        path = out / name
        if name.endswith(".npz"):
            atomic_write(path, functools.partial(_savez, data), binary=True)
        elif name.endswith(".json"):
            write_json(path, data)
        else:
            raise ValueError(f"artefact {name!r}: expected a .json or .npz file name")
        written.append(path)
    return written
