"""Read symmetric TSPLIB instances given by node coordinates, with TSPLIB's rounded distances.

Only the part of the TSPLIB95 format (Reinelt, 1995) that coordinate instances use is read:
the ``KEY : value`` specification lines, ``NODE_COORD_SECTION`` and ``EOF``. Other sections
(``DISPLAY_DATA_SECTION``, ``FIXED_EDGES_SECTION``, ...) are skipped. Every problem with a file
is raised as a one-line :class:`~pybullet_swarm.errors.ConfigError` naming the file, the
keyword or section, and what was expected.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.resources import scenarios_dir

__all__ = [
    "KNOWN_OPTIMA",
    "EdgeWeightType",
    "TSPInstance",
    "bundled_instances",
    "load_tsplib",
    "parse_tsplib",
    "tsplib_dir",
]

#: Optimal tour lengths (TSPLIB distances) of common symmetric instances, by lower-case name.
KNOWN_OPTIMA: dict[str, float] = {
    "burma14": 3323.0,
    "ulysses16": 6859.0,
    "ulysses22": 7013.0,
    "att48": 10628.0,
    "eil51": 426.0,
    "berlin52": 7542.0,
    "st70": 675.0,
    "eil76": 538.0,
    "pr76": 108159.0,
    "rat99": 1211.0,
    "kroa100": 21282.0,
    "krob100": 22141.0,
    "kroc100": 20749.0,
    "krod100": 21294.0,
    "kroe100": 22068.0,
    "rd100": 7910.0,
    "eil101": 629.0,
    "lin105": 14379.0,
    "ch130": 6110.0,
    "ch150": 6528.0,
}

_GEO_PI = 3.141592  # the value TSPLIB95 prescribes for GEO; published optima depend on it
_GEO_RADIUS = 6378.388  # km, TSPLIB's idealised Earth radius
_KEYWORD = re.compile(r"^([A-Z][A-Z0-9_]*)\s*(?::\s*(.*))?$")


class EdgeWeightType(str, Enum):
    """How TSPLIB turns node coordinates into integer edge weights."""

    EUC_2D = "EUC_2D"  # nint(sqrt(dx^2 + dy^2))
    CEIL_2D = "CEIL_2D"  # ceil(sqrt(dx^2 + dy^2))
    MAN_2D = "MAN_2D"  # nint(|dx| + |dy|)
    MAX_2D = "MAX_2D"  # max(nint(|dx|), nint(|dy|))
    ATT = "ATT"  # pseudo-Euclidean, rounded up
    GEO = "GEO"  # great-circle km, coordinates as DDD.MM latitude/longitude


@dataclass(frozen=True)
class TSPInstance:
    """A symmetric TSP instance given by 2-D node coordinates.

    Attributes:
        name: the file's ``NAME`` (or the file stem when absent).
        comment: the ``COMMENT`` lines joined by spaces ("" when absent).
        dimension: number of nodes n.
        edge_weight_type: distance function of the coordinates.
        coords: (n, 2) node coordinates in file units, node i of the file at row i - 1
            (read-only).
        optimum: optimal tour length in TSPLIB distances, from the file's ``OPTIMUM`` keyword
            or :data:`KNOWN_OPTIMA`; None when unknown.
    """

    name: str
    comment: str
    dimension: int
    edge_weight_type: EdgeWeightType
    coords: NDArray[np.float64] = field(repr=False, compare=False)
    optimum: float | None = None

    def distance_matrix(self) -> NDArray[np.float64]:
        """Return the (n, n) TSPLIB edge weights (integer-valued floats, zero diagonal)."""
        return _distances(self.coords, self.edge_weight_type)


def tsplib_dir() -> Path:
    """Directory of the bundled TSPLIB instances."""
    return scenarios_dir() / "tsplib"


def bundled_instances() -> list[str]:
    """Names of the bundled TSPLIB instances (file stems)."""
    return sorted(p.stem for p in tsplib_dir().glob("*.tsp"))


def load_tsplib(path_or_name: str | os.PathLike[str]) -> TSPInstance:
    """Load a TSPLIB file, or a bundled instance by name (``"eil51"``).

    Args:
        path_or_name: a path to a ``.tsp`` file, or the name of a bundled instance.

    Returns:
        The parsed instance.

    Raises:
        ConfigError: the file is missing, unreadable or not a supported TSPLIB instance.
    """
    path = Path(path_or_name)
    if not path.is_file():
        bundled = tsplib_dir() / (path.name if path.suffix == ".tsp" else f"{path.name}.tsp")
        if path.parent != Path("."):
            raise ConfigError("no such file", source=str(path_or_name))
        if not bundled.is_file():
            names = ", ".join(bundled_instances()) or "none"
            raise ConfigError(
                f"no such file and no bundled instance of that name (bundled: {names})", source=str(path_or_name)
            )
        path = bundled
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror or exc}", source=path.name) from exc
    return parse_tsplib(text, source=path.name)


def parse_tsplib(text: str, *, source: str = "<string>") -> TSPInstance:
    """Parse the text of a TSPLIB coordinate instance.

    Args:
        text: the file's contents.
        source: name used in error messages (usually the file name).

    Returns:
        The parsed instance.

    Raises:
        ConfigError: a required keyword is missing or malformed, the edge weight type is not
            supported, or ``NODE_COORD_SECTION`` does not hold exactly ``DIMENSION`` nodes.
    """
    scan = _scan(text, source)
    if not scan.has_coords:
        _check_spec(scan.spec, source)
        raise ConfigError("missing (the node coordinates)", source=source, field="NODE_COORD_SECTION")
    spec = scan.spec
    n = _dimension(spec, source)
    coords = _read_coords(scan.coord_lines, n, source)
    name = spec.get("NAME") or Path(source).stem
    return TSPInstance(
        name=name,
        comment=" ".join(scan.comments),
        dimension=n,
        edge_weight_type=EdgeWeightType(spec["EDGE_WEIGHT_TYPE"]),
        coords=coords,
        optimum=_optimum(spec, name, source),
    )


@dataclass
class _Scan:
    """What a pass over a TSPLIB file collected."""

    spec: dict[str, str] = field(default_factory=dict)  # specification keywords -> values
    comments: list[str] = field(default_factory=list)
    coord_lines: list[tuple[int, str]] = field(default_factory=list)  # (line number, text)
    has_coords: bool = False


def _scan(text: str, source: str) -> _Scan:
    """Split a file into specification values, comments and NODE_COORD_SECTION lines.

    The specification is checked when NODE_COORD_SECTION starts, so a file with an unusable
    specification fails on its header rather than on its data.
    """
    scan = _Scan()
    section: str | None = None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        match = _KEYWORD.match(line)
        if match is None:
            if section is None:
                raise ConfigError(f"line {lineno}: expected 'KEYWORD : value', got {line[:40]!r}", source=source)
            if section == "NODE_COORD_SECTION":
                scan.coord_lines.append((lineno, line))
            continue
        key, value = match.group(1), (match.group(2) or "").strip()
        if key == "EOF":
            break
        section = key if key.endswith("_SECTION") else None
        if key == "NODE_COORD_SECTION":
            _check_spec(scan.spec, source)
            scan.has_coords = True
        elif key == "COMMENT":
            scan.comments.append(value)
        elif section is None:
            scan.spec[key] = value
    return scan


def _check_spec(spec: dict[str, str], source: str) -> None:
    """Refuse specifications this reader cannot turn into a symmetric coordinate instance."""
    kind = spec.get("TYPE") or "TSP"  # TYPE is optional; coordinate files without it are TSPs
    if kind != "TSP":
        raise ConfigError(f"expected TSP (symmetric), got {kind!r}", source=source, field="TYPE")
    _dimension(spec, source)
    if "EDGE_WEIGHT_TYPE" not in spec:
        raise ConfigError("missing", source=source, field="EDGE_WEIGHT_TYPE")
    ewt = spec["EDGE_WEIGHT_TYPE"]
    if ewt not in EdgeWeightType.__members__:
        supported = ", ".join(EdgeWeightType.__members__)
        raise ConfigError(f"unsupported {ewt!r} (supported: {supported})", source=source, field="EDGE_WEIGHT_TYPE")
    coord_type = spec.get("NODE_COORD_TYPE", "TWOD_COORDS")
    if coord_type != "TWOD_COORDS":
        raise ConfigError(
            f"unsupported {coord_type!r} (supported: TWOD_COORDS)", source=source, field="NODE_COORD_TYPE"
        )


def _dimension(spec: dict[str, str], source: str) -> int:
    """The validated ``DIMENSION``."""
    if "DIMENSION" not in spec:
        raise ConfigError("missing (the number of nodes)", source=source, field="DIMENSION")
    value = spec["DIMENSION"]
    try:
        n = int(value)
    except ValueError:
        raise ConfigError(f"expected a positive integer, got {value!r}", source=source, field="DIMENSION") from None
    if n < 1:
        raise ConfigError(f"expected a positive integer, got {n}", source=source, field="DIMENSION")
    return n


def _read_coords(lines: list[tuple[int, str]], n: int, source: str) -> NDArray[np.float64]:
    """Turn the ``index x y`` lines of NODE_COORD_SECTION into an (n, 2) array."""
    where = "NODE_COORD_SECTION"
    if len(lines) != n:
        raise ConfigError(f"expected {n} nodes, got {len(lines)}", source=source, field=where)
    coords = np.full((n, 2), np.nan)
    for lineno, line in lines:
        parts = line.split()
        if len(parts) != 3:
            raise ConfigError(f"line {lineno}: expected 'index x y', got {line[:40]!r}", source=source, field=where)
        try:
            index = int(parts[0])
        except ValueError:
            raise ConfigError(
                f"line {lineno}: expected an integer node index, got {parts[0]!r}", source=source, field=where
            ) from None
        if not 1 <= index <= n:
            raise ConfigError(f"line {lineno}: node index {index} outside 1..{n}", source=source, field=where)
        if not np.isnan(coords[index - 1, 0]):
            raise ConfigError(f"line {lineno}: node {index} given twice", source=source, field=where)
        for axis, token in enumerate(parts[1:]):
            try:
                value = float(token)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise ConfigError(
                    f"line {lineno}: node {index}: expected a number, got {token!r}", source=source, field=where
                )
            coords[index - 1, axis] = value
    coords.setflags(write=False)
    return coords


def _optimum(spec: dict[str, str], name: str, source: str) -> float | None:
    """Optimal length from the (non-standard) ``OPTIMUM`` keyword, else from the known table."""
    value = spec.get("OPTIMUM")
    if value is None:
        return KNOWN_OPTIMA.get(name.lower())
    try:
        optimum = float(value)
    except ValueError:
        optimum = math.nan
    if not math.isfinite(optimum) or optimum < 0:
        raise ConfigError(f"expected a non-negative number, got {value!r}", source=source, field="OPTIMUM")
    return optimum


def _nint(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """TSPLIB's nint: round half up, ``(int)(x + 0.5)`` for the non-negative values it meets."""
    return np.floor(x + 0.5)


def _distances(coords: NDArray[np.float64], kind: EdgeWeightType) -> NDArray[np.float64]:
    """(n, n) TSPLIB edge weights of ``coords`` (n, 2) for edge weight type ``kind``."""
    if kind is EdgeWeightType.GEO:
        return _geo_distances(coords)
    delta = np.abs(coords[:, None, :] - coords[None, :, :])  # (n, n, 2)
    dx, dy = delta[..., 0], delta[..., 1]
    if kind is EdgeWeightType.EUC_2D:
        out = _nint(np.hypot(dx, dy))
    elif kind is EdgeWeightType.CEIL_2D:
        out = np.ceil(np.hypot(dx, dy))
    elif kind is EdgeWeightType.MAN_2D:
        out = _nint(dx + dy)
    elif kind is EdgeWeightType.MAX_2D:
        out = np.maximum(_nint(dx), _nint(dy))
    else:  # ATT: nint of the pseudo-Euclidean distance, bumped up when nint rounded down
        r = np.sqrt((dx * dx + dy * dy) / 10.0)
        t = _nint(r)
        out = np.where(t < r, t + 1.0, t)
    np.fill_diagonal(out, 0.0)
    return out


def _geo_distances(coords: NDArray[np.float64]) -> NDArray[np.float64]:
    """Great-circle distances in km of (n, 2) DDD.MM latitude/longitude pairs, as TSPLIB defines."""
    degrees = np.trunc(coords)
    radians = _GEO_PI * (degrees + 5.0 * (coords - degrees) / 3.0) / 180.0
    lat, lon = radians[:, 0], radians[:, 1]
    q1 = np.cos(lon[:, None] - lon[None, :])
    q2 = np.cos(lat[:, None] - lat[None, :])
    q3 = np.cos(lat[:, None] + lat[None, :])
    arg = np.clip(0.5 * ((1.0 + q1) * q2 - (1.0 - q1) * q3), -1.0, 1.0)
    out = np.floor(_GEO_RADIUS * np.arccos(arg) + 1.0)
    np.fill_diagonal(out, 0.0)
    return out
