"""Run directories: resolved scenario, metrics, time series, events and plots, written atomically."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import re
import shutil
import tempfile
import time
from pathlib import Path
from typing import IO, Any, Callable, Iterator

import yaml

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.types import Event


@contextlib.contextmanager
def exclusive_directory(out: Path, holder: str) -> Iterator[None]:
    """Hold ``out/.lock`` so that two ``holder``s (a sweep, a tuner) never write one directory at once."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield
        return
    out.mkdir(parents=True, exist_ok=True)
    with open(out / ".lock", "a+") as fh:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise ConfigError(f"another {holder} is writing this directory", source=str(out)) from None
        try:
            yield
        finally:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)


def atomic_write(path: Path, write: Callable[[Any], None], *, binary: bool = False) -> None:
    """Write ``path`` through a temporary file in the same directory, then rename it into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        fh: IO[Any] = os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", encoding="utf-8", newline="")
        with fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes files private; results are for sharing
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def write_json(path: Path, data: Any) -> None:
    """Atomically write JSON (indented, NaN refused)."""
    atomic_write(path, lambda fh: fh.write(json.dumps(data, indent=2, allow_nan=False) + "\n"))


def write_yaml(path: Path, data: Any) -> None:
    """Atomically write YAML."""
    atomic_write(path, lambda fh: yaml.safe_dump(data, fh, sort_keys=False))


def write_events(path: Path, events: list[Event]) -> None:
    """Atomically write events as CSV: time_s, kind, a, b, detail."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["time_s", "kind", "a", "b", "detail"])
    for e in events:
        w.writerow([f"{e.time_s:.6f}", e.kind, e.a, e.b, e.detail])
    atomic_write(path, lambda fh: fh.write(buf.getvalue()))


def safe_name(text: str, *, fallback: str = "scenario", limit: int = 64) -> str:
    """``text`` as one harmless path component: letters, digits, ``. _ -`` (others become ``_``).

    No path separator, no leading dot or dash (so never ``.``, ``..`` nor a hidden name), at most ``limit`` characters;
    ``fallback`` when nothing is left. A scenario's ``name`` is free text; directory names made
    from it stay inside the chosen output directory.
    """
    out = "".join(ch if (ch.isascii() and ch.isalnum()) or ch in "._-" else "_" for ch in str(text))
    out = re.sub(r"_{2,}", "_", out).lstrip("._-")[:limit].rstrip("_")
    return out or fallback


def default_run_dir(scenario: str, planner: str, seed: int, root: Path = Path("runs")) -> Path:
    """``runs/<scenario>-<planner>-s<seed>-<timestamp>`` (a suffix keeps it unique; names sanitised)."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    base = root / f"{safe_name(scenario)}-{safe_name(planner, fallback='planner')}-s{int(seed)}-{stamp}"
    candidate, k = base, 1
    while candidate.exists():
        candidate = Path(f"{base}-{k}")
        k += 1
    return candidate


def check_output_dir(path: Path, *, source: str | None = None) -> Path:
    """Refuse an output directory that cannot be written, before any work starts.

    The directory (and the missing parents) is created to try writing a file in it, then what
    was created is removed again: nothing is left behind by the check.

    Args:
        path: the directory.
        source: the option that named it (``--out``), for the message; default: the path.

    Raises:
        ConfigError: it exists and is not a directory, a parent is a file, or it cannot be
            created or written (permissions, a read-only file system, a name too long).
    """
    path = Path(path)
    where = f"{source} {path}" if source else str(path)
    created: list[Path] = []
    try:
        if path.exists() and not path.is_dir():
            raise ConfigError("exists and is not a directory", source=where)
        missing: list[Path] = []
        p = path
        while not p.exists():
            missing.append(p)
            if p.parent == p:
                break
            p = p.parent
        if p.exists() and not p.is_dir():
            raise ConfigError(f"cannot be created: {p} is a file, not a directory", source=where)
        for q in reversed(missing):
            q.mkdir()
            created.append(q)
        fd, probe = tempfile.mkstemp(prefix=".write-test-", dir=path)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        reason = exc.strerror or exc.__class__.__name__
        raise ConfigError(f"cannot write there ({reason})", source=where) from None
    finally:
        for q in reversed(created):
            try:
                q.rmdir()
            except OSError:
                pass
    return path


#: What a run directory holds (``runner.write_run``, the artifacts, ``--video``, a sweep's error.txt).
RUN_FILES = frozenset(
    {
        "scenario.yaml",
        "metrics.json",
        "timeseries.npz",
        "events.csv",
        "pheromones.npz",
        "tour.json",
        "video.mp4",
        "video.gif",
        "error.txt",
        "report.html",
        "frame.png",
    }
)
RUN_DIRS = frozenset({"plots"})


def _is_run_output(p: Path) -> bool:
    name = p.name
    if name in RUN_FILES or (name in RUN_DIRS and p.is_dir()):
        return True
    return name.startswith(".") and ".tmp" in name  # a temporary file of an interrupted atomic write


def check_run_dir(path: Path, *, source: str | None = None) -> Path:
    """Refuse a run directory that cannot be written or that holds files other than a run's.

    An empty or missing directory is used as is; a previous run's directory is replaced (see
    ``clear_run_dir``); a directory holding anything else (``--out .``, a folder of notes) is
    refused, so that a run never mixes its files with foreign ones nor deletes them.

    Raises:
        ConfigError: one line naming the directory.
    """
    path = check_output_dir(path, source=source)
    if path.is_dir():
        foreign = sorted(p.name for p in path.iterdir() if not _is_run_output(p))
        if foreign:
            shown = ", ".join(foreign[:3]) + (" ..." if len(foreign) > 3 else "")
            where = f"{source} {path}" if source else str(path)
            raise ConfigError(
                f"is not empty and not a run directory (holds {shown}); use a new or empty directory", source=where
            )
    return path


def clear_run_dir(path: Path, keep: frozenset[str] = frozenset()) -> None:
    """Remove a previous run's files from ``path`` (``RUN_FILES``, ``plots/``, temporaries) except ``keep``.

    A run written into a previous run's directory replaces it: figures, artifacts and the video
    of the old run that the new one does not write again would otherwise sit beside the new
    metrics. ``metrics.json`` goes first, so the directory never looks like a finished run
    while it is being replaced.
    """
    path = Path(path)
    if not path.is_dir():
        return
    old = sorted(
        (p for p in path.iterdir() if _is_run_output(p) and p.name not in keep), key=lambda p: p.name != "metrics.json"
    )
    for p in old:
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        else:
            p.unlink()
