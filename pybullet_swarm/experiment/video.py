"""Videos of runs: Bullet's renderer through an arena camera, and a streaming MP4 (or GIF) writer.

Frames come from ``World.render`` (the tiny software renderer, which works in DIRECT mode).
MP4 (H.264, yuv420p) is written through the ffmpeg binary shipped in the ``imageio-ffmpeg``
wheel; when that is not importable the writer falls back to an animated GIF written with
Pillow next to the requested path.
"""

from __future__ import annotations

import enum
import functools
import math
import os
import secrets
import sys
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from pybullet_swarm.world.camera import RENDER_FOV_DEG, Camera, camera_for_arena

if TYPE_CHECKING:
    from pybullet_swarm.world.world import World

__all__ = [
    "RENDER_FOV_DEG",
    "Camera",
    "VideoBackend",
    "VideoWriter",
    "camera_for_arena",
    "render_frame",
    "video_backend",
]

GIF_MAX_FPS = 10.0  # frames per second kept by the GIF fallback
GIF_COLORS = 64  # palette size of each GIF frame
MP4_CRF = 28  # x264 constant rate factor: 23 is x264's default, higher is smaller
MP4_PRESET = "medium"


class VideoBackend(str, enum.Enum):
    """Container a ``VideoWriter`` produces."""

    MP4 = "mp4"  # H.264 through imageio-ffmpeg
    GIF = "gif"  # animated GIF through Pillow

    def __str__(self) -> str:
        return self.value


@functools.cache
def _ffmpeg_exe() -> str | None:
    """Path of imageio-ffmpeg's ffmpeg binary, or None when it is unavailable."""
    try:
        import imageio_ffmpeg

        return str(imageio_ffmpeg.get_ffmpeg_exe())
    except Exception:  # ImportError, or RuntimeError when no binary is found
        return None


def video_backend() -> VideoBackend:
    """Backend a ``VideoWriter`` would use here: ``"mp4"`` when imageio-ffmpeg works, else ``"gif"``."""
    return VideoBackend.MP4 if _ffmpeg_exe() is not None else VideoBackend.GIF


# ----------------------------------------------------------------------------------- camera
# the camera is the world layer's (pybullet_swarm.world.camera); its names stay importable from here


def render_frame(world: World, camera: Camera, size: tuple[int, int]) -> NDArray[np.uint8]:
    """Render an RGB frame (height, width, 3) uint8 of ``world`` seen by ``camera``; ``size`` is (width, height) px."""
    width, height = size
    return world.render(
        int(width), int(height), target=camera.target, distance=camera.distance, yaw=camera.yaw, pitch=camera.pitch
    )


# ----------------------------------------------------------------------------------- writer
class _Mp4Sink:
    """Frames piped to an ffmpeg process as they come."""

    def __init__(self, path: Path, size: tuple[int, int], fps: int) -> None:
        import imageio_ffmpeg

        self._gen = imageio_ffmpeg.write_frames(
            str(path),
            size,
            fps=fps,
            codec="libx264",
            pix_fmt_in="rgb24",
            pix_fmt_out="yuv420p",
            quality=None,
            macro_block_size=2,
            ffmpeg_log_level="error",
            output_params=["-crf", str(MP4_CRF), "-preset", MP4_PRESET, "-movflags", "+faststart", "-f", "mp4"],
        )
        self._gen.send(None)  # starts ffmpeg

    def add(self, frame: NDArray[np.uint8]) -> None:
        self._gen.send(np.ascontiguousarray(frame))

    def finish(self) -> None:
        self._gen.close()  # closes ffmpeg's stdin and waits for it

    def abort(self) -> None:
        try:
            self._gen.close()
        except Exception:
            pass


class _GifSink:
    """Every ``stride``-th frame kept in memory as a palette image (1 byte per pixel), saved at the end."""

    def __init__(self, path: Path, fps: int) -> None:
        self._path = path
        self._stride = max(1, math.ceil(fps / GIF_MAX_FPS))
        self._duration_ms = round(1000.0 * self._stride / fps)
        self._seen = 0
        self._frames: list[Any] = []

    def add(self, frame: NDArray[np.uint8]) -> None:
        from PIL import Image

        if self._seen % self._stride == 0:
            self._frames.append(
                Image.fromarray(frame).quantize(GIF_COLORS, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
            )
        self._seen += 1

    def finish(self) -> None:
        first, *rest = self._frames
        first.save(
            self._path,
            format="GIF",
            save_all=True,
            append_images=rest,
            duration=self._duration_ms,
            loop=0,
            optimize=False,
            disposal=1,
        )
        self._frames.clear()

    def abort(self) -> None:
        self._frames.clear()


class VideoWriter:
    """Write RGB frames to a video file, streaming them to the encoder.

    MP4 (H.264, yuv420p, CRF ``MP4_CRF``) when imageio-ffmpeg is importable; otherwise an
    animated GIF at ``path.with_suffix(".gif")`` with at most ``GIF_MAX_FPS`` frames per second
    and ``GIF_COLORS`` colours per frame (the GIF frames are kept in memory until ``close``).
    The file is encoded under a hidden temporary name in the same directory and renamed on
    ``close``, so ``path`` is either absent, the previous file, or the complete video.

    Args:
        path: output file; its suffix is replaced by ``.mp4`` or ``.gif``.
        fps: frames per second of the frames added.
        size: (width, height) px of every frame; both even (yuv420p halves the chroma).
        progress_total: number of frames expected, for the progress bar (stderr).
        quiet: no progress bar.
        backend: force a backend (``"mp4"`` or ``"gif"``); None picks ``video_backend()``.

    Raises:
        ValueError: bad fps or size, or a backend that is not a ``VideoBackend``.
        RuntimeError: ``backend="mp4"`` forced without a working imageio-ffmpeg.
        FileNotFoundError: the directory of ``path`` does not exist.
    """

    def __init__(
        self,
        path: Path,
        *,
        fps: int = 20,
        size: tuple[int, int] = (480, 270),
        progress_total: int | None = None,
        quiet: bool = False,
        backend: VideoBackend | str | None = None,
    ) -> None:
        if not (isinstance(fps, (int, np.integer)) and fps > 0):
            raise ValueError(f"fps: expected a positive integer, got {fps!r}")
        width, height = (int(v) for v in size)
        if width <= 0 or height <= 0 or width % 2 or height % 2:
            raise ValueError(f"size: expected a positive even (width, height) in px, got {tuple(size)!r}")
        self.backend = video_backend() if backend is None else VideoBackend(backend)
        if self.backend is VideoBackend.MP4 and _ffmpeg_exe() is None:
            raise RuntimeError("backend 'mp4' needs imageio-ffmpeg: pip install imageio imageio-ffmpeg")
        path = Path(path)
        if not path.parent.is_dir():
            raise FileNotFoundError(f"video directory does not exist: {path.parent}")
        self.path = path.with_suffix(f".{self.backend.value}")
        self.fps = int(fps)
        self.size = (width, height)
        self.frames_written = 0
        self._tmp = self.path.with_name(f".{self.path.stem}.{os.getpid()}.{secrets.token_hex(4)}.tmp{self.path.suffix}")
        self._sink: _Mp4Sink | _GifSink | None = None  # opened with the first frame
        self._closed = False
        self._bar = tqdm(
            total=progress_total,
            desc=self.path.name,
            unit="frame",
            file=sys.stderr,
            disable=quiet,
            dynamic_ncols=True,
            mininterval=1.0,
        )

    def add(self, frame: NDArray[np.uint8]) -> None:
        """Append one RGB frame (height, width, 3) uint8."""
        if self._closed:
            raise ValueError(f"{self.path}: frame added after close()")
        width, height = self.size
        if frame.shape != (height, width, 3) or frame.dtype != np.uint8:
            raise ValueError(f"frame: expected ({height}, {width}, 3) uint8, got {frame.shape} {frame.dtype}")
        if self._sink is None:
            self._sink = (
                _Mp4Sink(self._tmp, self.size, self.fps)
                if self.backend is VideoBackend.MP4
                else _GifSink(self._tmp, self.fps)
            )
        try:
            self._sink.add(frame)
        except BaseException:
            self._abort()
            raise
        self.frames_written += 1
        self._bar.update(1)

    def close(self) -> Path:
        """Finish encoding, move the file into place and return its path.

        Raises:
            ValueError: no frame was added (nothing is written).
        """
        if self._closed:
            if self.frames_written == 0:
                raise ValueError(f"{self.path}: no frames were added; nothing was written")
            return self.path
        self._bar.close()
        if self._sink is None:
            self._closed = True
            raise ValueError(f"{self.path}: no frames were added; nothing was written")
        try:
            self._sink.finish()
            os.replace(self._tmp, self.path)
        except BaseException:
            self._abort()
            raise
        self._closed = True
        return self.path

    def _abort(self) -> None:
        """Stop the encoder and delete the temporary file (the output path is left untouched)."""
        self._closed = True
        self._bar.close()
        if self._sink is not None:
            self._sink.abort()
        self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc_type is not None:
            self._abort()
        elif not self._closed:
            self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort
        # A writer dropped without close() leaves no temporary file or ffmpeg process behind.
        try:
            if not self._closed:
                self._abort()
        except Exception:
            pass
