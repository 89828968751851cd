"""Ant colony optimisation for the symmetric travelling salesman problem.

Two colonies are available (Dorigo & Stuetzle, *Ant Colony Optimization*, MIT Press 2004):

* **Ant System (AS)**: every ant deposits ``1 / L`` on the edges of its tour after all trails
  evaporate by the fraction ``rho``; ``rho = 0`` keeps every deposit (no evaporation).
* **Ant Colony System (ACS)**: the pseudo-random proportional rule (with probability ``q0`` an
  ant takes the best-looking edge instead of sampling), a local update that pulls each edge an
  ant crosses back towards ``tau0`` (rate ``xi``), and a global update by the best-so-far tour
  only.

Either colony can use candidate (nearest-neighbour) lists, the linear alpha/beta schedules of
the course report the module reproduces (alpha rising from 0 while beta falls to 0, with or
without the factor 2 that keeps their means at the nominal values) and a local search of every
ant's tour: 2-opt, optionally followed by Or-opt, both driven by neighbour lists and
don't-look bits. Tour construction and local search are compiled with numba; random numbers
come from a ``numpy.random.Generator`` drawn in Python, so a seed fixes the whole run.

Distances are an (n, n) symmetric matrix in any length unit; tour lengths are in that unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import Field

from pybullet_swarm.planning.params import Params

__all__ = [
    "ACOParams",
    "ACOResult",
    "LocalSearch",
    "Schedule",
    "Variant",
    "nearest_neighbour_lists",
    "schedule_values",
    "solve_tsp",
    "tour_length",
    "two_opt",
]


class Variant(Enum):
    """Which pheromone rules the colony follows."""

    AS = "as"  # Ant System: evaporation everywhere, every ant deposits
    ACS = "acs"  # Ant Colony System: local update while building, best-so-far deposits


class Schedule(Enum):
    """How alpha and beta change over the iterations (k of n, see :func:`schedule_values`)."""

    CONSTANT = "constant"  # alpha_k = A, beta_k = B
    LINEAR = "linear"  # alpha_k = 2 (k/n) A, beta_k = 2 ((n-k)/n) B: means stay A and B
    LINEAR_NO_FACTOR = "linear-no-factor"  # alpha_k = (k/n) A, beta_k = ((n-k)/n) B


class LocalSearch(Enum):
    """Improvement applied to every ant's tour before the pheromone update."""

    NONE = "none"
    TWO_OPT = "2opt"
    TWO_OPT_OR_OPT = "2opt+oropt"  # alternate 2-opt and Or-opt until neither improves


_LS_CODE = {LocalSearch.NONE: 0, LocalSearch.TWO_OPT: 1, LocalSearch.TWO_OPT_OR_OPT: 2}
_OR_OPT_NEIGHBOURS = 10  # insertion points tried per segment end; more rarely pays


class ACOParams(Params):
    """Settings of an ant colony; refused at construction when out of range.

    The defaults (ACS, q0 = 0.9, 10 ants, 500 iterations, 15 candidates, 2-opt and Or-opt on
    every ant) found the optimum of TSPLIB eil51, berlin52, st70, eil76, pr76, rat99 and kroA100
    in 10 of 10 seeded runs each, in well under a second per run. ``tau0`` null uses ants / L_nn
    (AS) or 1 / (n L_nn) (ACS), L_nn the nearest-neighbour tour length.
    """

    variant: Variant = Field(
        Variant.ACS, strict=False, description="pheromone rules: as (Ant System) or acs (Ant Colony System)"
    )
    alpha: float = Field(1.0, ge=0.0, le=100.0, description="pheromone exponent A (the schedule's nominal value)")
    beta: float = Field(
        2.0, ge=0.0, le=100.0, description="heuristic exponent B on 1 / distance (the schedule's nominal value)"
    )
    rho: float = Field(
        0.1,
        ge=0.0,
        le=1.0,
        description="evaporation fraction per iteration (ACS: also the weight of the best-so-far deposit)",
    )
    ants: int = Field(10, ge=1, le=1000, description="ants per iteration")
    iterations: int = Field(500, ge=1, le=100_000, description="iterations of the colony")
    q0: float = Field(
        0.9, ge=0.0, le=1.0, description="probability of taking the best-looking edge instead of sampling (0: as AS)"
    )
    xi: float = Field(0.1, ge=0.0, le=1.0, description="ACS local update rate (unused by AS)")
    schedule: Schedule = Field(
        Schedule.CONSTANT,
        strict=False,
        description="alpha/beta over the iterations: constant, linear or linear-no-factor",
    )
    local_search: LocalSearch = Field(
        LocalSearch.TWO_OPT_OR_OPT,
        strict=False,
        description="improvement of every ant's tour: none, 2opt or 2opt+oropt",
    )
    candidates: int | None = Field(
        15, ge=1, le=1000, description="nearest-neighbour list ants choose from first (null: every city)"
    )
    ls_neighbours: int = Field(20, ge=1, le=1000, description="nearest-neighbour lists that drive the local search")
    tau0: float | None = Field(
        None, gt=0.0, le=1e30, description="initial pheromone (null: from the nearest-neighbour tour)"
    )


@dataclass(frozen=True)
class ACOResult:
    """Best tour a colony found.

    Attributes:
        tour: (n,) city indices, starting at city 0 and oriented so that tour[1] < tour[-1].
        length: closed length of ``tour`` in distance units.
        history: (iterations,) best-so-far length after each iteration.
        best_iteration: index of the iteration that found ``tour``.
    """

    tour: NDArray[np.int64] = field(compare=False)
    length: float
    history: NDArray[np.float64] = field(repr=False, compare=False)
    best_iteration: int


def schedule_values(params: ACOParams, k: int) -> tuple[float, float]:
    """Return (alpha_k, beta_k) at step k of ``params.iterations`` = n under ``params.schedule``.

    :func:`solve_tsp` uses k = i + 1 at iteration i = 0 .. n-1 (the report counts from 1), so
    a linear schedule ends on pure pheromone (beta = 0).

    Args:
        params: colony settings; alpha and beta are the nominal values A and B.
        k: step, 0 <= k <= n.

    Raises:
        ValueError: k outside 0 .. n.
    """
    n = params.iterations
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k <= n:
        raise ValueError(f"k: expected an integer in 0..{n}, got {k!r}")
    if params.schedule is Schedule.CONSTANT:
        return params.alpha, params.beta
    factor = 2.0 if params.schedule is Schedule.LINEAR else 1.0
    return factor * (k / n) * params.alpha, factor * ((n - k) / n) * params.beta


def tour_length(dist: ArrayLike, tour: ArrayLike) -> float:
    """Closed length of ``tour`` ((n,) permutation of 0..n-1) under ``dist`` (n, n)."""
    d = np.asarray(dist, dtype=np.float64)
    t = _as_tour(tour, d.shape[0])
    return float(d[t, np.roll(t, -1)].sum())


def nearest_neighbour_lists(dist: ArrayLike, k: int) -> NDArray[np.int64]:
    """(n, min(k, n-1)) indices of each city's nearest other cities, nearest first."""
    d = np.array(dist, dtype=np.float64)
    n = d.shape[0]
    np.fill_diagonal(d, np.inf)
    k = max(0, min(int(k), n - 1))
    return np.ascontiguousarray(np.argsort(d, axis=1, kind="stable")[:, :k], dtype=np.int64)


def two_opt(
    dist: ArrayLike, tour: ArrayLike, *, neighbours: int | None = 20, or_opt: bool = False
) -> NDArray[np.int64]:
    """Improve ``tour`` to a 2-opt local optimum (and Or-opt optimum when ``or_opt``).

    Moves are searched from each city's nearest neighbours with don't-look bits, so the
    result is a local optimum with respect to those neighbourhoods; ``neighbours=None`` uses
    all cities. The tour never gets longer.

    Args:
        dist: (n, n) symmetric distances.
        tour: (n,) permutation of 0..n-1.
        neighbours: neighbour-list length, or None for all n - 1 cities.
        or_opt: also move segments of 1-3 cities elsewhere, alternating with 2-opt.

    Returns:
        (n,) improved tour (a new array).
    """
    d = _check_dist(dist)
    n = d.shape[0]
    out = _as_tour(tour, n).copy()
    if n < 5:
        return out
    if neighbours is not None:
        _check_int("neighbours", neighbours, low=1)
    nn = nearest_neighbour_lists(d, n - 1 if neighbours is None else neighbours)
    _local_search(d, out, nn, 2 if or_opt else 1, _tolerance(d))
    return out


def solve_tsp(
    dist: ArrayLike, params: ACOParams | None = None, *, seed: int | None = None, rng: np.random.Generator | None = None
) -> ACOResult:
    """Search for a short closed tour through all cities with an ant colony.

    Args:
        dist: (n, n) symmetric, non-negative distances.
        params: colony settings (defaults: :class:`ACOParams`).
        seed: seed of a fresh generator; mutually exclusive with ``rng``.
        rng: generator to draw from; neither given means fresh OS entropy.

    Returns:
        The best tour found, its length and the best-so-far history.

    Raises:
        ValueError: bad distances, or both ``seed`` and ``rng`` given.
    """
    params = ACOParams() if params is None else params
    d = _check_dist(dist)
    if seed is not None and rng is not None:
        raise ValueError("seed, rng: give at most one")
    gen = rng if rng is not None else np.random.default_rng(seed)
    n = d.shape[0]
    if n < 4:  # every tour is optimal
        tour = np.arange(n, dtype=np.int64)
        length = tour_length(d, tour)
        return ACOResult(tour, length, np.full(params.iterations, length), 0)
    return _Colony(d, params, gen).run()


class _Colony:
    """State of one run: pheromone, heuristic, neighbour lists and the best tour so far."""

    def __init__(self, dist: NDArray[np.float64], params: ACOParams, rng: np.random.Generator) -> None:
        n = dist.shape[0]
        self.dist, self.params, self.rng, self.n = dist, params, rng, n
        self.eps = _tolerance(dist)
        self.use_candidates = params.candidates is not None and params.candidates < n - 1
        self.cand = nearest_neighbour_lists(dist, params.candidates or n - 1)
        self.ls_nn = nearest_neighbour_lists(dist, params.ls_neighbours)
        self.eta = _heuristic(dist, self.cand)
        l_nn = _nearest_neighbour_tour_length(dist)
        if params.tau0 is not None:
            self.tau0 = params.tau0
        elif params.variant is Variant.AS:
            self.tau0 = params.ants / l_nn
        else:
            self.tau0 = 1.0 / (n * l_nn)
        self.tau = np.full((n, n), self.tau0)
        self.ls_mode = _LS_CODE[params.local_search]

    def run(self) -> ACOResult:
        """Run all iterations and return the best tour."""
        p = self.params
        history = np.empty(p.iterations)
        best_tour = np.arange(self.n, dtype=np.int64)
        best_len, best_iter = math.inf, 0
        for i in range(p.iterations):
            tours, lengths = self._iterate(*schedule_values(p, i + 1))
            j = int(np.argmin(lengths))
            if lengths[j] < best_len - self.eps:
                best_tour, best_len, best_iter = tours[j].copy(), float(lengths[j]), i
            self._update_pheromone(tours, lengths, best_tour, best_len)
            history[i] = best_len
        tour = _canonical(best_tour)
        return ACOResult(tour, tour_length(self.dist, tour), history, best_iter)

    def _iterate(self, alpha: float, beta: float) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Let every ant build (and improve) a tour; return (ants, n) tours and their lengths."""
        p = self.params
        scale = 1.0 / float(self.tau.max())  # choice weights are scale-free; keeps powers finite
        eta_pow = self.eta**beta
        choice = (self.tau * scale) ** alpha * eta_pow
        starts = self.rng.integers(self.n, size=p.ants)
        draws = self.rng.random((2, p.ants, self.n))
        xi = p.xi if p.variant is Variant.ACS else 0.0
        return _build_and_improve(
            self.dist,
            choice,
            self.tau,
            eta_pow,
            scale,
            alpha,
            self.cand,
            self.use_candidates,
            p.q0,
            xi,
            self.tau0,
            starts,
            draws[0],
            draws[1],
            self.ls_nn,
            self.ls_mode,
            self.eps,
        )

    def _update_pheromone(
        self, tours: NDArray[np.int64], lengths: NDArray[np.float64], best_tour: NDArray[np.int64], best_len: float
    ) -> None:
        """Evaporate and deposit: all ants (AS) or the best-so-far tour (ACS)."""
        rho = self.params.rho
        if self.params.variant is Variant.AS:
            self.tau *= 1.0 - rho
            _deposit(self.tau, tours, 1.0 / np.maximum(lengths, self.eps))
        else:
            a, b = best_tour, np.roll(best_tour, -1)
            self.tau[a, b] = (1.0 - rho) * self.tau[a, b] + rho / max(best_len, self.eps)
            self.tau[b, a] = self.tau[a, b]


def _check_int(name: str, value: object, *, low: int) -> None:
    """Refuse a parameter that is not an integer >= low."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")


def _check_dist(dist: ArrayLike) -> NDArray[np.float64]:
    """Validated (n, n) float64 distance matrix (C-contiguous)."""
    try:
        d = np.ascontiguousarray(dist, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("dist: expected an (n, n) array of numbers") from None
    if d.ndim != 2 or d.shape[0] != d.shape[1] or d.shape[0] == 0:
        raise ValueError(f"dist: expected a non-empty square (n, n) matrix, got shape {d.shape}")
    if not np.all(np.isfinite(d)) or np.any(d < 0):
        raise ValueError("dist: expected finite, non-negative distances")
    if not np.allclose(d, d.T, rtol=1e-9, atol=0.0):
        raise ValueError("dist: expected a symmetric matrix (symmetric TSP)")
    return d


def _as_tour(tour: ArrayLike, n: int) -> NDArray[np.int64]:
    """Validated (n,) permutation of 0..n-1 as int64."""
    t = np.asarray(tour)
    if t.shape != (n,) or not np.issubdtype(t.dtype, np.integer) or not np.array_equal(np.sort(t), np.arange(n)):
        raise ValueError(f"tour: expected a permutation of 0..{n - 1}")
    return t.astype(np.int64)


def _tolerance(dist: NDArray[np.float64]) -> float:
    """Smallest length change counted as an improvement (guards against float cycling)."""
    return 1e-10 * max(1.0, float(dist.max()))


def _heuristic(dist: NDArray[np.float64], cand: NDArray[np.int64]) -> NDArray[np.float64]:
    """eta = d_ref / distance, (n, n); d_ref (nearest-neighbour distance) keeps eta near 1."""
    nearest = dist[np.arange(dist.shape[0]), cand[:, 0]]
    positive = nearest[nearest > 0]
    d_ref = float(np.median(positive)) if positive.size else max(float(dist.max()), 1.0)
    return d_ref / np.maximum(dist, 1e-3 * d_ref)  # coincident cities: strongly attractive


def _nearest_neighbour_tour_length(dist: NDArray[np.float64]) -> float:
    """Length of the greedy nearest-neighbour tour from city 0 (scale of tau0)."""
    n = dist.shape[0]
    visited = np.zeros(n, dtype=bool)
    city, total = 0, 0.0
    visited[0] = True
    for _ in range(n - 1):
        row = np.where(visited, np.inf, dist[city])
        nxt = int(np.argmin(row))
        total += float(row[nxt])
        visited[nxt] = True
        city = nxt
    total += float(dist[city, 0])
    return max(total, 1e-12)


def _canonical(tour: NDArray[np.int64]) -> NDArray[np.int64]:
    """The same cycle starting at city 0, oriented so that tour[1] < tour[-1]."""
    t = np.roll(tour, -int(np.flatnonzero(tour == 0)[0]))
    if t[1] > t[-1]:
        t = np.concatenate((t[:1], t[1:][::-1]))
    return t


@numba.njit(cache=True)
def _deposit(tau: np.ndarray, tours: np.ndarray, amounts: np.ndarray) -> None:
    """Add amounts[a] to both directions of every edge of tours[a] ((ants, n))."""
    ants, n = tours.shape
    for a in range(ants):
        for k in range(n):
            i, j = tours[a, k], tours[a, (k + 1) % n]
            tau[i, j] += amounts[a]
            tau[j, i] = tau[i, j]


@numba.njit(cache=True)
def _build_and_improve(
    dist, choice, tau, eta_pow, scale, alpha, cand, use_cand, q0, xi, tau0, starts, u_rule, u_pick, ls_nn, ls_mode, eps
):  # pragma: no cover - numba
    """Construct one tour per ant, improve it, and return (tours (ants, n), lengths (ants,))."""
    ants = starts.shape[0]
    n = dist.shape[0]
    tours = np.empty((ants, n), dtype=np.int64)
    lengths = np.empty(ants)
    for a in range(ants):
        tour = tours[a]
        _construct(
            tour,
            choice,
            tau,
            eta_pow,
            scale,
            alpha,
            cand,
            use_cand,
            q0,
            xi,
            tau0,
            starts[a],
            u_rule[a],
            u_pick[a],
            dist,
        )
        if ls_mode > 0:
            _local_search(dist, tour, ls_nn, ls_mode, eps)
        total = 0.0
        for k in range(n):
            total += dist[tour[k], tour[(k + 1) % n]]
        lengths[a] = total
    return tours, lengths


@numba.njit(cache=True)
def _construct(
    tour, choice, tau, eta_pow, scale, alpha, cand, use_cand, q0, xi, tau0, start, u_rule, u_pick, dist
):  # pragma: no cover - numba
    """Fill ``tour`` by the (pseudo-)random proportional rule; ACS local update when xi > 0."""
    n = tour.shape[0]
    visited = np.zeros(n, dtype=np.bool_)
    tour[0] = start
    visited[start] = True
    for step in range(1, n):
        i = tour[step - 1]
        j = -1
        if use_cand:
            j = _pick(choice[i], cand[i], visited, q0, u_rule[step], u_pick[step])
        if j < 0:  # no candidate lists, or all candidates visited: then take the best city
            j = _pick_any(choice[i], dist[i], visited, 1.0 if use_cand else q0, u_rule[step], u_pick[step])
        tour[step] = j
        visited[j] = True
        if xi > 0.0:
            _local_update(i, j, choice, tau, eta_pow, scale, alpha, xi, tau0)
    if xi > 0.0:
        _local_update(tour[n - 1], tour[0], choice, tau, eta_pow, scale, alpha, xi, tau0)


@numba.njit(cache=True)
def _local_update(i, j, choice, tau, eta_pow, scale, alpha, xi, tau0):  # pragma: no cover
    """ACS local rule on edge (i, j): tau <- (1 - xi) tau + xi tau0, refreshing its weight."""
    t = (1.0 - xi) * tau[i, j] + xi * tau0
    tau[i, j] = t
    tau[j, i] = t
    w = (t * scale) ** alpha * eta_pow[i, j]
    choice[i, j] = w
    choice[j, i] = w


@numba.njit(cache=True)
def _pick(weights, options, visited, q0, u_rule, u_pick):  # pragma: no cover - numba
    """Choose among the unvisited ``options``; -1 when all are visited."""
    total = 0.0
    best, best_w, count = -1, -1.0, 0
    for j in options:
        if not visited[j]:
            count += 1
            w = weights[j]
            total += w
            if w > best_w:
                best, best_w = j, w
    if count == 0:
        return -1
    if u_rule < q0 or total <= 0.0:
        return best
    target = u_pick * total
    acc = 0.0
    for j in options:
        if not visited[j]:
            acc += weights[j]
            if acc >= target:
                return j
    return best  # only reached through rounding in the running sum


@numba.njit(cache=True)
def _pick_any(weights, dist_row, visited, q0, u_rule, u_pick):  # pragma: no cover - numba
    """Choose among all unvisited cities by the (pseudo-)random proportional rule."""
    n = weights.shape[0]
    total = 0.0
    best, best_w = -1, -1.0
    nearest, nearest_d = -1, np.inf
    for j in range(n):
        if not visited[j]:
            w = weights[j]
            total += w
            if w > best_w:
                best, best_w = j, w
            if dist_row[j] < nearest_d:
                nearest, nearest_d = j, dist_row[j]
    if total <= 0.0:
        return nearest
    if u_rule < q0:
        return best
    target = u_pick * total
    acc = 0.0
    for j in range(n):
        if not visited[j]:
            acc += weights[j]
            if acc >= target:
                return j
    return best


@numba.njit(cache=True)
def _local_search(dist, tour, nn, mode, eps):  # pragma: no cover - numba
    """2-opt (mode 1), or 2-opt and Or-opt alternated until neither improves (mode 2)."""
    _two_opt(dist, tour, nn, eps)
    if mode == 2:
        while _or_opt(dist, tour, nn, eps):
            _two_opt(dist, tour, nn, eps)


@numba.njit(cache=True)
def _reverse(tour, pos, i, j):  # pragma: no cover - numba
    """Reverse the cyclic stretch tour[i..j]; the shorter side is reversed (same cycle)."""
    n = tour.shape[0]
    inner = (j - i) % n + 1
    if 2 * inner > n:  # reversing the complement gives the same cycle, read backwards
        i, j = (j + 1) % n, (i - 1) % n
        inner = n - inner
    for _ in range(inner // 2):
        a, b = tour[i], tour[j]
        tour[i], tour[j] = b, a
        pos[b], pos[a] = i, j
        i = (i + 1) % n
        j = (j - 1) % n


@numba.njit(cache=True)
def _two_opt(dist, tour, nn, eps):  # pragma: no cover - numba
    """First-improvement 2-opt from neighbour lists with don't-look bits (in place).

    Don't-look bits can leave an improving move behind, so the sweeps restart with every bit
    clear until one full sweep finds nothing: the result is a 2-opt local optimum with respect
    to the neighbour lists.
    """
    n = tour.shape[0]
    pos = np.empty(n, dtype=np.int64)
    for k in range(n):
        pos[tour[k]] = k
    dont_look = np.zeros(n, dtype=np.bool_)
    while _two_opt_sweeps(dist, tour, pos, nn, dont_look, eps):
        dont_look[:] = False


@numba.njit(cache=True)
def _two_opt_sweeps(dist, tour, pos, nn, dont_look, eps):  # pragma: no cover - numba
    """Sweep the cities whose don't-look bit is clear until none improves; True if any move."""
    n = tour.shape[0]
    any_move = False
    improved = True
    while improved:
        improved = False
        for c1 in range(n):
            if dont_look[c1]:
                continue
            if _improve_city(dist, tour, pos, nn, dont_look, c1, eps):
                improved = True
                any_move = True
            else:
                dont_look[c1] = True
    return any_move


@numba.njit(cache=True)
def _improve_city(dist, tour, pos, nn, dont_look, c1, eps):  # pragma: no cover - numba
    """Apply the first improving 2-opt move that adds an edge (c1, near neighbour); True if any."""
    n = tour.shape[0]
    for direction in range(2):  # 0: replace c1's successor edge, 1: its predecessor edge
        p1 = pos[c1]
        c1_next = tour[(p1 + 1) % n] if direction == 0 else tour[(p1 - 1) % n]
        radius = dist[c1, c1_next]
        for h in range(nn.shape[1]):
            c2 = nn[c1, h]
            d12 = dist[c1, c2]
            if d12 >= radius:
                break  # an improving move has a new edge shorter than a removed one
            p2 = pos[c2]
            c2_next = tour[(p2 + 1) % n] if direction == 0 else tour[(p2 - 1) % n]
            if c2_next == c1 or c2 == c1_next:
                continue
            gain = radius + dist[c2, c2_next] - d12 - dist[c1_next, c2_next]
            if gain > eps:
                # new edges (c1, c2) and (c1_next, c2_next): reverse the path c1_next .. c2
                if direction == 0:
                    _reverse(tour, pos, (p1 + 1) % n, p2)
                else:
                    _reverse(tour, pos, p2, (p1 - 1) % n)
                dont_look[c1_next] = False
                dont_look[c2] = False
                dont_look[c2_next] = False
                return True
    return False


@numba.njit(cache=True)
def _or_opt(dist, tour, nn, eps):  # pragma: no cover - numba
    """One sweep of Or-opt: move segments of 1-3 cities next to a near neighbour (in place).

    Returns True when the tour changed.
    """
    n = tour.shape[0]
    pos = np.empty(n, dtype=np.int64)
    for k in range(n):
        pos[tour[k]] = k
    width = min(nn.shape[1], _OR_OPT_NEIGHBOURS)
    changed = False
    for seg_len in range(1, 4):
        if seg_len > n - 3:
            break
        i = 0
        while i < n:
            first, last = tour[i], tour[(i + seg_len - 1) % n]
            prev, nxt = tour[(i - 1) % n], tour[(i + seg_len) % n]
            removal = dist[prev, first] + dist[last, nxt] - dist[prev, nxt]
            best_gain, best_a, best_rev = eps, -1, False
            if removal > eps:
                for end in range(2):
                    c = first if end == 0 else last
                    for h in range(width):
                        g = nn[c, h]
                        if (pos[g] - i) % n < seg_len:
                            continue
                        for side in range(2):  # the edge after g, then the edge before g
                            a = g if side == 0 else tour[(pos[g] - 1) % n]
                            b = tour[(pos[a] + 1) % n]
                            if (pos[a] - i) % n < seg_len or (pos[b] - i) % n < seg_len:
                                continue
                            keep = dist[a, first] + dist[last, b] - dist[a, b]
                            flip = dist[a, last] + dist[first, b] - dist[a, b]
                            if removal - keep > best_gain:
                                best_gain, best_a, best_rev = removal - keep, a, False
                            if removal - flip > best_gain:
                                best_gain, best_a, best_rev = removal - flip, a, True
            if best_a >= 0:
                _move_segment(tour, pos, i, seg_len, best_a, best_rev)
                changed = True
            i += 1
    return changed


@numba.njit(cache=True)
def _move_segment(tour, pos, i, seg_len, a, reverse):  # pragma: no cover - numba
    """Move tour[i .. i+seg_len-1] (cyclic) to just after city ``a``, reversed if asked."""
    n = tour.shape[0]
    seg = np.empty(seg_len, dtype=np.int64)
    for k in range(seg_len):
        seg[k] = tour[(i + k) % n]
    if reverse:
        seg = seg[::-1].copy()
    out = np.empty(n, dtype=np.int64)
    m = 0
    k = (i + seg_len) % n
    for _ in range(n - seg_len):
        city = tour[k]
        out[m] = city
        m += 1
        if city == a:
            for s in range(seg_len):
                out[m] = seg[s]
                m += 1
        k = (k + 1) % n
    for k in range(n):
        tour[k] = out[k]
        pos[out[k]] = k
