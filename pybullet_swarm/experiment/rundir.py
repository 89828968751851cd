"""Run directories: resolved scenario, metrics, time series, events and plots, written atomically."""
from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Iterator

import yaml

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.types import Event


@contextlib.contextmanager
def exclusive_directory(out: Path, holder: str) -> Iterator[None]:
    """Hold ``out/.lock`` so that two ``holder``s (a sweep, a tuner) never write one directory at once."""
    try:
        import fcntl
    except ImportError:    # not POSIX: no lock
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
        with os.fdopen(fd, "wb" if binary else "w", **({} if binary else {"encoding": "utf-8", "newline": ""})) as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)   # mkstemp makes files private; results are for sharing
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


def default_run_dir(scenario: str, planner: str, seed: int, root: Path = Path("runs")) -> Path:
    """``runs/<scenario>-<planner>-s<seed>-<timestamp>`` (a suffix keeps it unique)."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    base = root / f"{scenario}-{planner}-s{seed}-{stamp}"
    candidate, k = base, 1
    while candidate.exists():
        candidate = Path(f"{base}-{k}")
        k += 1
    return candidate
