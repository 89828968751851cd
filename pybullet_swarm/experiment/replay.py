"""Replays of finished runs written from their run directories: a video (``replay RUN_DIR``, ``run
--video``) or one frame as a PNG (``replay --frame T``). The frames are drawn by
``plotting.replay`` from the saved results; nothing is simulated again."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.results import read_events, read_scenario_data
from pybullet_swarm.plotting.replay import (
    DEFAULT_FPS,
    DEFAULT_SIZE,
    DEFAULT_SPEED,
    ReplayData,
    ReplayOptions,
    ReplayRenderer,
    View,
    replay_data,
)
from pybullet_swarm.types import TimeSeries


def load_replay(run_dir: Path | str, metrics: Mapping[str, Any] | None = None) -> ReplayData:
    """Read what a replay draws from a run directory.

    Args:
        run_dir: the run directory.
        metrics: the run's metrics (default: ``metrics.json`` when present), for the title line.

    Raises:
        ConfigError: not a run directory (no ``timeseries.npz``), or a run without samples.
    """
    run_dir = Path(run_dir)
    npz = run_dir / "timeseries.npz"
    if not npz.is_file():
        raise ConfigError("not a run directory (no timeseries.npz)", source=str(run_dir))
    ts = TimeSeries.load(npz)
    if ts.t.size == 0:
        raise ConfigError("the run recorded no samples (nothing to replay)", source=str(npz))
    if metrics is None:
        path = run_dir / "metrics.json"
        metrics = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}
    scenario = read_scenario_data(run_dir) or {"name": run_dir.name}
    pheromones = None
    if (run_dir / "pheromones.npz").is_file():
        with np.load(run_dir / "pheromones.npz") as z:
            pheromones = {k: z[k] for k in z.files}
    return replay_data(ts, read_events(run_dir / "events.csv"), scenario, metrics, pheromones)


def _options(**kw: Any) -> ReplayOptions:
    try:
        return ReplayOptions(**kw)
    except ValueError as exc:
        raise ConfigError(str(exc), source="replay") from None


def render_replay(
    run_dir: Path | str,
    out: Path | str | None = None,
    *,
    view: View | str = View.THREE_D,
    speed: float = DEFAULT_SPEED,
    size: tuple[int, int] = DEFAULT_SIZE,
    fps: int = DEFAULT_FPS,
    metrics: Mapping[str, Any] | None = None,
    quiet: bool = True,
) -> Path:
    """Render the replay video of a finished run.

    Args:
        run_dir: the run directory.
        out: video file (default ``run_dir/video.mp4``); ``.gif`` replaces the suffix without an MP4 encoder.
        view: ``top``, ``chase``, ``orbit`` or ``3d``.
        speed: simulated seconds per second of video.
        size: (width, height) px, both even.
        fps: frames per second.
        metrics: the run's metrics (default: ``metrics.json``), for the title line.
        quiet: no progress bar.

    Returns:
        The video file written.

    Raises:
        ConfigError: not a run directory, or bad options.
    """
    from pybullet_swarm.experiment.video import VideoWriter

    run_dir = Path(run_dir)
    options = _options(view=View(view), speed=float(speed), size=size, fps=int(fps))
    renderer = ReplayRenderer(load_replay(run_dir, metrics), options)
    path = Path(out) if out is not None else run_dir / "video.mp4"
    path.parent.mkdir(parents=True, exist_ok=True)
    times = renderer.times()
    with VideoWriter(path, fps=options.fps, size=options.size, progress_total=len(times), quiet=quiet) as writer:
        for t in times:
            writer.add(renderer.frame(float(t)))
    return writer.path


def still_png(
    data: ReplayData, t: float, *, view: View | str = View.THREE_D, size: tuple[int, int] = DEFAULT_SIZE
) -> bytes:
    """PNG bytes of the one frame of a replay at simulated time ``t`` s (no playback speed shown)."""
    import io

    from PIL import Image

    frame = ReplayRenderer(data, _options(view=View(view), size=size, show_speed=False)).frame(float(t))
    buf = io.BytesIO()
    Image.fromarray(frame).save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def render_still(
    run_dir: Path | str,
    t: float,
    out: Path | str | None = None,
    *,
    view: View | str = View.THREE_D,
    size: tuple[int, int] = DEFAULT_SIZE,
    metrics: Mapping[str, Any] | None = None,
) -> Path:
    """Write the one frame of a run's replay at simulated time ``t`` s as a PNG.

    Args:
        run_dir: the run directory.
        t: s, within the recorded samples.
        out: PNG file (default ``run_dir/frame.png``).
        view: ``top``, ``chase``, ``orbit`` or ``3d``.
        size: (width, height) px, both even.
        metrics: the run's metrics (default: ``metrics.json``), for the title line.

    Raises:
        ConfigError: not a run directory, bad options, or ``t`` outside the recorded samples.
    """
    from pybullet_swarm.experiment.rundir import atomic_write

    run_dir = Path(run_dir)
    _options(view=View(view), size=size)
    data = load_replay(run_dir, metrics)
    t0, t1 = float(data.t[0]), float(data.t[-1])
    if not (math.isfinite(t) and t0 - 1e-6 <= t <= t1 + 1e-6):
        raise ConfigError(f"expected a time within the recorded {t0:g} .. {t1:g} s, got {t:g}", source="--frame")
    png = still_png(data, min(max(t, t0), t1), view=view, size=size)
    path = Path(out) if out is not None else run_dir / "frame.png"
    atomic_write(path, lambda fh: fh.write(png), binary=True)
    return path
