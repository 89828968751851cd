"""Result tables: metrics flattened into rows, ``runs.csv`` appended atomically, rows read back.

A row is one run: who ran it (``run_id``, ``planner``, ``avoidance``, ``seed``, grid values),
how it ended (``exit_status``, ``error``, ``worker_time_s``, ``run_dir``) and every scalar
metric of its ``metrics.json`` flattened with dots (``collisions.agent_agent``). Lists (per-agent
values) stay in the run directory. Cells hold plain scalars: ``None``, ``bool``, ``int``,
``float`` or ``str`` (lists and mappings of grid values are stored as JSON text).
"""
from __future__ import annotations

import csv
import enum
import hashlib
import io
import json
import math
import os
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping, Sequence

import yaml

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.rundir import atomic_write
from pybullet_swarm.types import Event

Cell = None | bool | int | float | str
Row = dict[str, Cell]

RUNS_CSV = "runs.csv"
RUNS_PARQUET = "runs.parquet"
SUMMARY_CSV = "summary.csv"
MANIFEST = "sweep.json"


class RunStatus(str, enum.Enum):
    """``exit_status`` of a row: the simulation outcomes, plus ``error`` for a run that raised."""

    COMPLETED = "completed"
    TIMEOUT = "timeout"
    CRASHED = "crashed"
    DIVERGED = "diverged"
    ERROR = "error"


#: Identity columns of a row, before the grid values.
ID_COLUMNS: tuple[str, ...] = ("run_id", "planner", "avoidance", "seed")
#: Outcome columns of a row, after the grid values and before the metrics.
STATUS_COLUMNS: tuple[str, ...] = ("exit_status", "error", "worker_time_s", "run_dir")
#: Columns that are not outcomes of a run (never summarised or plotted).
NOT_METRICS: frozenset[str] = frozenset({*ID_COLUMNS, *STATUS_COLUMNS, "crashed_agent", "scenario", "vehicle",
                                         "video"})
#: Metric keys already in the identity or status columns.
_DUPLICATES = frozenset({"planner", "avoidance", "seed", "exit_status"})


# ----------------------------------------------------------------------- rows
def flatten_metrics(metrics: Mapping[str, Any], prefix: str = "") -> Row:
    """Scalar metrics with nested keys joined by dots; lists are left out.

    Args:
        metrics: the JSON data of ``metrics.json``.
        prefix: prepended to every key (used by the recursion).

    Returns:
        ``{'sim_time_s': 12.0, 'collisions.agent_agent': 0, ...}`` in the order of ``metrics``.
    """
    flat: Row = {}
    for key, value in metrics.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(flatten_metrics(value, prefix=f"{name}."))
        elif isinstance(value, (list, tuple)):
            continue
        elif value is None or isinstance(value, (bool, int, float, str)):
            flat[name] = value
        else:
            flat[name] = str(value)
    return flat


def plain_cell(value: Any) -> Cell:
    """A value as a table cell: scalars unchanged, anything else as compact JSON text."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return json.dumps(value, separators=(",", ":"), sort_keys=True)


def metrics_row(metrics: Mapping[str, Any]) -> Row:
    """The metric part of a row: flattened metrics plus ``collisions.total`` and ``completed`` (1/0)."""
    flat = {k: v for k, v in flatten_metrics(metrics).items() if k not in _DUPLICATES}
    counts = [v for k, v in flat.items() if k.startswith("collisions.") and isinstance(v, (int, float))]
    if counts:
        flat["collisions.total"] = sum(counts)
    status = metrics.get("exit_status")
    if status is not None:
        flat["completed"] = int(status == RunStatus.COMPLETED.value)
    return flat


def one_line(text: str, limit: int = 500) -> str:
    """``text`` on one line, at most ``limit`` characters."""
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 3] + "..."


def is_number(v: Cell) -> bool:
    """True for finite ints and floats (bools excluded)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


# ------------------------------------------------------------------ CSV cells
def format_cell(v: Cell) -> str:
    """CSV text of a cell: '' for None, ``true``/``false``, shortest round-trip floats."""
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    return str(v)


def parse_cell(text: str) -> Cell:
    """Inverse of ``format_cell``: '' -> None, numbers, ``true``/``false``, else the text."""
    if text == "":
        return None
    if text in ("true", "false"):
        return text == "true"
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        return text
    return value if math.isfinite(value) else text


def _csv_line(values: Iterable[str]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(list(values))
    return buf.getvalue()


# ------------------------------------------------------------------ runs.csv
class RunsTable:
    """``runs.csv`` of a sweep: one row per finished run, appended atomically, read back on resume.

    Each row is appended as one complete line with a single ``write`` on an ``O_APPEND`` file,
    then flushed to disk (``fsync``): a process killed at any instant leaves every earlier row
    intact and at most a torn last line, which ``open`` drops (that run's directory still holds
    its ``metrics.json``, from which the sweep recovers the row). A row with a column the file
    does not have yet rewrites the file under the wider header (temporary file, then rename).

    Args:
        path: the CSV file (created on the first append).
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.columns: list[str] = []
        self._rows: dict[str, Row] = {}
        self._load()

    # reading
    def _load(self) -> None:
        if not self.path.is_file():
            return
        raw = self.path.read_bytes()
        repaired = False
        if raw and not raw.endswith(b"\n"):   # torn last line of a killed writer: drop it
            raw = raw[: raw.rfind(b"\n") + 1]
            repaired = True
        reader = csv.reader(io.StringIO(raw.decode("utf-8"), newline=""))
        header = next(reader, None)
        if header is None:
            self.path.unlink()
            return
        if not header or header[0] != "run_id":
            raise ConfigError("not a runs table (its first column must be run_id)", source=str(self.path))
        self.columns = header
        for cells in reader:
            if not cells:
                continue
            row = {c: parse_cell(t) for c, t in zip(header, cells)}
            run_id = str(row["run_id"])
            if run_id in self._rows:
                repaired = True       # keep one row per run: the later one, unless it is an error
                if row.get("exit_status") == RunStatus.ERROR.value:
                    continue
            self._rows[run_id] = row
        if repaired:
            self._rewrite()

    @property
    def rows(self) -> list[Row]:
        """Every row, in the order they were recorded."""
        return list(self._rows.values())

    def ids(self) -> set[str]:
        """Run ids with a row."""
        return set(self._rows)

    def get(self, run_id: str) -> Row | None:
        """The row of ``run_id``, if recorded."""
        return self._rows.get(run_id)

    def __len__(self) -> int:
        return len(self._rows)

    # writing
    def append(self, row: Mapping[str, Cell]) -> None:
        """Record one finished run (a run already recorded is replaced by a rewrite)."""
        row = dict(row)
        run_id = str(row["run_id"])
        new_columns = [c for c in row if c not in self.columns]
        replacing = run_id in self._rows
        self._rows[run_id] = row
        if new_columns or replacing or not self.path.is_file():
            if not self.columns:
                self.columns = ["run_id"]
                new_columns = [c for c in new_columns if c != "run_id"]
            self.columns.extend(new_columns)
            self._rewrite()
            return
        line = _csv_line(format_cell(row.get(c)) for c in self.columns).encode("utf-8")
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            os.write(fd, line)
            os.fsync(fd)
        finally:
            os.close(fd)

    def update(self, run_id: str, values: Mapping[str, Cell]) -> bool:
        """Fill cells of a recorded row that are empty; returns True when anything changed (no write)."""
        row = self._rows[run_id]
        changed = False
        for key, value in values.items():
            if row.get(key) is None and value is not None:
                row[key] = value
                if key not in self.columns:
                    self.columns.append(key)
                changed = True
        return changed

    def drop(self, run_ids: Iterable[str]) -> int:
        """Forget rows (e.g. failed runs to try again); returns how many (no write)."""
        n = 0
        for run_id in run_ids:
            n += self._rows.pop(run_id, None) is not None
        return n

    def save(self) -> None:
        """Rewrite the whole file atomically (after ``update`` or ``drop``)."""
        if self._rows or self.path.is_file():
            self._rewrite()

    def _rewrite(self) -> None:
        if not self.columns:
            self.columns = ["run_id"]
        text = _csv_line(self.columns) + "".join(
            _csv_line(format_cell(r.get(c)) for c in self.columns) for r in self._rows.values())
        atomic_write(self.path, lambda fh: fh.write(text))


# --------------------------------------------------------------- typed columns
def column_values(rows: Sequence[Mapping[str, Cell]], column: str) -> list[Cell]:
    """The cells of one column (None where a row lacks it)."""
    return [r.get(column) for r in rows]


def numeric_columns(rows: Sequence[Mapping[str, Cell]], columns: Sequence[str]) -> list[str]:
    """Columns whose non-empty cells are all numbers (or all bools) and not all empty."""
    out = []
    for c in columns:
        values = [v for v in column_values(rows, c) if v is not None]
        if values and (all(is_number(v) for v in values) or all(isinstance(v, bool) for v in values)):
            out.append(c)
    return out


def metric_columns(rows: Sequence[Mapping[str, Cell]], exclude: Iterable[str] = ()) -> list[str]:
    """Numeric outcome columns, in order of first appearance (identity, grid and status columns left out)."""
    skip = set(NOT_METRICS) | set(exclude)
    seen: dict[str, None] = {}
    for r in rows:
        for c in r:
            if c not in skip:
                seen.setdefault(c, None)
    return numeric_columns(rows, list(seen))


def write_parquet(path: Path, rows: Sequence[Mapping[str, Cell]], columns: Sequence[str]) -> Path | None:
    """Write the rows as Parquet when pyarrow is installed; returns the file, or None without pyarrow."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return None
    arrays = {}
    for c in columns:
        values = column_values(rows, c)
        present = [v for v in values if v is not None]
        if present and all(isinstance(v, bool) for v in present):
            arrays[c] = pa.array(values, type=pa.bool_())
        elif present and all(isinstance(v, int) and not isinstance(v, bool) for v in present):
            arrays[c] = pa.array(values, type=pa.int64())
        elif present and all(is_number(v) for v in present):
            arrays[c] = pa.array([None if v is None else float(v) for v in values], type=pa.float64())
        else:
            arrays[c] = pa.array([None if v is None else str(v) for v in values], type=pa.string())
    table = pa.table(arrays)
    atomic_write(path, lambda fh: pq.write_table(table, fh), binary=True)
    return path


# ------------------------------------------------------------ run directories
def config_hash(data: Any, n: int = 12) -> str:
    """A stable short hash of plain data (sorted-key JSON, SHA-256)."""
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:n]


def is_run_dir(path: Path) -> bool:
    """True for a finished run directory (it holds ``metrics.json``)."""
    return (Path(path) / "metrics.json").is_file()


def is_sweep_dir(path: Path) -> bool:
    """True for a sweep directory (it holds ``runs.csv`` or ``sweep.json``)."""
    return (Path(path) / RUNS_CSV).is_file() or (Path(path) / MANIFEST).is_file()


def read_metrics(run_dir: Path) -> dict[str, Any]:
    """``metrics.json`` of a finished run."""
    path = Path(run_dir) / "metrics.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError("not a finished run directory (no metrics.json)", source=str(run_dir)) from None
    except (OSError, ValueError) as exc:
        raise ConfigError(f"unreadable metrics.json ({exc})", source=str(run_dir)) from None
    if not isinstance(data, dict):
        raise ConfigError("metrics.json must hold a mapping", source=str(run_dir))
    return data


def read_scenario_data(run_dir: Path) -> dict[str, Any] | None:
    """The resolved ``scenario.yaml`` of a run directory (None when missing or unreadable)."""
    path = Path(run_dir) / "scenario.yaml"
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError):
        return None
    return data if isinstance(data, dict) else None


def read_events(path: Path) -> list[Event]:
    """Events of ``events.csv`` (empty when the file is missing)."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        return []
    events = []
    for rec in csv.DictReader(io.StringIO(text, newline="")):
        try:
            events.append(Event(time_s=float(rec["time_s"]), kind=rec["kind"], a=rec.get("a", ""),
                                b=rec.get("b", "") or "", detail=rec.get("detail", "") or ""))
        except (KeyError, TypeError, ValueError):
            continue
    return events


def run_dir_row(run_dir: Path) -> Row:
    """A row for a stand-alone run directory (``compare``): identity from its metrics and scenario.

    ``run_id`` is the directory name; ``config`` is a hash of the resolved scenario without its
    seed, planner and avoidance, so runs that differ only by seed share it.
    """
    run_dir = Path(run_dir)
    metrics = read_metrics(run_dir)
    scenario = read_scenario_data(run_dir) or {}
    base = {k: v for k, v in scenario.items() if k not in ("seed", "planner", "avoidance")}
    row: Row = {
        "run_id": run_dir.name,
        "planner": plain_cell(metrics.get("planner")),
        "avoidance": plain_cell(metrics.get("avoidance")),
        "seed": plain_cell(metrics.get("seed")),
        "scenario": plain_cell(metrics.get("scenario")),
        "config": config_hash(base, 8),
        "exit_status": plain_cell(metrics.get("exit_status")),
        "error": None,
        "worker_time_s": None,
        "run_dir": str(run_dir),
    }
    row.update(metrics_row(metrics))
    return row


def iter_finished_run_dirs(root: Path) -> Iterator[Path]:
    """Finished run directories directly below ``root``."""
    if not Path(root).is_dir():
        return
    for child in sorted(Path(root).iterdir()):
        if child.is_dir() and is_run_dir(child):
            yield child
