"""Report pages of a run and of a sweep: content, figures that resolve, and a real headless browser
(Chromium) rendering them."""

from __future__ import annotations

import base64
import csv
import html.parser
import io
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.report import REPORT_NAME, write_run_report
from pybullet_swarm.experiment.sweep_report import write_sweep_report


class _Page(html.parser.HTMLParser):
    """Sources of <img> and <video>, the text of table cells, and the hrefs of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.images: list[str] = []
        self.videos: list[str] = []
        self.links: list[str] = []
        self.cells: list[str] = []
        self._cell: list[str] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "img":
            self.images.append(a.get("src") or "")
        elif tag == "video":
            self.videos.append(a.get("src") or "")
        elif tag == "a":
            self.links.append(a.get("href") or "")
        elif tag in ("td", "th"):
            self._cell = []

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "th") and self._cell is not None:
            self.cells.append("".join(self._cell).strip())
            self._cell = None


def parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def assert_sources_resolve(page_path: Path, sources: list[str]) -> None:
    """Every source is a data URI of a PNG that decodes, or a file beside the page."""
    assert sources
    for src in sources:
        if src.startswith("data:"):
            assert src.startswith("data:image/png;base64,")
            data = base64.b64decode(src.split(",", 1)[1], validate=True)
            with Image.open(io.BytesIO(data)) as im:
                assert im.format == "PNG"
                im.load()
                assert im.width > 100 and im.height > 100
        else:
            assert "://" not in src and not src.startswith("/")  # relative: the directory moves as a whole
            assert (page_path.parent / src).is_file(), src


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 3 s construction run with one figure, a small replay video and its report."""
    from pybullet_swarm.experiment.runner import run
    from pybullet_swarm.plotting.run_plots import plot_positions
    from pybullet_swarm.types import TimeSeries

    out = tmp_path_factory.mktemp("report") / "run"
    run(
        "construction",
        planner="stigmergy",
        out=out,
        plots=False,
        video=True,
        speed=8.0,
        overrides={"task.time_limit_s": 3.0},
    )
    plot_positions(TimeSeries.load(out / "timeseries.npz"), out / "plots" / "position.png")
    write_run_report(out)
    return out


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny sweep: two configurations of a 1 s hover, one seed, one comparison figure, a report for
    one of its runs."""
    from pybullet_swarm.experiment.sweep import Sweep, draw_comparison, load_sweep, run_sweep

    overrides = {
        "task.time_limit_s": 1.0,
        "task.relative": False,
        "task.hold_s": 0.2,
        "task.tolerance_m": 0.1,
        "task.waypoints": [{"t_s": 0.0, "position": [1.5, 1.5, 0.3]}],
        "agents.start_jitter": 0.05,
    }
    out = tmp_path_factory.mktemp("report") / "sweep"
    run_sweep(
        Sweep("hover", grid={"limits.velocity": [0.5, 1.0]}, seeds=1, overrides=overrides),
        out,
        workers=1,
        figures=False,
    )
    rows, group_by = load_sweep(out)
    draw_comparison(rows, group_by, out / "plots", ["sim_time_s", "energy_j"])
    write_run_report(out / str(rows[0]["run_dir"]))
    write_sweep_report(out)
    return out


def test_run_report_holds_scenario_metrics_figures_and_events(run_dir: Path) -> None:
    from pybullet_swarm.experiment.results import flatten_metrics, read_events, read_metrics

    path = run_dir / REPORT_NAME
    assert path.is_file()
    page = parse(path)
    metrics = flatten_metrics(read_metrics(run_dir))
    assert metrics["video"] == "video.mp4"
    for key in ("exit_status", "sim_time_s", "boxes_placed", "collisions.agent_agent"):
        assert key in page.cells
    assert page.cells[page.cells.index("sim_time_s") + 1] == "3"
    figures = sorted((run_dir / "plots").glob("*.png"))
    # every figure of plots/, the still of the last instant and the events timeline
    assert len(page.images) == len(figures) + 2
    assert_sources_resolve(path, page.images)
    assert page.videos == ["video.mp4"]
    assert_sources_resolve(path, page.videos)
    events = read_events(run_dir / "events.csv")
    assert events
    header = page.cells.index("detail")
    rows = page.cells[header + 1 :]
    assert len(rows) == 5 * len(events)
    assert [r for r in rows[1::5]] == [e.kind for e in events]


def test_sweep_report_holds_the_comparison_with_intervals(sweep_dir: Path) -> None:
    path = sweep_dir / REPORT_NAME
    page = parse(path)
    with open(sweep_dir / "summary.csv", newline="") as fh:
        summary = list(csv.DictReader(fh))
    configs = list(dict.fromkeys(r["config"] for r in summary))
    assert len(configs) == 2
    assert all(c in page.cells for c in configs)
    row = next(r for r in summary if r["metric"] == "sim_time_s" and r["config"] == configs[0])
    cell = page.cells[page.cells.index("sim_time_s") + 1]
    assert cell.startswith(f"{float(row['mean']):.4g}") and "[" in cell and f"n {row['n']}/{row['n_runs']}" in cell
    figures = sorted((sweep_dir / "plots").glob("*.png"))
    assert figures and len(page.images) == len(figures)
    assert_sources_resolve(path, page.images)
    run_pages = [link for link in page.links if link.endswith(REPORT_NAME)]
    assert len(run_pages) == 1 and (sweep_dir / run_pages[0]).is_file()  # the one run with a page


def test_reports_of_directories_that_are_not_results_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not a run directory"):
        write_run_report(tmp_path)
    with pytest.raises(ConfigError, match="not a sweep directory"):
        write_sweep_report(tmp_path)


# ------------------------------------------------------------------------------ in a browser
def _chromium() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.skip("chromium is not installed (CI installs Debian's chromium)")
    return exe


def screenshot(page: Path, png: Path, profile: Path) -> NDArrayLike:
    exe = _chromium()
    subprocess.run(
        [
            exe,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            f"--user-data-dir={profile}",
            f"--screenshot={png}",
            "--window-size=1280,2000",
            page.resolve().as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=180,
    )
    with Image.open(png) as im:
        return np.asarray(im.convert("RGB"), dtype=float)


NDArrayLike = np.ndarray


@pytest.mark.slow
@pytest.mark.parametrize("which", ["run", "sweep"])
def test_report_renders_in_a_headless_browser(which: str, request: pytest.FixtureRequest, tmp_path: Path) -> None:
    directory: Path = request.getfixturevalue(f"{which}_dir")
    page = directory / REPORT_NAME
    pixels = screenshot(page, tmp_path / "page.png", tmp_path / "profile")
    assert pixels.shape == (2000, 1280, 3)
    assert pixels.std() > 20.0  # not blank
    background = np.array([0xF6, 0xF6, 0xF4], dtype=float)
    drawn = np.any(np.abs(pixels - background) > 12, axis=2).mean()
    assert drawn > 0.03  # text, rules and figures, not only white
    parsed = parse(page)
    assert_sources_resolve(page, parsed.images + parsed.videos)
