"""Replays written from run directories: what the time series records for them, a video's frames, a
still, and runs recorded before the carriers were."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pybullet_swarm.experiment.replay import load_replay, render_replay, render_still
from pybullet_swarm.plotting.replay import _carried_from_events, frame_times


@pytest.fixture(scope="module")
def construction_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 6 s construction run of the stigmergy planner (the first grasps happen after ~4.7 s)."""
    from pybullet_swarm.experiment.runner import run

    out = tmp_path_factory.mktemp("replay") / "run"
    run("construction", planner="stigmergy", out=out, plots=False, overrides={"task.time_limit_s": 6.0})
    return out


def test_time_series_records_box_poses_and_carriers(construction_run: Path) -> None:
    from pybullet_swarm.experiment.results import read_events
    from pybullet_swarm.types import TimeSeries

    ts = TimeSeries.load(construction_run / "timeseries.npz")
    m = ts.t.size
    assert ts.extra["box_positions"].shape == (m, 9, 3)
    assert ts.extra["box_quaternions"].shape == (m, 9, 4)
    assert np.allclose(np.linalg.norm(ts.extra["box_quaternions"], axis=2), 1.0, atol=1e-5)
    carried = ts.extra["box_carried_by"]
    assert carried.shape == (m, 9) and carried[0].tolist() == [-1] * 9
    grasps = [e for e in read_events(construction_run / "events.csv") if e.kind == "grasp" and e.time_s < 5.9]
    assert grasps
    for e in grasps:  # the sample at the grasp's instant was taken before it, the next one holds the box
        k = int(np.searchsorted(ts.t, e.time_s + 1e-4))
        assert carried[k - 1, int(e.b[3:])] == -1 and carried[k, int(e.b[3:])] == int(e.a[5:])
    data = load_replay(construction_run)
    assert np.array_equal(data.box_carried_by, _carried_from_events(data.t, 9, data.events))


def test_replay_of_a_run_directory_writes_the_frames(construction_run: Path, tmp_path: Path) -> None:
    import imageio_ffmpeg

    data = load_replay(construction_run)
    out = render_replay(construction_run, tmp_path / "r.mp4", view="top", speed=2.0, size=(320, 180), fps=10)
    assert out == tmp_path / "r.mp4"
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert frames == frame_times(float(data.t[0]), float(data.t[-1]), 2.0, 10).size == 30  # floor(5.95 s * 10 / 2) + 1
    reader = imageio_ffmpeg.read_frames(str(out))
    meta = next(reader)
    assert tuple(meta["size"]) == (320, 180)
    reader.close()


def test_still_of_a_run_directory(construction_run: Path, tmp_path: Path) -> None:
    from PIL import Image

    out = render_still(construction_run, 5.0, tmp_path / "s.png", view="top", size=(640, 360))
    with Image.open(out) as im:
        assert im.format == "PNG" and im.size == (640, 360)


def test_run_recorded_without_carriers_takes_them_from_events(construction_run: Path, tmp_path: Path) -> None:
    import dataclasses
    import shutil

    from pybullet_swarm.types import TimeSeries

    old = tmp_path / "old"
    shutil.copytree(construction_run, old)
    ts = TimeSeries.load(old / "timeseries.npz")
    extra = {k: v for k, v in ts.extra.items() if k not in ("box_carried_by", "box_quaternions")}
    dataclasses.replace(ts, extra=extra).save(old / "timeseries.npz")
    new, was = load_replay(old), load_replay(construction_run)
    assert np.array_equal(new.box_carried_by, was.box_carried_by)
    assert np.allclose(new.box_quaternions[..., 3], 1.0)  # upright, as recorded runs before them
