"""Result tables: metrics flattened into rows, ``runs.csv`` appended atomically, rows read back.

A row is one run: who ran it (``run_id``, ``planner``, ``avoidance``, ``seed``, grid values),
how it ended (``exit_status``, ``error``, ``worker_time_s``, ``run_dir``, ``worker_cpu_s``) and every scalar
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
    STALLED = "stalled"
    ERROR = "error"


#: Identity columns of a row, before the grid values.
ID_COLUMNS: tuple[str, ...] = ("run_id", "planner", "avoidance", "seed")
#: Outcome columns of a row, after the grid values and before the metrics.
STATUS_COLUMNS: tuple[str, ...] = ("exit_status", "error", "worker_time_s", "run_dir", "worker_cpu_s")
#: Columns that are not outcomes of a run (never summarised or plotted).
NOT_METRICS: frozenset[str] = frozenset(
    {*ID_COLUMNS, *STATUS_COLUMNS, "crashed_agent", "crash_cause", "scenario", "vehicle", "video"}
)
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


#: columns that are names, read back as the text written: a run id of hex digits may read as a number
#: ("7600923850e0" as 7.6e12, "012345678901" without its leading zero)
TEXT_COLUMNS = frozenset({"run_id", "run_dir"})


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
        if raw and not raw.endswith(b"\n"):  # torn last line of a killed writer: drop it
            raw = raw[: raw.rfind(b"\n") + 1]
            repaired = True
        try:
            text = raw.decode("utf-8")
            if "\x00" in text:
                raise ValueError("binary data (NUL characters)")
            reader = csv.reader(io.StringIO(text, newline=""))
            header = next(reader, None)
            if header is None:
                self.path.unlink()
                return
            if not header or header[0] != "run_id" or len(set(header)) != len(header):
                raise ConfigError(
                    "not a runs table (its first column must be run_id, its columns unique)", source=str(self.path)
                )
            self.columns = header
            for cells in reader:
                if not cells:
                    continue
                row = {c: (t if c in TEXT_COLUMNS else parse_cell(t)) for c, t in zip(header, cells)}
                run_id = str(row["run_id"])
                if run_id in self._rows:
                    repaired = True  # keep one row per run: the later one, unless it is an error
                    if row.get("exit_status") == RunStatus.ERROR.value:
                        continue
                self._rows[run_id] = row
        except (ValueError, csv.Error) as exc:  # UnicodeDecodeError is a ValueError
            if isinstance(exc, ConfigError):
                raise
            raise ConfigError(f"unreadable runs table ({_reason(exc)})", source=str(self.path)) from None
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
            _csv_line(format_cell(r.get(c)) for c in self.columns) for r in self._rows.values()
        )
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


def _reason(exc: BaseException) -> str:
    """An exception as a short one-line reason."""
    text = " ".join(str(exc).split())
    text = text if len(text) <= 120 else text[:117] + "..."
    return f"{exc.__class__.__name__}: {text}" if text else exc.__class__.__name__


def _read_text(path: Path) -> str:
    """The UTF-8 text of a result file (at most ``MAX_RESULT_BYTES``); anything else is a one-line ConfigError."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_RESULT_BYTES + 1)
    except OSError as exc:
        raise ConfigError(f"unreadable ({_reason(exc)})", source=str(path)) from None
    if len(raw) > MAX_RESULT_BYTES:
        raise ConfigError(f"unreadable (larger than {MAX_RESULT_BYTES >> 20} MiB)", source=str(path))
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ConfigError("unreadable (not UTF-8 text)", source=str(path)) from None
    if "\x00" in text:
        raise ConfigError("unreadable (binary data)", source=str(path))
    return text


MAX_RESULT_BYTES = 256 << 20  # largest metrics.json, scenario.yaml or events.csv read back, bytes


def _check_metrics(data: Mapping[str, Any], path: Path) -> None:
    """Refuse metrics whose values the figures and tables read have the wrong shape."""

    def bad(field: str, want: str) -> ConfigError:
        return ConfigError(
            f"corrupt: must be {want}, got {_short_value(data.get(field))}", source=str(path), field=field
        )

    for key in ("completion_time_s", "sim_time_s", "positioning_noise_std_m"):
        v = data.get(key)
        if v is not None and not is_number(v):
            raise bad(key, "a finite number or null")
    for key in ("exit_status", "planner", "avoidance", "scenario"):
        v = data.get(key)
        if v is not None and not isinstance(v, str):
            raise bad(key, "a string")
    times = data.get("waypoint_times_s")
    if times is not None and not (isinstance(times, list) and all(v is None or is_number(v) for v in times)):
        raise bad("waypoint_times_s", "a list of numbers or nulls")
    est = data.get("estimation")
    if est is not None and not (
        isinstance(est, dict) and all(isinstance(est.get(k, {}), dict) for k in ("kalman", "gps", "imu"))
    ):
        raise bad("estimation", "a mapping of kalman, gps and imu mappings")


def _short_value(v: Any) -> str:
    text = " ".join(repr(v).split())
    return text if len(text) <= 60 else text[:57] + "..."


def read_metrics(run_dir: Path) -> dict[str, Any]:
    """``metrics.json`` of a finished run.

    Raises:
        ConfigError: missing, unreadable, not JSON, not a mapping or holding values of the wrong
            shape: one line naming the file.
    """
    path = Path(run_dir) / "metrics.json"
    if not path.is_file():
        raise ConfigError("not a finished run directory (no metrics.json)", source=str(run_dir))
    text = _read_text(path)
    try:
        data = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise ConfigError(f"unreadable: not JSON ({_reason(exc)})", source=str(path)) from None
    if not isinstance(data, dict):
        raise ConfigError("corrupt: must hold a mapping", source=str(path))
    _check_metrics(data, path)
    return data


def read_scenario_data(run_dir: Path) -> dict[str, Any] | None:
    """The resolved ``scenario.yaml`` of a run directory (None when there is none).

    Raises:
        ConfigError: unreadable, malformed, or not a scenario (the sections the figures read are
            validated: arena, agents and their vehicle, task): one line naming the file.
    """
    from pybullet_swarm.validation import parse_yaml

    path = Path(run_dir) / "scenario.yaml"
    if not path.is_file():
        return None
    text = _read_text(path)
    data = parse_yaml(text, source=str(path))
    if not isinstance(data, dict):
        raise ConfigError("corrupt: must hold a mapping of scenario sections", source=str(path))
    from pybullet_swarm.experiment.scenario import check_saved_scenario

    check_saved_scenario(data, source=str(path))
    return data


def read_events(path: Path) -> list[Event]:
    """Events of ``events.csv`` (empty when the file is missing; rows that cannot be read are skipped).

    Raises:
        ConfigError: the file is not text (binary, not UTF-8) or not CSV.
    """
    path = Path(path)
    if not path.is_file():
        return []
    text = _read_text(path)
    events = []
    try:
        for rec in csv.DictReader(io.StringIO(text, newline="")):
            try:
                events.append(
                    Event(
                        time_s=float(rec["time_s"]),
                        kind=str(rec["kind"]),
                        a=str(rec.get("a", "") or ""),
                        b=str(rec.get("b", "") or ""),
                        detail=str(rec.get("detail", "") or ""),
                    )
                )
            except (KeyError, TypeError, ValueError):
                continue
    except csv.Error as exc:
        raise ConfigError(f"unreadable: not CSV ({_reason(exc)})", source=str(path)) from None
    return [e for e in events if math.isfinite(e.time_s)]


def _open_npz(path: Path) -> Any:
    """``np.load`` of an ``.npz`` whose members would fit the memory budget (a zip bomb is refused unread)."""
    import zipfile

    import numpy as np

    from pybullet_swarm.memory import format_bytes, memory_budget

    try:
        with zipfile.ZipFile(path) as zf:
            size = sum(info.file_size for info in zf.infolist())
        if size > memory_budget():
            raise ConfigError(
                f"unreadable (its arrays would take {format_bytes(size)}, above the memory budget)", source=str(path)
            )
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(f"unreadable ({_reason(exc)})", source=str(path)) from None


def _npz_arrays(path: Path) -> dict[str, Any]:
    """Every array of an ``.npz`` file, read (decompressed) under the same guards as ``_open_npz``."""
    z = _open_npz(path)
    try:
        with z:
            return {k: z[k] for k in z.files}
    except Exception as exc:  # noqa: BLE001 - a member that cannot be read (truncated, bad CRC, zlib.error ...)
        raise ConfigError(f"unreadable ({_reason(exc)})", source=str(path)) from None


_SERIES_SHAPES = {
    "t": (),
    "positions": (3,),
    "quaternions": (4,),
    "velocities": (3,),
    "rotor_speeds": (4,),
    "ref_positions": (3,),
    "ref_velocities": (3,),
}


def read_timeseries(path: Path) -> Any:
    """The ``TimeSeries`` of ``timeseries.npz``, its arrays checked: present, numeric, of consistent shapes
    (``t`` (m,), per-agent channels (m, n, k)) and finite (the core channels).

    Raises:
        ConfigError: empty, truncated, garbage or inconsistent: one line naming the file.
    """
    import numpy as np

    from pybullet_swarm.experiment.recorder import TimeSeries

    path = Path(path)
    arrays = _npz_arrays(path)

    def bad(name: str, why: str) -> ConfigError:
        return ConfigError(f"corrupt: {why}", source=str(path), field=name)

    for name in _SERIES_SHAPES:
        if name not in arrays:
            raise bad(name, "array missing")
        if arrays[name].dtype.kind not in "fiu":
            raise bad(name, f"must hold numbers, got dtype {arrays[name].dtype}")
    t = arrays["t"]
    if t.ndim != 1:
        raise bad("t", f"must have shape (m,), got {t.shape}")
    m = t.shape[0]
    n = arrays["positions"].shape[1] if arrays["positions"].ndim == 3 else -1
    if n < 1:
        raise bad("positions", f"must have shape (m, n, 3) with n >= 1, got {arrays['positions'].shape}")
    for name, tail in _SERIES_SHAPES.items():
        want = (m, *(() if name == "t" else (n, *tail)))
        if arrays[name].shape != want:
            raise bad(name, f"must have shape {want}, got {arrays[name].shape}")
        if name in ("t", "positions", "quaternions", "velocities", "rotor_speeds") and not np.all(
            np.isfinite(arrays[name])
        ):
            raise bad(name, "must hold finite numbers")
    extra = {}
    for key, value in arrays.items():
        if key.startswith("extra_"):
            if value.dtype.kind not in "fiub" or value.ndim < 1 or value.shape[0] != m:
                raise bad(key, f"must hold numbers with {m} samples first, got {value.dtype} {value.shape}")
            extra[key[6:]] = value
    return TimeSeries(**{k: arrays[k] for k in _SERIES_SHAPES}, extra=extra)


def read_summary_csv(path: Path) -> list[dict[str, str]]:
    """The records of a ``summary.csv`` (text cells by column), checked: CSV text with ``config`` and
    ``metric`` columns and a value for both in every row.

    Raises:
        ConfigError: unreadable or not a summary table, in one line naming the file.
    """
    path = Path(path)
    text = _read_text(path)
    try:
        reader = csv.DictReader(io.StringIO(text, newline=""))
        records = list(reader)
        header = reader.fieldnames or []
    except csv.Error as exc:
        raise ConfigError(f"unreadable: not CSV ({_reason(exc)})", source=str(path)) from None
    if text.strip() and not {"config", "metric"} <= set(header):
        raise ConfigError("corrupt: not a summary table (no config and metric columns)", source=str(path))
    for i, rec in enumerate(records):
        if not isinstance(rec.get("config"), str) or not isinstance(rec.get("metric"), str) or None in rec:
            raise ConfigError(f"corrupt: row {i + 2} does not fit the header", source=str(path))
    return records


def check_saved_run(run_dir: Path) -> dict[str, Any]:
    """Read and check every result file of a run directory before anything is drawn from it.

    Returns:
        ``metrics`` (a mapping, empty without ``metrics.json``), ``timeseries``, ``scenario``
        (None without ``scenario.yaml``) and ``events``; ``pheromones.npz`` and ``tour.json`` are
        checked when present.

    Raises:
        ConfigError: the first missing, unreadable or corrupt file, in one line naming it.
    """
    run_dir = Path(run_dir)
    npz = run_dir / "timeseries.npz"
    if not npz.is_file():
        raise ConfigError("not a run directory (no timeseries.npz)", source=str(run_dir))
    out: dict[str, Any] = {
        "metrics": read_metrics(run_dir) if (run_dir / "metrics.json").is_file() else {},
        "timeseries": read_timeseries(npz),
        "scenario": read_scenario_data(run_dir),
        "events": read_events(run_dir / "events.csv"),
    }
    if (run_dir / "pheromones.npz").is_file():
        read_pheromones(run_dir / "pheromones.npz")
    if (run_dir / "tour.json").is_file():
        read_tour(run_dir / "tour.json")
    return out


def read_tour(path: Path) -> dict[str, Any]:
    """The data of ``tour.json`` (see ``TourRuntime.artefacts``), checked for the figure.

    Raises:
        ConfigError: unreadable or inconsistent: one line naming the file and the field.
    """
    import numpy as np

    path = Path(path)
    text = _read_text(path)
    try:
        data = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise ConfigError(f"unreadable: not JSON ({_reason(exc)})", source=str(path)) from None

    def bad(field: str, want: str) -> ConfigError:
        return ConfigError(f"corrupt: must be {want}", source=str(path), field=field)

    def points(value: Any, field: str, *, empty: bool = False) -> int:
        try:
            a = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise bad(field, "a list of [x, y, z] points") from None
        if a.ndim != 2 or a.shape[1] != 3 or (a.shape[0] == 0 and not empty) or not np.all(np.isfinite(a)):
            raise bad(field, "a list of finite [x, y, z] points")
        return int(a.shape[0])

    if not isinstance(data, dict):
        raise ConfigError("corrupt: must hold a mapping", source=str(path))
    w = points(data.get("points"), "points")
    size = data.get("arena_size")
    if size is not None and not (
        isinstance(size, list) and len(size) == 2 and all(is_number(v) and v > 0 for v in size)
    ):
        raise bad("arena_size", "two lengths > 0")
    radius = data.get("visit_radius")
    if radius is not None and not is_number(radius):
        raise bad("visit_radius", "a finite number")
    by = data.get("visited_by")
    if by is not None and not (
        isinstance(by, list)
        and len(by) == w
        and all(isinstance(v, int) and not isinstance(v, bool) and v >= -1 for v in by)
    ):
        raise bad("visited_by", f"a list of {w} agent indices (-1: not visited)")
    plan = data.get("plan")
    if plan is not None:
        if not isinstance(plan, dict):
            raise bad("plan", "a mapping")
        paths = plan.get("paths")
        if paths is not None:
            if not isinstance(paths, list):
                raise bad("plan.paths", "a list of paths")
            for i, p in enumerate(paths):
                points(p, f"plan.paths[{i}]", empty=True)
    return data


def read_pheromones(path: Path) -> dict[str, Any]:
    """The arrays of ``pheromones.npz`` (see ``PheromoneGrid.arrays``), checked for the figures.

    Raises:
        ConfigError: unreadable or inconsistent: one line naming the file.
    """
    import numpy as np

    path = Path(path)
    arrays = _npz_arrays(path)

    def bad(name: str, why: str) -> ConfigError:
        return ConfigError(f"corrupt: {why}", source=str(path), field=name)

    def numeric(name: str, ndim: int) -> Any:
        if name not in arrays:
            raise bad(name, "array missing")
        a = arrays[name]
        if a.dtype.kind not in "fiu" or a.ndim != ndim or not np.all(np.isfinite(a)):
            raise bad(name, f"must hold {ndim}-dimensional finite numbers, got {a.dtype} {a.shape}")
        return a

    cell = numeric("cell", 0)
    if not float(cell) > 0:
        raise bad("cell", "must be > 0")
    extent = numeric("extent", 1)
    if extent.shape != (3,) or not np.all(extent > 0):
        raise bad("extent", f"must be 3 lengths > 0, got {extent.tolist()}")
    t = numeric("snapshot_t", 1)
    layers = arrays.get("layers")
    if layers is None or layers.dtype.kind != "U" or layers.ndim != 1 or layers.size == 0:
        raise bad("layers", "must be a list of layer names")
    for name in (str(x) for x in layers):
        values = numeric(name, 3)
        hist = numeric(f"{name}_history", 3)
        if hist.shape[0] not in (0, t.shape[0]) or hist.shape[1:] != values.shape[:2] or 0 in values.shape:
            raise bad(
                f"{name}_history",
                f"must have shape ({t.shape[0]}, {values.shape[0]}, {values.shape[1]}), got {hist.shape}",
            )
        marked = numeric(f"{name}_marked", 1)
        if marked.shape != t.shape:
            raise bad(f"{name}_marked", f"must have shape {t.shape}, got {marked.shape}")
        if f"{name}_mass" in arrays and numeric(f"{name}_mass", 1).shape != t.shape:
            raise bad(f"{name}_mass", f"must have shape {t.shape}")
    return arrays


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
