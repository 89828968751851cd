"""Structures and depots as users write them: voxel layers and named shapes, expanded to box centres.

The construction task's ``structure`` (goal slots) and ``boxes`` (the depot) are lists of box
centres ``[x, y, z]`` m. Besides such a list, each takes:

* **voxels**, cells at a pitch, layer by layer from the ground up::

      structure:
        voxels:
          origin: [2.5, 0.3]      # m, centre of the first cell of the bottom layer ([x, y, z]: z its centre)
          pitch: 0.1              # m, between neighbouring cells (default: box_size)
          rows: x                 # the characters of a row run along x (y: along y); rows follow each other
          layers:                 # bottom layer first; a layer is a list of rows, or one row
            - ["XXXX", "X..X"]
            - ["XXXX"]
            - "XX"

  ``X`` (or ``#``) is a box, ``.`` (or a space, ``-``, ``_``) an empty cell. Layers are
  ``box_size`` apart: each stands on the one under it.
* **a named shape** with parameters (counts are boxes, ``origin`` is the centre of the first cell of
  the bottom layer, ``pitch`` defaults to ``box_size``, ``axis`` is the direction a wall runs along):

  ====================  ====================================================================
  shape                 parameters
  ====================  ====================================================================
  ``wall``              ``length``, ``height`` (1), ``axis`` (x)
  ``stepped_wall``      ``length``, ``height`` (= length), ``step`` (1), ``axis``: layer k
                        holds ``length - k * step`` boxes from the origin end (the thesis's
                        4-3-2 wall: length 4, height 3)
  ``slab``              ``size: [nx, ny]``, ``height`` (1)
  ``grid``              a slab whose first ``count`` cells hold a box (a depot of any count)
  ``tower``             ``height``
  ``pyramid``           ``base``: a base x base square of columns, each one box lower than
                        the column inside it (a stepped pyramid of columns)
  ``ring``              ``size: [nx, ny]``, ``height`` (1): the cells on the rim of the rectangle
  ====================  ====================================================================

* **several structures**: a list of voxel mappings and shapes.

Cells are listed layer by layer from the ground up (within a layer, row by row). The expansion
is bounded (``MAX_BOXES``) before any array is made; a bad specification raises
``LayoutError`` naming the field inside the task section (``structure[1].length``).
"""

from __future__ import annotations

import itertools
from typing import Annotated, Any, Literal

import numpy as np
import pydantic
from pydantic import Field

MAX_BOXES = 500
"""Most boxes (or slots) a task holds."""
MAX_COORD = 1e5
"""m, largest coordinate accepted."""

EMPTY_CELLS = frozenset(".- _")
BOX_CELLS = frozenset("X#")

Coord = Annotated[float, Field(ge=-MAX_COORD, le=MAX_COORD)]
Origin = Annotated[list[Coord], Field(min_length=2, max_length=3)]
Count = Annotated[int, Field(ge=1, le=MAX_BOXES)]
Pitch = Annotated[float, Field(gt=0.0, le=100.0)]


class LayoutError(ValueError):
    """A structure or depot specification that cannot be expanded.

    Attributes:
        field: where, inside the task section (``structure.voxels.layers[2]``); the scenario's
            one-line error reports it as ``task.<field>``.
    """

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field


class _Spec(pydantic.BaseModel):
    model_config = pydantic.ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


class _Placed(_Spec):
    origin: Origin  # m, centre of the first cell of the bottom layer ([x, y] stands it on the ground)
    pitch: Pitch | None = None  # m, between neighbouring cells' centres (default: box_size)


class Voxels(_Placed):
    """Cells at a pitch, layer by layer (bottom first), each layer a list of rows of ``X`` and ``.``."""

    rows: Literal["x", "y"] = "x"  # the axis a row's characters run along; successive rows step along the other
    layers: Annotated[
        list[
            Annotated[list[Annotated[str, Field(max_length=MAX_BOXES)]], Field(min_length=1, max_length=MAX_BOXES)]
            | str
        ],
        Field(min_length=1, max_length=MAX_BOXES),
    ]


class Wall(_Placed):
    """``height`` layers of ``length`` boxes along ``axis``."""

    shape: Literal["wall"]
    length: Count
    height: Count = 1
    axis: Literal["x", "y"] = "x"


class SteppedWall(_Placed):
    """A wall whose layer k holds ``length - k * step`` boxes, from the origin end."""

    shape: Literal["stepped_wall"]
    length: Count
    height: Count | None = None  # layers (default: as many as the steps allow)
    step: Count = 1
    axis: Literal["x", "y"] = "x"


class Slab(_Placed):
    """``height`` layers of ``size[0]`` x ``size[1]`` boxes."""

    shape: Literal["slab"]
    size: Annotated[list[Count], Field(min_length=2, max_length=2)]
    height: Count = 1


class Grid(_Placed):
    """The first ``count`` cells (row by row, layer by layer) of ``height`` layers of ``size`` cells."""

    shape: Literal["grid"]
    size: Annotated[list[Count], Field(min_length=2, max_length=2)]
    height: Count = 1
    count: Count | None = None  # default: every cell


class Tower(_Placed):
    """One column of ``height`` boxes."""

    shape: Literal["tower"]
    height: Count


class Pyramid(_Placed):
    """A ``base`` x ``base`` square of columns; a column is one box taller than those around it outside."""

    shape: Literal["pyramid"]
    base: Count


class Ring(_Placed):
    """The cells on the rim of a ``size[0]`` x ``size[1]`` rectangle, ``height`` layers."""

    shape: Literal["ring"]
    size: Annotated[list[Count], Field(min_length=2, max_length=2)]
    height: Count = 1


SHAPES: dict[str, type[_Placed]] = {
    "wall": Wall,
    "stepped_wall": SteppedWall,
    "slab": Slab,
    "grid": Grid,
    "tower": Tower,
    "pyramid": Pyramid,
    "ring": Ring,
}


class _VoxelSpec(_Spec):
    voxels: Voxels


# ------------------------------------------------------------------ cells of each form
def _cells_voxels(v: Voxels, field: str) -> list[tuple[int, int, int]]:
    """(column, row, layer) of every box cell (characters along a row are columns)."""
    total = sum(
        sum(ch in BOX_CELLS for row in ([layer] if isinstance(layer, str) else layer) for ch in row)
        for layer in v.layers
    )
    _bound(total, field)
    out: list[tuple[int, int, int]] = []
    for k, layer in enumerate(v.layers):
        rows = [layer] if isinstance(layer, str) else layer
        for r, row in enumerate(rows):
            where = f"{field}.layers[{k}]" if isinstance(layer, str) else f"{field}.layers[{k}][{r}]"
            for c, ch in enumerate(row):
                if ch in BOX_CELLS:
                    out.append((c, r, k))
                elif ch not in EMPTY_CELLS:
                    raise LayoutError(where, f"cells are X (a box) or . (empty), got {ch!r} in {row[:40]!r}")
    if not out:
        raise LayoutError(f"{field}.layers", "holds no box (no X)")
    return out


def _bound(total: int, field: str) -> None:
    if total > MAX_BOXES:
        raise LayoutError(field, f"would hold {total} boxes, more than {MAX_BOXES}")


def _cells_shape(s: _Placed, field: str) -> list[tuple[int, int, int]]:
    """(i, j, layer) cells of a named shape (i along x, j along y; walls turned by their axis)."""
    if isinstance(s, (Wall, SteppedWall)):
        step = s.step if isinstance(s, SteppedWall) else 0
        if isinstance(s, SteppedWall):
            most = (s.length - 1) // s.step + 1
            height = most if s.height is None else s.height
            if height > most:
                raise LayoutError(
                    f"{field}.height",
                    f"a stepped wall of length {s.length} and step {s.step} has at most {most} layers, got {height}",
                )
        else:
            height = s.height
        _bound(sum(s.length - k * step for k in range(height)), field)
        cells = [(i, 0, k) for k in range(height) for i in range(s.length - k * step)]
        return [(0, i, k) for i, _, k in cells] if s.axis == "y" else cells
    if isinstance(s, (Slab, Grid)):
        nx, ny = s.size
        cells_total = nx * ny * s.height
        count = s.count if isinstance(s, Grid) and s.count is not None else None
        if count is not None and count > cells_total:
            raise LayoutError(
                f"{field}.count", f"a grid of {nx} x {ny} x {s.height} cells holds at most {cells_total}, got {count}"
            )
        _bound(cells_total if count is None else count, field)
        every = ((i, j, k) for k in range(s.height) for j in range(ny) for i in range(nx))
        return list(itertools.islice(every, cells_total if count is None else count))
    if isinstance(s, Tower):
        return [(0, 0, k) for k in range(s.height)]
    if isinstance(s, Pyramid):
        n = s.base
        _bound(sum((n - 2 * k) ** 2 for k in range((n + 1) // 2)), field)
        return [(i, j, k) for k in range((n + 1) // 2) for j in range(k, n - k) for i in range(k, n - k)]
    if isinstance(s, Ring):
        nx, ny = s.size
        rim = [(i, j) for j in range(ny) for i in range(nx) if i in (0, nx - 1) or j in (0, ny - 1)]
        _bound(len(rim) * s.height, field)
        return [(i, j, k) for k in range(s.height) for i, j in rim]
    raise AssertionError(type(s).__name__)


def _centres(cells: list[tuple[int, int, int]], spec: _Placed, box_size: float, *, swap: bool) -> list[list[float]]:
    pitch = box_size if spec.pitch is None else spec.pitch
    ox, oy = spec.origin[0], spec.origin[1]
    oz = spec.origin[2] if len(spec.origin) == 3 else 0.5 * box_size
    ijk = np.array(cells, dtype=float).reshape(-1, 3)
    if swap:
        ijk = ijk[:, [1, 0, 2]]
    xyz = np.column_stack([ox + pitch * ijk[:, 0], oy + pitch * ijk[:, 1], oz + box_size * ijk[:, 2]])
    return [[float(round(c, 12)) for c in p] for p in xyz]


# ------------------------------------------------------------------ expansion
def _validated(model: type[_Spec], data: dict[str, Any], field: str) -> Any:
    from pybullet_swarm.validation import from_pydantic

    try:
        return model.model_validate(data)
    except pydantic.ValidationError as exc:
        err = from_pydantic(exc, source=None, prefix=field, data=data)
        raise LayoutError(err.field or field, err.detail) from None


def _expand_one(item: dict[str, Any], box_size: float, field: str) -> list[list[float]]:
    if "voxels" in item:
        v = _validated(_VoxelSpec, item, field).voxels
        return _centres(_cells_voxels(v, f"{field}.voxels"), v, box_size, swap=v.rows == "y")
    shape = item.get("shape")
    if shape is None:
        raise LayoutError(
            field,
            f"a mapping here needs voxels: or shape: ({' | '.join(SHAPES)}), got keys {', '.join(map(str, item))}",
        )
    if not isinstance(shape, str) or shape not in SHAPES:
        raise LayoutError(f"{field}.shape", f"must be one of {' | '.join(SHAPES)}, got {shape!r}"[:200])
    spec = _validated(SHAPES[shape], item, field)
    return _centres(_cells_shape(spec, field), spec, box_size, swap=False)


def expand_boxes(value: Any, box_size: float, field: str) -> Any:
    """Box centres ``[[x, y, z], ...]`` m of a structure or depot written as voxels, a named shape, or a
    list of those; a list of centres (or anything else, for the model to refuse) is returned as is.

    Raises:
        LayoutError: a specification that cannot be expanded, naming the field (``field`` is the
            task section's field: ``structure`` or ``boxes``).
    """
    if isinstance(value, dict):
        return _expand_one(value, box_size, field)
    if not isinstance(value, list) or not value or not any(isinstance(item, dict) for item in value):
        return value
    out: list[list[float]] = []
    for i, item in enumerate(value):
        if not isinstance(item, dict):
            raise LayoutError(
                f"{field}[{i}]",
                "a list of structures holds voxel mappings and shapes only (write box centres as their own "
                f"list, or as a voxels: mapping), got {str(item)[:40]}",
            )
        out.extend(_expand_one(item, box_size, f"{field}[{i}]"))
        _bound(len(out), field)
    return out
