"""Per-configuration statistics of a result table: n, mean, std, median and a 95 % confidence interval.

The interval of the mean is either Student's t-interval (``scipy.stats.t``: mean +- t_{0.975, n-1}
s / sqrt(n), s the sample standard deviation) or a bootstrap interval (``scipy.stats.bootstrap``,
BCa, 9999 resamples, fixed seed so the table is reproducible). Runs that raised
(``exit_status = error``) are counted in ``n_error`` and left out of every statistic; empty cells
(a metric a run does not have, e.g. ``completion_time_s`` of a timeout) are left out of that metric.
"""

from __future__ import annotations

import csv
import dataclasses
import enum
import io
import math
import warnings
from typing import Any, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from pybullet_swarm.experiment.results import Cell, RunStatus, is_number, metric_columns
from pybullet_swarm.experiment.rundir import atomic_write

CONFIDENCE = 0.95


class CIMethod(str, enum.Enum):
    """How the 95 % confidence interval of the mean is computed."""

    T = "t"  # Student's t-interval
    BOOTSTRAP = "bootstrap"  # BCa bootstrap (scipy.stats.bootstrap)


@dataclasses.dataclass(frozen=True)
class Stats:
    """Statistics of one metric over the runs of one configuration.

    Attributes:
        n: number of finite values.
        mean, std, median: of the values (std: sample standard deviation, ddof = 1).
        ci95_low, ci95_high: 95 % confidence interval of the mean (NaN when n < 2).
    """

    n: int
    mean: float
    std: float
    median: float
    ci95_low: float
    ci95_high: float


def describe(values: ArrayLike, *, ci: CIMethod | str = CIMethod.T, n_resamples: int = 9999, seed: int = 0) -> Stats:
    """Statistics of a sample; non-finite values are left out.

    Args:
        values: (n,) sample.
        ci: ``t`` or ``bootstrap``.
        n_resamples: bootstrap resamples.
        seed: seed of the bootstrap resampling.

    Returns:
        n, mean, std (ddof = 1), median and the 95 % interval of the mean; NaN where undefined.
    """
    ci = CIMethod(ci)
    x = np.asarray(values, dtype=float).ravel()
    x = x[np.isfinite(x)]
    n = int(x.size)
    nan = math.nan
    if n == 0:
        return Stats(0, nan, nan, nan, nan, nan)
    mean, median = float(np.mean(x)), float(np.median(x))
    if n < 2:
        return Stats(n, mean, nan, median, nan, nan)
    std = float(np.std(x, ddof=1))
    if std == 0.0:  # every run gave the same value: the interval is that value
        return Stats(n, mean, 0.0, median, mean, mean)
    low, high = _interval(x, ci, n_resamples, seed)
    return Stats(n, mean, std, median, low, high)


def _interval(x: np.ndarray, ci: CIMethod, n_resamples: int, seed: int) -> tuple[float, float]:
    from scipy import stats

    if ci is CIMethod.T:
        low, high = stats.t.interval(CONFIDENCE, x.size - 1, loc=np.mean(x), scale=stats.sem(x))
        return float(low), float(high)
    with warnings.catch_warnings():  # BCa on tiny or lumpy samples warns and may give NaN
        warnings.simplefilter("ignore")
        res = stats.bootstrap(
            (x,),
            np.mean,
            confidence_level=CONFIDENCE,
            n_resamples=n_resamples,
            method="BCa",
            vectorized=True,
            rng=np.random.default_rng(seed),
        )
        low, high = float(res.confidence_interval.low), float(res.confidence_interval.high)
        if not (math.isfinite(low) and math.isfinite(high)):
            res = stats.bootstrap(
                (x,),
                np.mean,
                confidence_level=CONFIDENCE,
                n_resamples=n_resamples,
                method="percentile",
                vectorized=True,
                rng=np.random.default_rng(seed),
            )
            low, high = float(res.confidence_interval.low), float(res.confidence_interval.high)
    return low, high


# ------------------------------------------------------------- configurations
@dataclasses.dataclass(frozen=True)
class Config:
    """One configuration of a comparison: the values of the grouping columns.

    Attributes:
        values: ``(column, value)`` pairs, e.g. ``(('planner', 'waypoints'), ('avoidance', 'none'))``.
        label: short name: the values that differ between the configurations compared.
    """

    values: tuple[tuple[str, Cell], ...]
    label: str


def group_rows(rows: Sequence[Mapping[str, Cell]], by: Sequence[str]) -> list[tuple[Config, list[Mapping[str, Cell]]]]:
    """Group rows by the values of ``by`` (in order of first appearance) and label each group.

    The label names what varies: ``planner`` and ``avoidance`` by their value, other columns as
    ``column=value``; columns equal in every group are left out of the labels.
    """
    groups: dict[tuple[Cell, ...], list[Mapping[str, Cell]]] = {}
    for r in rows:
        groups.setdefault(tuple(r.get(c) for c in by), []).append(r)
    keys = list(groups)
    varying = [i for i, _ in enumerate(by) if len({k[i] for k in keys}) > 1]
    out = []
    for key in keys:
        parts = []
        for i in varying:
            col, val = by[i], key[i]
            parts.append(str(val) if col in ("planner", "avoidance") else f"{col}={val}")
        if not parts:  # one configuration: name it by its planner (or the first column)
            parts = [str(key[by.index("planner")] if "planner" in by else key[0] if key else "all")]
        out.append((Config(tuple(zip(by, key)), " ".join(parts)), groups[key]))
    return out


@dataclasses.dataclass(frozen=True)
class SummaryRow:
    """One metric of one configuration.

    Attributes:
        config: the configuration.
        metric: column name, e.g. ``completion_time_s``.
        n_runs: runs of the configuration (errors included).
        n_error: runs that raised.
        stats: statistics over the runs that have a finite value.
        ci_method: how ``stats.ci95_*`` was computed.
    """

    config: Config
    metric: str
    n_runs: int
    n_error: int
    stats: Stats
    ci_method: CIMethod


def summarize(
    rows: Sequence[Mapping[str, Cell]],
    by: Sequence[str],
    *,
    metrics: Sequence[str] | None = None,
    ci: CIMethod | str = CIMethod.T,
) -> list[SummaryRow]:
    """Statistics per configuration and metric.

    Args:
        rows: result rows (``runs.csv``).
        by: the columns that define a configuration (planner, avoidance, grid keys).
        metrics: the metrics to summarise (default: every numeric outcome column).
        ci: ``t`` or ``bootstrap``.

    Returns:
        Rows ordered by configuration, then metric.
    """
    ci = CIMethod(ci)
    ok_rows = [r for r in rows if r.get("exit_status") != RunStatus.ERROR.value]
    names = list(metrics) if metrics is not None else metric_columns(ok_rows, exclude=by)
    out = []
    for config, members in group_rows(rows, by):
        ok = [r for r in members if r.get("exit_status") != RunStatus.ERROR.value]
        for m in names:
            values = [
                float(v)
                for v in (r.get(m) for r in ok)
                if isinstance(v, (int, float)) and (is_number(v) or isinstance(v, bool))
            ]
            out.append(SummaryRow(config, m, len(members), len(members) - len(ok), describe(values, ci=ci), ci))
    return out


SUMMARY_COLUMNS = ("n", "mean", "std", "median", "ci95_low", "ci95_high")


def summary_records(summary: Sequence[SummaryRow]) -> list[dict[str, Any]]:
    """Plain records of a summary: configuration columns, metric, counts, statistics, CI method."""
    records = []
    for s in summary:
        rec: dict[str, Any] = {
            "config": s.config.label,
            **dict(s.config.values),
            "metric": s.metric,
            "n_runs": s.n_runs,
            "n_error": s.n_error,
        }
        rec.update({k: getattr(s.stats, k) for k in SUMMARY_COLUMNS})
        rec["ci_method"] = s.ci_method.value
        records.append(rec)
    return records


def write_summary(path: Any, summary: Sequence[SummaryRow]) -> None:
    """Write ``summary.csv`` atomically (empty cells where a statistic is undefined)."""
    records = summary_records(summary)
    columns: list[str] = []
    for rec in records:
        columns.extend(k for k in rec if k not in columns)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns or ["config", "metric", "n_runs", "n_error", *SUMMARY_COLUMNS, "ci_method"])
    for rec in records:
        w.writerow([_text(rec.get(c)) for c in columns])
    atomic_write(path, lambda fh: fh.write(buf.getvalue()))


def _text(v: Any) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    return repr(v) if isinstance(v, float) else str(v)


#: Metrics shown by ``format_table`` when present (in this order).
HEADLINE_METRICS = (
    "completed",
    "completion_time_s",
    "sim_time_s",
    "collisions.total",
    "collisions.agent_agent",
    "path_length_m.total",
    "energy_j",
    "tracking_rmse_m",
    "min_separation_m",
)


def format_table(summary: Sequence[SummaryRow], metrics: Sequence[str] | None = None) -> str:
    """The comparison table: one line per metric and configuration, ``mean +- std [CI]`` and n."""
    present = list(dict.fromkeys(s.metric for s in summary))
    wanted = [m for m in (metrics or HEADLINE_METRICS) if m in present] or present
    rows = [s for m in wanted for s in summary if s.metric == m]
    if not rows:
        return "(no metrics to compare: no run finished without an error)"
    method = rows[0].ci_method.value
    header = ("metric", "configuration", "n", "mean", "std", "median", f"95% CI of mean ({method})")
    lines = [header]
    for s in rows:
        st = s.stats
        n = f"{st.n}/{s.n_runs}" if st.n != s.n_runs else str(st.n)
        lines.append(
            (
                s.metric,
                s.config.label,
                n,
                _g(st.mean),
                _g(st.std),
                _g(st.median),
                f"[{_g(st.ci95_low)}, {_g(st.ci95_high)}]" if math.isfinite(st.ci95_low) else "-",
            )
        )
    widths = [max(len(r[i]) for r in lines) for i in range(len(header))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in lines)


def _g(v: float) -> str:
    return f"{v:.4g}" if math.isfinite(v) else "-"
