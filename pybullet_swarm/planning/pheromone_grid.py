"""The pheromone medium: named layers of a 3-D grid of cells over the arena that agents mark and read.

This is the shared environment of the stigmergy planners (thesis chapters 5 and 6): the arena
[0, Lx] x [0, Ly] x [0, height] is cut into cubic cells (10 cm in the thesis: a 30 x 10 x 10 grid
over the 3 x 1 m floor), each layer holds one value per cell, and every value fades towards zero
at the layer's rate. A value's sign carries meaning for the planners (the thesis marks boxes
with +1 and goals with -1 in the same layer).

Deposits made while the agents plan are queued and applied when the simulation calls ``step``
once per planner tick, after every agent has planned: agents of one tick all read the same grid,
so the order in which the simulation asks them does not matter. Each cell remembers which agent
marked it last (its "source"), so an agent can tell its own scent from the others'.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

NO_SOURCE = -1
"""Source of a cell that nobody marked (or whose mark has faded)."""
FADED = 1e-9
"""A value that fatigue brought below this magnitude is gone (rounding residue of linear decay)."""


class DepositRule(enum.Enum):
    """How a deposit combines with the value already in a cell."""

    ADD = "add"  # amplify: value += amount
    SET = "set"  # overwrite: value = amount (the thesis's rule)


@dataclasses.dataclass(frozen=True)
class LayerSpec:
    """One kind of pheromone.

    Attributes:
        name: how planners address the layer.
        fatigue: value units per second by which every value moves towards zero (linear decay,
            the thesis's "pheromone fatigue": 2/s erases a 2 in one second).
        evaporation: 1/s, exponential decay rate (value *= exp(-evaporation dt)), applied first.
    """

    name: str
    fatigue: float = 0.0
    evaporation: float = 0.0

    def __post_init__(self) -> None:
        if not self.name:
            raise ValueError("LayerSpec.name: must not be empty")
        if not (math.isfinite(self.fatigue) and self.fatigue >= 0.0):
            raise ValueError(f"LayerSpec.fatigue: must be finite and >= 0, got {self.fatigue}")
        if not (math.isfinite(self.evaporation) and self.evaporation >= 0.0):
            raise ValueError(f"LayerSpec.evaporation: must be finite and >= 0, got {self.evaporation}")


class PheromoneGrid:
    """Pheromone layers on a grid of cubic cells over the arena (the medium of the stigmergy planners).

    Positions outside the grid are clipped into the border cells, as the thesis did.

    Args:
        arena_size: (2,) m, (Lx, Ly) of the floor.
        layers: the kinds of pheromone, names unique.
        cell: m, edge of a cell.
        height: m, top of the grid.
        snapshot_s: s, period of the horizontal snapshots kept for the figures (0: none).

    Attributes:
        shape: (nx, ny, nz) cells.
        values: layer name -> (nx, ny, nz) value of each cell.
        sources: layer name -> (nx, ny, nz) id of the agent that marked each cell last (``NO_SOURCE``: none).
        deposits: layer name -> number of marks applied.
        tallies: planner event name -> count.
        time_s: s, time stepped so far.
    """

    def __init__(
        self,
        arena_size: ArrayLike,
        layers: Sequence[LayerSpec],
        *,
        cell: float = 0.1,
        height: float = 1.0,
        snapshot_s: float = 1.0,
    ) -> None:
        size = np.asarray(arena_size, dtype=float).ravel()
        if size.size < 2 or not np.all(np.isfinite(size[:2])) or np.any(size[:2] <= 0):
            raise ValueError(f"arena_size: expected two positive lengths, got {size.tolist()}")
        if not (math.isfinite(cell) and cell > 0):
            raise ValueError(f"cell: must be > 0, got {cell}")
        if not (math.isfinite(height) and height > 0):
            raise ValueError(f"height: must be > 0, got {height}")
        if not (math.isfinite(snapshot_s) and snapshot_s >= 0):
            raise ValueError(f"snapshot_s: must be >= 0, got {snapshot_s}")
        names = [spec.name for spec in layers]
        if not names:
            raise ValueError("layers: needs at least one layer")
        if len(set(names)) != len(names):
            raise ValueError(f"layers: names must be unique, got {names}")
        self.cell = float(cell)
        self.extent = np.array([size[0], size[1], float(height)])  # (3,) m
        # the small offset keeps 3.0 / 0.1 = 29.999... from adding a sliver cell
        self.shape = tuple(int(k) for k in np.maximum(1, np.ceil(self.extent / self.cell - 1e-9)))  # (nx, ny, nz)
        self.specs = {spec.name: spec for spec in layers}
        self.values = {name: np.zeros(self.shape) for name in names}  # value per cell
        self.sources = {name: np.full(self.shape, NO_SOURCE, dtype=np.int64) for name in names}
        self.deposits = {name: 0 for name in names}
        self.tallies: dict[str, int] = {}
        self.time_s = 0.0
        self._pending: list[tuple[str, int, float, DepositRule, int]] = []
        self.snapshot_s = float(snapshot_s)
        self._next_snapshot = 0.0
        self.snapshot_t: list[float] = []
        self.snapshots: dict[str, list[NDArray[np.float32]]] = {name: [] for name in names}
        self.mass: dict[str, list[float]] = {name: [] for name in names}  # sum of |values| per snapshot
        self.marked: dict[str, list[int]] = {name: [] for name in names}

    # ------------------------------------------------------------- geometry
    @property
    def layer_names(self) -> tuple[str, ...]:
        """Names of the layers."""
        return tuple(self.specs)

    def _check(self, layer: str) -> None:
        if layer not in self.specs:
            raise KeyError(f"unknown pheromone layer {layer!r}; layers: {', '.join(self.specs)}")

    def index(self, points: ArrayLike) -> NDArray[np.int64]:
        """Cell indices of points.

        Args:
            points: (3,) or (k, 3) m.

        Returns:
            (3,) or (k, 3) integer indices, clipped into the grid.
        """
        p = np.asarray(points, dtype=float)
        idx = np.floor(p / self.cell + 1e-9).astype(np.int64)
        return np.clip(idx, 0, np.asarray(self.shape) - 1)

    def centre(self, index: ArrayLike) -> NDArray[np.float64]:
        """Centres (3,) or (k, 3) m of cells given by integer indices."""
        return (np.asarray(index, dtype=float) + 0.5) * self.cell

    def _flat(self, points: ArrayLike) -> NDArray[np.int64]:
        idx = self.index(np.atleast_2d(np.asarray(points, dtype=float)))
        return np.ravel_multi_index(tuple(idx.T), self.shape)

    # ------------------------------------------------------------- reading
    def values_at(self, layer: str, points: ArrayLike, *, exclude_source: int | None = None) -> NDArray[np.float64]:
        """Values of the cells holding each point.

        Args:
            layer: layer name.
            points: (k, 3) m.
            exclude_source: cells last marked by this agent read as 0 (an agent ignores its own scent).

        Returns:
            (k,) values.
        """
        self._check(layer)
        flat = self._flat(points)
        v = self.values[layer].ravel()[flat]
        if exclude_source is not None:
            v = np.where(self.sources[layer].ravel()[flat] == exclude_source, 0.0, v)
        return v

    def sample(self, layer: str, p: ArrayLike, *, exclude_source: int | None = None) -> float:
        """Value of the cell holding position ``p`` (3,) m."""
        # one point, as planners ask for every agent at every tick: the cell index in Python scalars
        # (the same float64 arithmetic as ``index``), without building (1, 3) arrays
        self._check(layer)
        q = np.asarray(p, dtype=float)
        c, (nx, ny, nz) = self.cell, self.shape
        try:
            i = min(max(math.floor(float(q[0]) / c + 1e-9), 0), nx - 1)
            j = min(max(math.floor(float(q[1]) / c + 1e-9), 0), ny - 1)
            k = min(max(math.floor(float(q[2]) / c + 1e-9), 0), nz - 1)
        except (ValueError, OverflowError):  # not finite: as ``values_at`` clips it
            return float(self.values_at(layer, np.reshape(q, (1, 3)), exclude_source=exclude_source)[0])
        if exclude_source is not None and self.sources[layer][i, j, k] == exclude_source:
            return 0.0
        return float(self.values[layer][i, j, k])

    def strongest(
        self,
        layer: str,
        sign: int = +1,
        *,
        near: ArrayLike | None = None,
        distance_scale: float | None = None,
        rng: np.random.Generator | None = None,
        by_column: bool = False,
        first_by: tuple[int, ...] | None = None,
    ) -> NDArray[np.float64] | None:
        """Centre (3,) m of the cell with the strongest value of the given sign, or None when no cell has one.

        Args:
            layer: layer name.
            sign: +1 for the largest positive value, -1 for the most negative one.
            near: (3,) m, a reference position: among equally strong cells the nearest wins.
            distance_scale: m; when given (with ``near``), nearer cells appear stronger: the cell
                maximising ``sign * value / (1 + distance / distance_scale)`` wins.
            rng: when given, equally strong cells are drawn from at random (before ``near`` is
                considered); otherwise, without ``near``, the first in index order wins.
            by_column: equally strong cells stacked in one vertical column count once (the lowest
                stands for them) in the random draw, so that a column marked at several
                altitudes is not drawn more often than one marked once.
            first_by: axes from most to least significant (e.g. ``(1, 2, 0)``); when given (and no
                ``rng``), the first of equally strong cells in that order wins, whatever ``near`` is.
        """
        self._check(layer)
        if sign not in (-1, 1):
            raise ValueError(f"sign: must be +1 or -1, got {sign}")
        if distance_scale is not None and not distance_scale > 0:
            raise ValueError(f"distance_scale: must be > 0, got {distance_scale}")
        v = sign * self.values[layer].ravel()
        top = float(v.max())
        if top <= 0.0:
            return None
        if distance_scale is not None and near is not None:
            cand = np.flatnonzero(v > 0.0)
            d = np.linalg.norm(
                self.centre(np.stack(np.unravel_index(cand, self.shape), axis=1)) - np.asarray(near, dtype=float),
                axis=1,
            )
            score = v[cand] / (1.0 + d / distance_scale)
            cand = cand[score >= score.max() - 1e-12]
        else:
            cand = np.flatnonzero(v >= top - 1e-12)
        idx = np.stack(np.unravel_index(cand, self.shape), axis=1)
        if by_column and rng is not None:
            _, first = np.unique(idx[:, :2], axis=0, return_index=True)
            idx = idx[np.sort(first)]
        centres = self.centre(idx)
        if rng is not None:
            return centres[int(rng.integers(len(centres)))]
        if first_by is not None:
            return centres[int(np.lexsort(tuple(idx[:, a] for a in reversed(first_by)))[0])]
        if near is None:
            return centres[0]
        return centres[int(np.argmin(np.linalg.norm(centres - np.asarray(near, dtype=float), axis=1)))]

    def projection(self, layer: str) -> NDArray[np.float64]:
        """(nx, ny) view from above: in each column, the value of largest magnitude (its sign kept)."""
        self._check(layer)
        v = self.values[layer]
        k = np.argmax(np.abs(v), axis=2)
        return np.take_along_axis(v, k[:, :, None], axis=2)[:, :, 0]

    # ------------------------------------------------------------- writing
    def deposit(
        self, layer: str, p: ArrayLike, amount: float, *, rule: DepositRule = DepositRule.ADD, source: int = NO_SOURCE
    ) -> None:
        """Queue a mark in the cell holding ``p`` (3,) m; it takes effect at the next ``step``.

        With ``DepositRule.SET`` several marks of one tick in the same cell resolve to the one of
        largest magnitude (a found box outweighs a trail); ``ADD`` marks sum, on top of any SET.
        """
        self._check(layer)
        if not math.isfinite(amount):
            raise ValueError(f"amount: must be finite, got {amount}")
        flat = int(self._flat(np.reshape(np.asarray(p, dtype=float), (1, 3)))[0])
        self._pending.append((layer, flat, float(amount), rule, int(source)))

    def tally(self, name: str, k: int = 1) -> None:
        """Count a planner event (a search strategy chosen, a re-plan); reported by ``metrics``."""
        self.tallies[name] = self.tallies.get(name, 0) + int(k)

    def step(self, dt: float) -> None:
        """Let every value fade for ``dt`` s, then apply the marks queued since the last step."""
        if dt < 0:
            raise ValueError(f"dt: must be >= 0, got {dt}")
        for name, spec in self.specs.items():
            v = self.values[name]
            if spec.evaporation > 0.0:
                v *= math.exp(-spec.evaporation * dt)
            if spec.fatigue > 0.0:
                np.copysign(np.maximum(np.abs(v) - spec.fatigue * dt, 0.0), v, out=v)
                v[np.abs(v) < FADED] = 0.0  # 2 - 10 x 0.2 is not exactly 0 in floating point
            if spec.evaporation > 0.0 or spec.fatigue > 0.0:
                self.sources[name][v == 0.0] = NO_SOURCE
        self._apply_pending()
        self.time_s += dt
        if self.snapshot_s > 0.0 and self.time_s >= self._next_snapshot - 1e-9:
            self._snapshot()
            self._next_snapshot = (math.floor(self.time_s / self.snapshot_s + 1e-9) + 1) * self.snapshot_s

    def _apply_pending(self) -> None:
        if not self._pending:
            return
        pending, self._pending = self._pending, []
        for name in self.specs:
            mine = [d for d in pending if d[0] == name]
            if not mine:
                continue
            self.deposits[name] += len(mine)
            flat = np.array([d[1] for d in mine], dtype=np.int64)
            amount = np.array([d[2] for d in mine])
            source = np.array([d[4] for d in mine], dtype=np.int64)
            is_set = np.array([d[3] is DepositRule.SET for d in mine])
            v, src = self.values[name].ravel(), self.sources[name].ravel()  # views
            if is_set.any():
                f, a, s = flat[is_set], amount[is_set], source[is_set]
                # per cell the SET of largest magnitude wins (the last one on a tie): sort, keep each cell's last
                order = np.lexsort((np.abs(a), f))
                f, a, s = f[order], a[order], s[order]
                last = np.r_[f[1:] != f[:-1], True]
                v[f[last]] = a[last]
                src[f[last]] = s[last]
            if (~is_set).any():
                f, a, s = flat[~is_set], amount[~is_set], source[~is_set]
                np.add.at(v, f, a)
                src[f] = s
            src[v == 0.0] = NO_SOURCE

    def _snapshot(self) -> None:
        self.snapshot_t.append(self.time_s)
        for name in self.specs:
            self.snapshots[name].append(self.projection(name).astype(np.float32))
            self.marked[name].append(int(np.count_nonzero(self.values[name])))
            self.mass[name].append(float(np.abs(self.values[name]).sum()))

    # ------------------------------------------------------------- results
    def metrics(self) -> dict[str, Any]:
        """Per layer: cells marked now, extreme values, number of deposits; and the planners' tallies."""
        out: dict[str, Any] = {}
        for name, v in self.values.items():
            out[name] = {
                "cells_marked": int(np.count_nonzero(v)),
                "max": float(v.max()),
                "min": float(v.min()),
                "deposits": self.deposits[name],
            }
        out["tallies"] = dict(sorted(self.tallies.items()))
        return {"pheromone": out}

    def arrays(self) -> dict[str, NDArray[Any]]:
        """Everything ``write`` saves, by name: the grid geometry, each layer's values and sources,
        and the horizontal snapshots ``<layer>_history`` (k, nx, ny) at ``snapshot_t`` (k,) s."""
        out: dict[str, NDArray[Any]] = {
            "cell": np.array(self.cell),
            "extent": self.extent.copy(),
            "time_s": np.array(self.time_s),
            "layers": np.array(self.layer_names),
            "snapshot_t": np.array(self.snapshot_t),
        }
        for name in self.specs:
            out[name] = self.values[name].copy()
            out[f"{name}_source"] = self.sources[name].copy()
            hist = self.snapshots[name]
            out[f"{name}_history"] = np.stack(hist) if hist else np.zeros((0, *self.shape[:2]), dtype=np.float32)
            out[f"{name}_marked"] = np.array(self.marked[name], dtype=np.int64)
            out[f"{name}_mass"] = np.array(self.mass[name], dtype=float)
        return out

    def artefacts(self) -> dict[str, Any]:
        """``pheromones.npz``: the arrays of ``arrays`` plus ``persistent``, the layers that neither
        evaporate nor fatigue (``pybullet-swarm plot`` draws the maps from this file)."""
        arrays = self.arrays()
        lasting = [n for n, s in self.specs.items() if s.fatigue == 0 and s.evaporation == 0]
        arrays["persistent"] = np.array(lasting, dtype=str)
        return {"pheromones.npz": arrays}
