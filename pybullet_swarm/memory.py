"""Memory budget: estimates of the largest arrays a run or a command allocates, refused above a budget.

Some parameters set array sizes: the cells of a pheromone grid (arena / ``cell_size``, up to
``grid_height``), the distance and pheromone matrices of an ant colony (points squared), its
best-so-far history (``iterations``), the recorder's buffers (time limit x record rate x agents).
A value inside its physical range can still ask for more memory than the machine has; such a
configuration is refused when it is loaded, with the bytes it would need, instead of failing
after minutes (or swapping the machine to a halt).

The budget is ``DEFAULT_BUDGET`` (4 GiB) unless the environment variable
``PYBULLET_SWARM_MEMORY_BUDGET`` says otherwise: a number of MiB (``8192``) or a size with a unit
(``512M``, ``16G``, ``16GiB``).
"""

from __future__ import annotations

import math
import os
import re

from pybullet_swarm.errors import ConfigError

ENV_VAR = "PYBULLET_SWARM_MEMORY_BUDGET"
DEFAULT_BUDGET = 4 << 30  # bytes

_UNITS = {"": 1 << 20, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


def memory_budget() -> int:
    """The memory budget, bytes (``PYBULLET_SWARM_MEMORY_BUDGET`` or ``DEFAULT_BUDGET``).

    Raises:
        ConfigError: the environment variable is not a positive size.
    """
    raw = os.environ.get(ENV_VAR, "").strip()
    if not raw:
        return DEFAULT_BUDGET
    m = re.fullmatch(r"([0-9]+(?:\.[0-9]*)?(?:[eE][-+]?[0-9]+)?)\s*([kKmMgGtT]?)(?:i?[bB])?", raw)
    value = float(m.group(1)) * _UNITS[m.group(2).lower()] if m else math.nan
    if not (math.isfinite(value) and value >= 1):
        raise ConfigError(f"must be a size such as 8192 (MiB), 512M or 16G, got {raw!r}", source=ENV_VAR)
    return int(value)


def format_bytes(n: float) -> str:
    """``n`` bytes in the largest binary unit that keeps it >= 1 (``22.4 GiB``)."""
    for unit, size in (("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def check_budget(need: float, what: str, *, source: str | None, field: str | None) -> None:
    """Refuse ``need`` bytes above the budget, in one line naming ``field`` and saying what needs them.

    Args:
        need: estimated bytes.
        what: what allocates them (``"a pheromone grid of 3000 x 1000 x 1000 cells"``).
        source: file (or option) for the message.
        field: the field whose value sets the size.

    Raises:
        ConfigError: ``need`` exceeds the budget.
    """
    budget = memory_budget()
    if need > budget:
        raise ConfigError(
            f"{what} would need about {format_bytes(need)}, above the memory budget of "
            f"{format_bytes(budget)} (set {ENV_VAR} to allow more)",
            source=source,
            field=field,
        )


def colony_bytes(n: int, *, ants: int, iterations: int, candidates: int | None) -> float:
    """Peak bytes of an ant colony on ``n`` cities (``planning.aco.solve_tsp``).

    The distance, pheromone and choice matrices are ``n x n`` float64, and building the
    nearest-neighbour lists sorts a copy of the distances (an int64 ``n x n`` argsort beside a
    float64 copy): measured 6.0-6.2 ``n x n`` float64 arrays at the peak (n = 300 .. 1200), taken
    as 6.5. Each iteration draws ``2 x ants x n`` random numbers and keeps ``ants x n`` tours; the
    history holds one float per iteration.
    """
    k = n - 1 if candidates is None else min(candidates, max(n - 1, 0))
    return 8.0 * (6.5 * n * n + 3.0 * ants * n + n * k + iterations)


def grid_bytes(cells: float, columns: float, layers: int, snapshots: float) -> float:
    """Bytes of a pheromone grid (``planning.pheromone_grid.PheromoneGrid``).

    Per layer and cell: the value (float64) and the source (int64), plus as much again in the
    temporaries of a projection or a count; per layer and snapshot, a float32 top view of
    ``columns`` cells, copied once when the run is saved.
    """
    return layers * (32.0 * cells + 8.0 * columns * snapshots)


def recorder_bytes(samples: float, agents: int, channels: int) -> float:
    """Bytes of the time-series buffers (float32 ``samples x agents x channels``), copied once when saved."""
    return 2.0 * 4.0 * samples * agents * channels
