"""Random construction layouts for benchmark suites: a structure, a depot, a swarm and an arena per seed.

``random_layout(seed)`` draws, from the stream ``layout`` of the seed (``pybullet_swarm.rng``),
an arena (2 to 6 m by 1 to 3 m, half-metre steps; ``max_arena`` widens the range), a swarm of 1 to
20 agents standing in columns at the near end (x = 0), a structure at the far end (a named shape of
``tasks.layouts``, or two or three of them side by side) and a depot between them: a grid of as
many boxes as the structure has slots, 20 cm apart, or (``depots=2``) two grids, one along each
long side of the arena, sharing the boxes. Any of these can be fixed instead of drawn (the swarm
size also as a range). The scenario is the bundled
``construction`` with these parts replaced, written in the compact forms (the structure and the
depot as shapes), and validated as any scenario is, with each construction planner: a draw that a
check refuses (a structure too wide for the arena, slots a stigmergy agent would not see) is drawn again from the next stream (``layout/1``, ``layout/2`` ...), so
a seed always gives the same scenario.
"""

from __future__ import annotations

import copy
import math
from typing import Any, Sequence

import numpy as np

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import apply_choices, build_scenario, resolve_scenario_path
from pybullet_swarm.rng import named_rng
from pybullet_swarm.tasks.layouts import expand_boxes
from pybullet_swarm.validation import read_yaml

#: structure shapes drawn (``several``: two or three of the others side by side)
SHAPES = ("wall", "stepped_wall", "slab", "tower", "pyramid", "ring", "several")
BOX = 0.1  # m, box edge (the thesis's)
START_PITCH = 0.2  # m, between the agents' start positions
DEPOT_PITCH = 0.2  # m, between depot boxes (10 cm gaps, as the thesis's depot)
EDGE = 0.2  # m, least distance from a structure's boxes to the arena's edge
GAP = 0.5  # m, between the depot and the structure
APART = 0.4  # m, between the structures of a ``several``
MAX_ATTEMPTS = 50
#: the construction planners a layout must load with
PLANNERS = ("shortest_path", "stigmergy", "layered_stigmergy")
MAX_SLOTS = 60
MAX_AGENTS = 20
MAX_ARENA = (6.0, 3.0)  # m, largest arena drawn by default
ARENA_BOUND = (20.0, 10.0)  # m, largest ``max_arena`` accepted


def _check_draw_args(
    *, agents: int | tuple[int, int] | None, shape: str | None, depots: int, max_arena: Sequence[float]
) -> None:
    """Refuse generator arguments no draw can satisfy (one line naming the argument)."""
    if shape is not None and shape not in SHAPES:
        raise ConfigError(f"must be one of {', '.join(SHAPES)}, got {shape!r}", source="--shape")
    if isinstance(depots, bool) or depots not in (1, 2):
        raise ConfigError(f"must be 1 or 2, got {depots!r}", source="--depots")
    span = (agents, agents) if isinstance(agents, int) else agents
    if span is not None and (
        len(span) != 2
        or any(isinstance(v, bool) or not isinstance(v, int) for v in span)
        or not 1 <= span[0] <= span[1] <= MAX_AGENTS
    ):
        raise ConfigError(
            f"must be an integer or a range [lo, hi] within 1..{MAX_AGENTS}, got {agents!r}", source="--agents"
        )
    if len(max_arena) != 2 or not all(lo <= float(v) <= hi for v, lo, hi in zip(max_arena, (2.0, 1.0), ARENA_BOUND)):
        raise ConfigError(
            f"must be [Lx, Ly] m within 2..{ARENA_BOUND[0]:g} x 1..{ARENA_BOUND[1]:g}, got {list(max_arena)!r}",
            source="--max-arena",
        )


def _shape(rng: np.random.Generator, name: str) -> dict[str, Any]:
    """A shape of ``name`` with drawn parameters, at the origin."""
    pitch = float(rng.choice([BOX, 2 * BOX]))
    axis = str(rng.choice(["x", "y"]))
    if name == "wall":
        return {
            "shape": "wall",
            "length": int(rng.integers(2, 9)),
            "height": int(rng.integers(1, 4)),
            "axis": axis,
            "pitch": pitch,
        }
    if name == "stepped_wall":
        length = int(rng.integers(3, 7))
        return {
            "shape": "stepped_wall",
            "length": length,
            "height": int(rng.integers(2, length + 1)),
            "axis": axis,
            "pitch": pitch,
        }
    if name == "slab":
        return {
            "shape": "slab",
            "size": [int(rng.integers(2, 5)), int(rng.integers(2, 5))],
            "height": int(rng.integers(1, 3)),
            "pitch": pitch,
        }
    if name == "tower":
        return {"shape": "tower", "height": int(rng.integers(2, 6))}
    if name == "pyramid":
        return {"shape": "pyramid", "base": int(rng.integers(2, 5)), "pitch": pitch}
    if name == "ring":
        return {
            "shape": "ring",
            "size": [int(rng.integers(3, 5)), int(rng.integers(3, 5))],
            "height": int(rng.integers(1, 3)),
            "pitch": pitch,
        }
    raise ValueError(name)


def _extent(spec: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corners (2,) m of the boxes of a shape placed at the origin."""
    pts = np.asarray(expand_boxes({**spec, "origin": [0.0, 0.0]}, BOX, "structure"))
    return pts[:, :2].min(axis=0) - 0.5 * BOX, pts[:, :2].max(axis=0) + 0.5 * BOX


def _place(
    rng: np.random.Generator, specs: list[dict[str, Any]], lo: np.ndarray, hi: np.ndarray
) -> list[dict[str, Any]] | None:
    """The shapes with origins drawn inside the box [lo, hi] (2,) m, ``APART`` from each other, or None."""
    placed: list[dict[str, Any]] = []
    boxes: list[tuple[np.ndarray, np.ndarray]] = []
    for spec in specs:
        a, b = _extent(spec)
        room_lo, room_hi = lo - a, hi - b  # where the origin may go
        if np.any(room_hi < room_lo):
            return None
        for _ in range(20):
            o = rng.uniform(room_lo, room_hi)
            o = np.round(o / 0.05) * 0.05  # on a 5 cm grid: readable files
            o = np.clip(o, np.ceil(room_lo / 0.05 - 1e-9) * 0.05, np.floor(room_hi / 0.05 + 1e-9) * 0.05)
            q_lo, q_hi = o + a, o + b
            if all(np.any((q_lo > h + APART) | (q_hi < lo_ - APART)) for lo_, h in boxes):
                break
        else:
            return None
        boxes.append((q_lo, q_hi))
        placed.append({**spec, "origin": [round(float(o[0]), 3), round(float(o[1]), 3)]})
    return placed


def _draw(
    rng: np.random.Generator,
    *,
    agents: int | tuple[int, int] | None,
    arena: Sequence[float] | None,
    shape: str | None,
    depots: int = 1,
    max_arena: Sequence[float] = MAX_ARENA,
) -> dict[str, Any] | None:
    """One draw of the parts of a layout (plain data), or None when they do not fit together."""
    lx, ly = (
        (float(v) for v in arena)
        if arena is not None
        else (
            0.5 * float(rng.integers(4, int(round(2 * max_arena[0])) + 1)),
            0.5 * float(rng.integers(2, int(round(2 * max_arena[1])) + 1)),
        )
    )
    lo_n, hi_n = (agents, agents) if isinstance(agents, int) else agents if agents is not None else (1, MAX_AGENTS)
    n = lo_n if lo_n == hi_n else int(rng.integers(lo_n, hi_n + 1))
    name = shape if shape is not None else str(rng.choice(SHAPES))
    if name == "several":
        parts = [_shape(rng, str(rng.choice(SHAPES[:-1]))) for _ in range(int(rng.integers(2, 4)))]
    else:
        parts = [_shape(rng, name)]
    slots = sum(len(expand_boxes({**p, "origin": [0.0, 0.0]}, BOX, "structure")) for p in parts)
    if slots > MAX_SLOTS:
        return None
    _, _, depot_end = swarm_and_depot(n, (lx, ly), slots, depots=depots)
    lo = np.array([depot_end + GAP, EDGE])
    hi = np.array([lx - EDGE, ly - EDGE])
    if np.any(hi <= lo):
        return None
    placed = _place(rng, parts, lo, hi)
    if placed is None:
        return None
    return {"arena": [lx, ly], "agents": n, "structure": placed[0] if len(placed) == 1 else placed, "shape": name}


def _depot_grid(x: float, y_first: float, rows: int, count: int, *, downward: bool = False) -> dict[str, Any]:
    """A depot grid of ``count`` boxes in ``rows`` rows from (x, ``y_first``) m, up (or down) along y."""
    cols = math.ceil(count / rows)
    y0 = y_first - DEPOT_PITCH * (rows - 1) if downward else y_first
    return {
        "shape": "grid",
        "origin": [round(x, 3), round(y0, 3)],
        "size": [cols, rows],
        "pitch": DEPOT_PITCH,
        "count": count,
    }


def swarm_and_depot(
    n: int, arena: Sequence[float], slots: int, *, depots: int = 1
) -> tuple[list[list[float]], dict[str, Any] | list[dict[str, Any]], float]:
    """Start positions of ``n`` agents in columns at the near end (x = 0) of an ``arena`` (Lx, Ly) m, 20 cm
    apart, and beyond them a depot grid of ``slots`` boxes 20 cm apart (``depots=2``: two grids, one along
    each long side, the first holding the odd box); and x m of the depots' far side."""
    if depots not in (1, 2):
        raise ConfigError(f"must be 1 or 2, got {depots!r}", source="depots")
    ly = float(arena[1])
    rows = max(1, int(math.floor((ly - 0.2) / START_PITCH + 1e-9)) + 1)
    cols = math.ceil(n / rows)
    y0 = 0.5 * ly - 0.5 * START_PITCH * (min(n, rows) - 1)
    starts = [
        [round(0.12 + START_PITCH * (k // rows), 3), round(y0 + START_PITCH * (k % rows), 3), 0.011] for k in range(n)
    ]
    depot_x = 0.12 + START_PITCH * (cols - 1) + 0.35
    if depots == 1 or slots < 2:
        depot_rows = min(max(1, int(math.floor((ly - 0.4) / DEPOT_PITCH + 1e-9)) + 1), slots)
        depot = _depot_grid(depot_x, 0.5 * ly - 0.5 * DEPOT_PITCH * (depot_rows - 1), depot_rows, slots)
        return starts, depot, depot_x + DEPOT_PITCH * (depot["size"][0] - 1) + 0.5 * BOX
    counts = (slots - slots // 2, slots // 2)
    # each grid fills at most a third of the arena's width from its side: the middle stays a free lane
    side_rows = max(1, int(math.floor((ly / 3.0 - 0.2) / DEPOT_PITCH + 1e-9)) + 1)
    grids = [
        _depot_grid(depot_x, 0.2, min(side_rows, counts[0]), counts[0]),
        _depot_grid(depot_x, ly - 0.2, min(side_rows, counts[1]), counts[1], downward=True),
    ]
    far = max(depot_x + DEPOT_PITCH * (g["size"][0] - 1) for g in grids)
    return starts, grids, far + 0.5 * BOX


def compose_layout(
    structure: Any,
    *,
    agents: int,
    arena: Sequence[float],
    seed: int = 0,
    name: str = "layout",
    description: str = "",
    collisions: str | None = None,
    base: str = "construction",
    depots: int = 1,
) -> dict[str, Any]:
    """Scenario data (as a file holds it) of ``structure`` (a structure of ``tasks.layouts``, placed) built
    by ``agents`` agents starting at the near end of an ``arena`` (Lx, Ly) m, with a depot grid of as many
    boxes as it has slots between them (``depots=2``: two grids; ``swarm_and_depot``), and a time limit
    generous for the distances. Not validated: ``build_scenario`` judges it."""
    lx, ly = float(arena[0]), float(arena[1])
    slots = np.asarray(expand_boxes(structure, BOX, "structure"))
    starts, depot, _ = swarm_and_depot(agents, (lx, ly), len(slots), depots=depots)
    # each box is carried from the depot to the structure and the carrier comes back: a generous time limit
    depot_x = (depot if isinstance(depot, dict) else depot[0])["origin"][0]
    far = float(np.mean(slots[:, 0])) - depot_x
    per_box = 2.0 * far / 0.15 + 30.0  # s, at the thesis's 0.15 m/s
    limit = 300.0 + 2.0 * len(slots) * per_box / min(agents, len(slots))
    data = copy.deepcopy(read_yaml(resolve_scenario_path(base)))
    data["name"] = name
    data["description"] = description
    data["seed"] = int(seed)
    data["arena"] = {**data.get("arena", {}), "size": [lx, ly]}
    data["agents"] = {**data.get("agents", {}), "count": int(agents), "start": starts}
    if collisions is not None:
        data["collisions"] = collisions
    data["task"] = {
        **data["task"],
        "boxes": depot,
        "structure": structure,
        "time_limit_s": float(min(1e5, math.ceil(limit / 50.0) * 50.0)),
    }
    return data


def random_layout(
    seed: int,
    *,
    agents: int | tuple[int, int] | None = None,
    arena: Sequence[float] | None = None,
    shape: str | None = None,
    depots: int = 1,
    max_arena: Sequence[float] = MAX_ARENA,
    collisions: str | None = None,
    base: str = "construction",
    planners: Sequence[str] = PLANNERS,
) -> dict[str, Any]:
    """A valid construction scenario (plain data, as a file holds it) drawn from ``seed``.

    Args:
        seed: the layout's seed (also the scenario's seed).
        agents: swarm size, or the range (lo, hi) it is drawn in (default: drawn in 1..20).
        arena: (Lx, Ly) m (default: drawn in 2..Lmax x 1..Wmax m, half-metre steps).
        shape: one of ``SHAPES`` (default: drawn).
        depots: 1 (one grid between the swarm and the structure) or 2 (one along each long side).
        max_arena: (Lmax, Wmax) m, largest arena drawn (default 6 x 3 m; at most 20 x 10 m).
        collisions: ``ghost`` or ``physical`` (default: the base scenario's).
        base: the scenario the layout replaces the arena, swarm and task layout of.
        planners: the layout must load with each of these planners (their layout checks pass).

    Raises:
        ConfigError: a fixed part that no draw fits (e.g. 20 agents in a 2 x 1 m arena).
    """
    _check_draw_args(agents=agents, shape=shape, depots=depots, max_arena=max_arena)
    last: ConfigError | None = None
    for attempt in range(MAX_ATTEMPTS):
        rng = named_rng(seed, "layout" if attempt == 0 else f"layout/{attempt}")
        part = _draw(rng, agents=agents, arena=arena, shape=shape, depots=depots, max_arena=max_arena)
        if part is None:
            continue
        lx, ly = part["arena"]
        data = compose_layout(
            part["structure"], agents=part["agents"], arena=part["arena"], seed=seed, name=f"layout-{seed}",
            collisions=collisions, base=base, depots=depots,
        )  # fmt: skip
        slots = len(expand_boxes(data["task"]["structure"], BOX, "structure"))
        data["description"] = (
            f"random construction layout (seed {seed}): {part['shape']} of {slots} boxes, "
            f"{part['agents']} agents, arena {lx:g} x {ly:g} m" + (f", {depots} depots" if depots > 1 else "")
        )
        try:
            for name in planners:
                choice = apply_choices(copy.deepcopy(data), planner=name, source=f"layout seed {seed}")
                build_scenario(choice, source=f"layout seed {seed}")
        except ConfigError as exc:
            last = exc
            continue
        return data
    raise ConfigError(
        f"no layout fits after {MAX_ATTEMPTS} draws" + (f" (last refused: {last})" if last else ""),
        source=f"layout seed {seed}",
    )
