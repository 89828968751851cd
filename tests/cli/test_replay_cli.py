"""``pybullet-swarm replay`` and ``report``, and what ``run`` prints about them."""

from __future__ import annotations

from pathlib import Path

import pytest

from pybullet_swarm.cli.main import REPLAY_VIEWS, main

PREFIX = "pybullet-swarm: error: "


def run_cli(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 1 s construction run made by ``pybullet-swarm run`` (no figures)."""
    out = tmp_path_factory.mktemp("cli") / "run"
    argv = ["run", "construction", "--set", "task.time_limit_s=1", "--no-plots", "--quiet", "--out", str(out)]
    assert main(argv) == 0
    return out


def test_run_prints_where_the_report_is(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r"
    code, stdout, stderr = run_cli(
        capsys, ["run", "construction", "--set", "task.time_limit_s=0.5", "--no-plots", "--out", str(out)]
    )
    assert code == 0, stderr
    assert stdout.splitlines()[-1] == f"report: {out / 'report.html'}"
    assert (out / "report.html").is_file()


def test_run_video_is_a_replay_at_the_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import imageio_ffmpeg

    out = tmp_path / "v"
    code, stdout, stderr = run_cli(
        capsys,
        [
            "run",
            "construction",
            "--set",
            "task.time_limit_s=1",
            "--no-plots",
            "--video",
            "--speed",
            "2",
            "--out",
            str(out),
        ],
    )
    assert code == 0, stderr
    assert f"video: {out / 'video.mp4'}" in stdout
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(out / "video.mp4"))
    assert frames == 12  # samples from 0.05 s to 1.0 s, 2x at 25 fps: floor(0.95 * 25 / 2) + 1


def test_replay_writes_the_video(run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    video = tmp_path / "top.mp4"
    code, stdout, stderr = run_cli(
        capsys,
        ["replay", str(run_dir), "--view", "top", "--speed", "4", "--size", "320x180", "--out", str(video), "--quiet"],
    )
    assert code == 0, stderr
    assert stdout == "" and video.is_file() and video.stat().st_size > 1000
    code, stdout, _ = run_cli(
        capsys,
        [
            "replay",
            str(run_dir),
            "--view",
            "orbit",
            "--speed",
            "8",
            "--size",
            "320x180",
            "--out",
            str(tmp_path / "orbit.mp4"),
        ],
    )
    assert code == 0 and stdout.strip() == str(tmp_path / "orbit.mp4")


def test_replay_frame_writes_one_png(run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from PIL import Image

    code, stdout, stderr = run_cli(
        capsys, ["replay", str(run_dir), "--frame", "0.5", "--size", "640x360", "--out", str(tmp_path / "f.png")]
    )
    assert code == 0, stderr
    assert stdout.strip() == str(tmp_path / "f.png")
    with Image.open(tmp_path / "f.png") as im:
        assert im.format == "PNG" and im.size == (640, 360)
    code, _, stderr = run_cli(capsys, ["replay", str(run_dir), "--frame", "7", "--out", str(tmp_path / "g.png")])
    assert code == 2 and "--frame: expected a time within the recorded 0.05 .. 1 s, got 7" in stderr
    assert not (tmp_path / "g.png").exists()


def test_report_writes_the_page(run_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, stdout, _ = run_cli(capsys, ["report", str(run_dir)])
    assert code == 0 and stdout.strip() == str(run_dir / "report.html")


@pytest.mark.parametrize(
    "args, message",
    [
        (["--size", "321x180"], "--size: expected WIDTHxHEIGHT in px, both even and >= 64"),
        (["--size", "big"], "--size: expected WIDTHxHEIGHT"),
        (["--speed", "0"], "--speed: expected a positive number, got '0'"),
        (["--speed", "nan"], "--speed: expected a positive number"),
        (["--view", "side"], "--view: invalid choice: 'side'"),
    ],
)
def test_bad_replay_options_are_one_line_and_exit_2(
    run_dir: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    code, _, stderr = run_cli(capsys, ["replay", str(run_dir), *args])
    assert code == 2 and stderr.startswith(PREFIX) and message in stderr and stderr.count("\n") == 1


def test_replay_and_report_refuse_what_is_not_a_result(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for command in ("replay", "report"):
        code, _, stderr = run_cli(capsys, [command, str(tmp_path)])
        assert code == 2 and "not a run directory" in stderr and stderr.count("\n") == 1


def test_the_parser_knows_every_view() -> None:
    from pybullet_swarm.plotting.replay import View

    assert REPLAY_VIEWS == tuple(v.value for v in View)
