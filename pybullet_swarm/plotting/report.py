"""HTML pages of a run and of a sweep, built from their saved results: ``experiment.report`` reads a
directory into a ``RunPage`` or ``SweepPage`` and writes the page as ``report.html``.

A run's page: the scenario summary, the metrics table, the replay video when there is one, a still
of the run's last instant, every figure, and the events (a timeline figure and a table). A sweep's
page: what was swept, the comparison table with 95 % confidence intervals, every comparison
figure, and one line per run linking to the run's own page when it has one.

Figures are embedded as base64 PNG data URIs, so the page can be mailed or moved alone; the video
(too large to embed) is linked by its path relative to the page.
"""

from __future__ import annotations

import base64
import dataclasses
import html
import io
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from pybullet_swarm.types import Event

MAX_EVENT_ROWS = 2000  # rows of the events table (the figure shows every event)

_CSS = """
body{font-family:-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;margin:0;background:#f6f6f4;color:#222}
main{max-width:1240px;margin:0 auto;padding:24px 28px 60px}
h1{font-size:26px;margin:4px 0 2px}h2{font-size:19px;margin:34px 0 10px;border-bottom:1px solid #ccc;padding-bottom:4px}
.sub{color:#666;margin:0 0 14px}.badge{display:inline-block;padding:2px 10px;border-radius:12px;font-weight:600;
color:#fff;background:#777;margin-right:8px}.completed{background:#2e8b57}.timeout,.stalled{background:#c88a12}
.crashed,.diverged,.error{background:#c0392b}
table{border-collapse:collapse;background:#fff;font-size:13.5px;margin:6px 0}
th,td{border:1px solid #ddd;padding:4px 9px;text-align:left;vertical-align:top}
th{background:#eceae4}td.num{text-align:right;font-variant-numeric:tabular-nums}
.grid{display:flex;flex-wrap:wrap;gap:14px}figure{margin:0;background:#fff;border:1px solid #ddd;padding:8px}
figure img{max-width:100%;display:block}figcaption{font-size:12.5px;color:#555;margin-top:4px}
.half{flex:1 1 560px;max-width:600px}.full{flex:1 1 100%}
.scroll{max-height:460px;overflow:auto;border:1px solid #ddd}pre{background:#fff;border:1px solid #ddd;padding:8px;
overflow:auto;font-size:12.5px}video{max-width:100%;background:#000}
.cols{display:flex;flex-wrap:wrap;gap:28px;align-items:flex-start}.cols>section{flex:1 1 520px;min-width:0}
.cols .scroll{max-height:520px}
"""


# ------------------------------------------------------------------------- helpers
def _esc(value: Any) -> str:
    return html.escape(str(value), quote=True)


def fmt(value: Any) -> str:
    """A table cell's text: 4 significant digits for floats, '-' for None and non-finite numbers."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else "-"
    return str(value)


def png_data_uri(data: bytes) -> str:
    """A ``data:image/png;base64,...`` URI of PNG bytes."""
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def figure_png(fig: Figure, dpi: int = 100) -> bytes:
    """PNG bytes of a figure."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def _img(src: str, caption: str, css: str = "half") -> str:
    return (
        f'<figure class="{css}"><img src="{_esc(src)}" alt="{_esc(caption)}" loading="eager">'
        f"<figcaption>{_esc(caption)}</figcaption></figure>"
    )


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]], numeric: Sequence[bool] | None = None) -> str:
    """A table; ``rows`` hold HTML already escaped."""
    numeric = numeric or [False] * len(header)
    head = "".join(f"<th>{_esc(h)}</th>" for h in header)
    body = "".join(
        "<tr>"
        + "".join(f'<td class="num">{c}</td>' if numeric[i] else f"<td>{c}</td>" for i, c in enumerate(r))
        + "</tr>"
        for r in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _figures(figures: Sequence[tuple[str, bytes]]) -> list[str]:
    return [_img(png_data_uri(png), caption) for caption, png in figures]


def _page(title: str, body: str) -> str:
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f'<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{_esc(title)}</title><style>{_CSS}</style></head><body><main>{body}</main></body></html>\n"
    )


# ------------------------------------------------------------------------- a run
@dataclasses.dataclass(frozen=True)
class RunPage:
    """What a run's page shows.

    Attributes:
        directory: the run directory, as shown.
        scenario: the resolved scenario (``scenario.yaml``), {} when missing.
        metrics: the run's metrics (``metrics.json``), {} for an unfinished run.
        flat_metrics: the metrics as ``(name, value)`` rows (nested names joined by dots).
        events: the run's events in time order.
        figures: ``(caption, PNG bytes)`` of every figure.
        still: PNG bytes of the run's last instant (the replay renderer), when it has samples.
        video: the video's file name beside the page, when there is one.
    """

    directory: str
    scenario: Mapping[str, Any]
    metrics: Mapping[str, Any]
    flat_metrics: Sequence[tuple[str, Any]]
    events: Sequence[Event]
    figures: Sequence[tuple[str, bytes]] = ()
    still: bytes | None = None
    video: str | None = None


def events_timeline_figure(events: Sequence[Event], t_end: float) -> Figure:
    """Every event over time, one row per kind (with its count)."""
    kinds = list(dict.fromkeys(e.kind for e in events))
    fig = Figure(figsize=(11, 1.1 + 0.42 * max(len(kinds), 1)), layout="constrained")
    ax = fig.subplots()
    rows = np.arange(len(kinds))[::-1]
    for k, (row, kind) in enumerate(zip(rows, kinds)):
        t = np.array([e.time_s for e in events if e.kind == kind])
        ax.plot(t, np.full(t.shape, row), "|", ms=13, mew=1.6, color=f"C{k % 10}")
    ax.set_yticks(rows, [f"{kind} ({sum(e.kind == kind for e in events)})" for kind in kinds])
    ax.set_ylim(-0.7, max(len(kinds), 1) - 0.3)
    ax.set_xlim(0.0, max(float(t_end), 1e-9))
    ax.set_xlabel("simulated time [s]")
    ax.set_title(f"events ({len(events)})" if events else "no events")
    ax.grid(axis="x", alpha=0.3)
    return fig


def _scenario_rows(scenario: Mapping[str, Any], metrics: Mapping[str, Any]) -> list[tuple[str, str]]:
    sim = scenario.get("sim", {}) or {}
    agents = scenario.get("agents", {}) or {}
    arena = scenario.get("arena", {}) or {}
    task = scenario.get("task", {}) or {}
    planner = metrics.get("planner") or (scenario.get("planner", {}) or {}).get("name") or "-"
    limits = scenario.get("limits", {}) or {}
    size = arena.get("size", [])
    rows = [
        ("scenario", scenario.get("name", metrics.get("scenario", "-"))),
        ("description", scenario.get("description", "")),
        ("task", f"{task.get('kind', '-')}, time limit {fmt(task.get('time_limit_s'))} s"),
        (
            "agents",
            f"{agents.get('count', metrics.get('agents', '-'))} x {agents.get('vehicle', metrics.get('vehicle', '-'))}",
        ),
        ("planner", planner),
        ("avoidance", metrics.get("avoidance") or scenario.get("avoidance") or "none"),
        ("seed", metrics.get("seed", scenario.get("seed", "-"))),
        ("arena", f"{' x '.join(fmt(v) for v in size)} m, {len(arena.get('obstacles', []) or [])} obstacles"),
        ("collisions", scenario.get("collisions", "-")),
        (
            "rates",
            "physics {} Hz, control {} Hz, planner {} Hz, recording {} Hz".format(
                *(sim.get(k, "-") for k in ("physics_hz", "control_hz", "planner_hz", "record_hz"))
            ),
        ),
        ("limits", f"velocity {fmt(limits.get('velocity'))} m/s, acceleration {fmt(limits.get('acceleration'))} m/s^2"),
    ]
    if task.get("kind") == "construction":
        rows.append(
            (
                "structure",
                f"{len(task.get('boxes', []))} boxes, {len(task.get('structure', []))} slots, "
                f"box {fmt(task.get('box_size'))} m",
            )
        )
    return [(k, str(v)) for k, v in rows]


def run_report_html(page: RunPage) -> str:
    """The HTML page of a run."""
    import yaml

    scenario, metrics, events = page.scenario, page.metrics, list(page.events)
    name = scenario.get("name", metrics.get("scenario", "run"))
    status = str(metrics.get("exit_status", "unfinished"))
    sim_t = metrics.get("sim_time_s")
    parts = [
        f"<h1>{_esc(name)}: run report</h1>",
        f'<p class="sub"><span class="badge {_esc(status)}">{_esc(status)}</span>'
        f"{_esc(fmt(sim_t))} s simulated, {_esc(fmt(metrics.get('real_time_factor')))}x real time"
        f" &middot; <code>{_esc(page.directory)}</code></p>",
    ]
    summary = "<h2>Scenario</h2>" + _table(
        ("field", "value"), [(_esc(k), _esc(v)) for k, v in _scenario_rows(scenario, metrics)]
    )
    if scenario:
        summary += (
            "<details><summary>scenario.yaml (reproduces the run)</summary><pre>"
            f"{_esc(yaml.safe_dump(dict(scenario), sort_keys=False))}</pre></details>"
        )
    rows_m = [(_esc(k), _esc(fmt(v))) for k, v in page.flat_metrics]
    table = (
        f'<div class="scroll">{_table(("metric", "value"), rows_m, (False, True))}</div>'
        if rows_m
        else "<p>No metrics.json (unfinished run).</p>"
    )
    parts.append(f'<div class="cols"><section>{summary}</section><section><h2>Metrics</h2>{table}</section></div>')
    if page.video:
        media = (
            f'<video controls preload="metadata" src="{_esc(page.video)}"></video>'
            if page.video.endswith(".mp4")
            else f'<img src="{_esc(page.video)}" alt="replay">'
        )
        parts.append(
            f'<h2>Replay</h2>{media}<p class="sub">{_esc(page.video)} (pybullet-swarm replay RUN_DIR '
            "draws other views)</p>"
        )
    figures = (
        [_img(png_data_uri(page.still), "last instant, seen from above (replay renderer)", "full")]
        if page.still
        else []
    )
    figures += _figures(page.figures)
    parts.append(
        "<h2>Figures</h2>"
        + (
            f'<div class="grid">{"".join(figures)}</div>'
            if figures
            else "<p>No figures (drawn with pybullet-swarm plot RUN_DIR).</p>"
        )
    )
    t_end = float(sim_t) if isinstance(sim_t, (int, float)) else max((e.time_s for e in events), default=1.0)
    timeline = png_data_uri(figure_png(events_timeline_figure(events, t_end)))
    rows = [(f"{e.time_s:.3f}", _esc(e.kind), _esc(e.a), _esc(e.b), _esc(e.detail)) for e in events[:MAX_EVENT_ROWS]]
    more = (
        f'<p class="sub">first {MAX_EVENT_ROWS} of {len(events)} events (all in events.csv)</p>'
        if len(events) > MAX_EVENT_ROWS
        else ""
    )
    parts.append(
        "<h2>Events</h2>"
        + _img(timeline, "events over time, one row per kind", "full")
        + more
        + '<div class="scroll">'
        + _table(("time [s]", "kind", "a", "b", "detail"), rows, (True, False, False, False, False))
        + "</div>"
    )
    return _page(f"{name} run report", "".join(parts))


# ------------------------------------------------------------------------- a sweep
@dataclasses.dataclass(frozen=True)
class SweepPage:
    """What a sweep's page shows.

    Attributes:
        name: the scenario's name.
        directory: the sweep directory, as shown.
        setup: ``(field, value)`` rows of what was swept.
        statuses: runs recorded per ``exit_status``.
        summary: records of ``summary.csv`` (text cells by column name).
        metric_order: metrics shown first in the comparison table, when present.
        figures: ``(caption, PNG bytes)`` of every comparison figure.
        run_columns: columns of the runs table.
        runs: one row per run: cells by column, and ``link``, the run's page relative to this one (or None).
    """

    name: str
    directory: str
    setup: Sequence[tuple[str, str]]
    statuses: Mapping[str, int]
    summary: Sequence[Mapping[str, str]]
    metric_order: Sequence[str] = ()
    figures: Sequence[tuple[str, bytes]] = ()
    run_columns: Sequence[str] = ()
    runs: Sequence[Mapping[str, Any]] = ()


def _number(text: str | None) -> float:
    try:
        return float(text) if text not in (None, "") else math.nan
    except ValueError:
        return math.nan


def comparison_table(records: Sequence[Mapping[str, str]], first: Sequence[str] = ()) -> str:
    """HTML table of ``summary.csv`` records: one row per metric (those of ``first`` first), one column
    per configuration, cells ``mean [95 % CI low, high]`` with std and n."""
    configs = list(dict.fromkeys(r["config"] for r in records))
    present = list(dict.fromkeys(r["metric"] for r in records))
    wanted = [m for m in first if m in present] + [m for m in present if m not in first]
    cell = {(r["metric"], r["config"]): r for r in records}
    method = records[0].get("ci_method", "t") if records else "t"
    rows = []
    for m in wanted:
        row = [f"<b>{_esc(m)}</b>"]
        for c in configs:
            r = cell.get((m, c))
            if r is None:
                row.append("-")
                continue
            mean, lo, hi, std = (_number(r.get(k)) for k in ("mean", "ci95_low", "ci95_high", "std"))
            ci = f"[{lo:.4g}, {hi:.4g}]" if math.isfinite(lo) and math.isfinite(hi) else "[-]"
            row.append(
                f"{_esc(fmt(mean))} <small>{_esc(ci)}<br>std {_esc(fmt(std))}, n {_esc(r.get('n', '-'))}"
                f"/{_esc(r.get('n_runs', '-'))}</small>"
            )
        rows.append(row)
    header = ["metric", *configs]
    return (
        f'<p class="sub">mean [95 % confidence interval of the mean, {_esc(method)}]; n = runs with a value / '
        "runs of the configuration</p>" + _table(header, rows, [False] + [True] * len(configs))
    )


def sweep_report_html(page: SweepPage) -> str:
    """The HTML page of a sweep."""
    badges = "".join(f'<span class="badge {_esc(k)}">{_esc(k)} {v}</span>' for k, v in page.statuses.items())
    parts = [
        f"<h1>{_esc(page.name)}: sweep report</h1>",
        f'<p class="sub">{badges} {sum(page.statuses.values())} runs recorded &middot; '
        f"<code>{_esc(page.directory)}</code></p>",
        "<h2>Sweep</h2>" + _table(("field", "value"), [(_esc(k), _esc(v)) for k, v in page.setup]),
    ]
    parts.append(
        "<h2>Comparison</h2>"
        + (comparison_table(page.summary, page.metric_order) if page.summary else "<p>No summary.csv yet.</p>")
    )
    figures = _figures(page.figures)
    parts.append(
        "<h2>Comparison figures</h2>"
        + (
            f'<div class="grid">{"".join(figures)}</div>'
            if figures
            else "<p>No figures (pybullet-swarm plot SWEEP_DIR draws them).</p>"
        )
    )
    numeric = [c not in ("run_id", "planner", "avoidance", "exit_status") for c in page.run_columns]
    rows = []
    for r in page.runs:
        cells = []
        for c in page.run_columns:
            text = _esc(fmt(r.get(c)))
            cells.append(f'<a href="{_esc(r["link"])}">{text}</a>' if c == "run_id" and r.get("link") else text)
        rows.append(cells)
    parts.append('<h2>Runs</h2><div class="scroll">' + _table(page.run_columns, rows, numeric) + "</div>")
    return _page(f"{page.name} sweep report", "".join(parts))
