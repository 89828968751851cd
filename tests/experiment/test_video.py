"""Video writer (MP4 and GIF fallback), arena camera and a real render from DIRECT mode."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from pybullet_swarm.experiment import video
from pybullet_swarm.experiment.video import (
    Camera,
    VideoBackend,
    VideoWriter,
    camera_for_arena,
    render_frame,
    video_backend,
)
from pybullet_swarm.world.world import World

SIZE = (480, 270)  # (width, height) px


def _synthetic(n: int, size: tuple[int, int] = SIZE) -> list[np.ndarray]:
    """n frames (h, w, 3) uint8 of a square moving over a gradient."""
    w, h = size
    base = np.zeros((h, w, 3), np.uint8)
    base[..., 0] = np.linspace(0, 255, w, dtype=np.uint8)[None, :]
    base[..., 2] = np.linspace(255, 0, h, dtype=np.uint8)[:, None]
    frames = []
    for i in range(n):
        f = base.copy()
        x = 10 + 10 * i
        f[100:140, x : x + 40] = (255, 255, 0)
        frames.append(f)
    return frames


@pytest.fixture
def arena_world():
    """A world with the ground, a 3 x 1 m orange floor tile and one small box on it."""
    world = World(physics_hz=240)
    world.add_ground()
    world.add_box([1.5, 0.5, 0.005], [3.0, 1.0, 0.01], color=(1.0, 0.5, 0.0, 1.0))
    world.add_box([1.5, 0.5, 0.06], [0.1, 0.1, 0.1], mass=0.01, color=(0.0, 0.0, 1.0, 1.0))
    yield world
    world.close()


def test_backend_is_mp4_with_imageio_ffmpeg_installed():
    pytest.importorskip("imageio_ffmpeg")
    assert video_backend() is VideoBackend.MP4
    assert video_backend() == "mp4" and f"{video_backend()}" == "mp4"


@pytest.fixture
def without_imageio_ffmpeg(monkeypatch):
    """Make ``import imageio_ffmpeg`` fail, as on an install without it."""
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)
    video._ffmpeg_exe.cache_clear()
    yield
    video._ffmpeg_exe.cache_clear()


def test_without_imageio_ffmpeg_falls_back_to_gif(tmp_path, without_imageio_ffmpeg):
    assert video_backend() is VideoBackend.GIF
    with VideoWriter(tmp_path / "run.mp4", quiet=True) as vw:
        for f in _synthetic(4):
            vw.add(f)
    assert vw.close() == tmp_path / "run.gif" and vw.close().is_file()
    with pytest.raises(RuntimeError, match="imageio-ffmpeg"):
        VideoWriter(tmp_path / "run.mp4", quiet=True, backend="mp4")


def test_mp4_of_synthetic_frames_reads_back(tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    iio = pytest.importorskip("imageio.v2")
    with VideoWriter(tmp_path / "run.mp4", fps=20, quiet=True, backend="mp4") as vw:
        for f in _synthetic(30):
            vw.add(f)
    out = vw.close()  # idempotent after the context manager closed it
    assert out == tmp_path / "run.mp4"
    assert out.stat().st_size > 1000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mp4"]  # no temporary left behind
    reader = iio.get_reader(out, format="FFMPEG")
    try:
        frames = [np.asarray(f) for f in reader]
        assert reader.get_meta_data()["fps"] == pytest.approx(20.0)
    finally:
        reader.close()
    assert len(frames) == 30
    assert frames[0].shape == (270, 480, 3)
    # lossy, but the moving square is where it was drawn
    np.testing.assert_allclose(frames[5][110:130, 70:90].mean(axis=(0, 1)), (255, 255, 0), atol=25)


def test_gif_fallback_is_small_and_subsampled(tmp_path):
    from PIL import Image

    vw = VideoWriter(tmp_path / "run.mp4", fps=20, quiet=True, backend="gif")
    for f in _synthetic(30):
        vw.add(f)
    out = vw.close()
    assert out == tmp_path / "run.gif"
    assert 1000 < out.stat().st_size < 1_000_000
    with Image.open(out) as im:
        assert im.size == SIZE
        assert im.n_frames == 15  # 20 fps kept at 10 fps
        assert im.info["duration"] == 100


def test_zero_frames_raise_and_write_nothing(tmp_path):
    for backend in ("mp4", "gif") if video_backend() is VideoBackend.MP4 else ("gif",):
        vw = VideoWriter(tmp_path / "empty.mp4", quiet=True, backend=backend)
        with pytest.raises(ValueError, match="no frames"):
            vw.close()
    with pytest.raises(ValueError, match="no frames"):
        with VideoWriter(tmp_path / "empty.mp4", quiet=True):
            pass
    assert list(tmp_path.iterdir()) == []


def test_error_inside_context_leaves_no_file(tmp_path):
    with pytest.raises(RuntimeError, match="boom"):
        with VideoWriter(tmp_path / "run.mp4", quiet=True) as vw:
            vw.add(_synthetic(1)[0])
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_bad_frames_and_sizes_are_refused(tmp_path):
    with pytest.raises(ValueError, match="even"):
        VideoWriter(tmp_path / "odd.mp4", size=(481, 270), quiet=True)
    with pytest.raises(ValueError, match="fps"):
        VideoWriter(tmp_path / "x.mp4", fps=0, quiet=True)
    with pytest.raises(FileNotFoundError):
        VideoWriter(tmp_path / "missing" / "x.mp4", quiet=True)
    with VideoWriter(tmp_path / "x.mp4", quiet=True, backend="gif") as vw:
        with pytest.raises(ValueError, match=r"\(270, 480, 3\) uint8"):
            vw.add(np.zeros((270, 480, 3), np.float32))
        vw.add(np.zeros((270, 480, 3), np.uint8))


def test_camera_is_validated_and_frozen():
    cam = Camera((1, 2, 3), 2, 0, -45)
    assert cam.target == (1.0, 2.0, 3.0)
    with pytest.raises(ValueError, match="distance"):
        Camera((0, 0, 0), 0.0, 0.0, -45.0)
    with pytest.raises(ValueError, match="size_xy"):
        camera_for_arena((3.0, -1.0))
    # yaw 0 looks along +y from the -y side, down at 45 deg
    np.testing.assert_allclose(cam.eye(), [1.0, 2.0 - np.sqrt(2.0), 3.0 + np.sqrt(2.0)], atol=1e-12)


def test_camera_for_arena_keeps_the_long_side_across():
    wide, tall = camera_for_arena((3.0, 1.0)), camera_for_arena((1.0, 3.0))
    assert (wide.yaw, tall.yaw) == (0.0, 90.0)
    assert wide.pitch == pytest.approx(-45.0)
    assert wide.distance == pytest.approx(tall.distance)
    assert wide.target[0] == pytest.approx(1.5) and tall.target[1] == pytest.approx(1.5)


def test_real_render_frames_the_arena(arena_world):
    camera = camera_for_arena((3.0, 1.0))
    frame = render_frame(arena_world, camera, SIZE)
    assert frame.shape == (270, 480, 3) and frame.dtype == np.uint8
    assert np.ptp(frame.reshape(-1, 3), axis=0).max() > 50  # not a constant image
    floor = (frame[..., 0] > 200) & (frame[..., 1] > 90) & (frame[..., 1] < 160) & (frame[..., 2] < 60)
    cols = np.flatnonzero(floor.any(axis=0))
    rows = np.flatnonzero(floor.any(axis=1))
    assert cols.size and rows.size
    assert 0 < cols[0] and cols[-1] < 479  # the whole floor is in view ...
    assert cols[-1] - cols[0] > 0.65 * 480  # ... and spans most of the width
    assert 0 < rows[0] and rows[-1] < 269
    assert (frame[..., 2] > 150).any() and ((frame[..., 2] > 150) & (frame[..., 0] < 50)).any()  # the blue box


def test_rendered_frames_to_mp4(arena_world, tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    camera = camera_for_arena((3.0, 1.0))
    with VideoWriter(tmp_path / "render.mp4", quiet=True) as vw:
        for _ in range(5):
            arena_world.step()
            vw.add(render_frame(arena_world, camera, vw.size))
    assert vw.close().stat().st_size > 1000
