"""Tests of pybullet_swarm/planning/tsplib.py: parsing, TSPLIB distances, one-line errors."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.planning.aco import solve_tsp, tour_length
from pybullet_swarm.planning.tsplib import (
    EdgeWeightType,
    bundled_instances,
    load_tsplib,
    parse_tsplib,
    tsplib_dir,
)

# TSPLIB's eil51.opt.tour (1-based), length 426 under EUC_2D rounding.
EIL51_OPT_TOUR = [
    1,
    22,
    8,
    26,
    31,
    28,
    3,
    36,
    35,
    20,
    2,
    29,
    21,
    16,
    50,
    34,
    30,
    9,
    49,
    10,
    39,
    33,
    45,
    15,
    44,
    42,
    40,
    19,
    41,
    13,
    25,
    14,
    24,
    43,
    7,
    23,
    48,
    6,
    27,
    51,
    46,
    12,
    47,
    18,
    4,
    17,
    37,
    5,
    38,
    11,
    32,
]

BURMA14 = """NAME: burma14
TYPE: TSP
COMMENT: 14-Staedte in Burma (Zaw Win)
DIMENSION: 14
EDGE_WEIGHT_TYPE: GEO
NODE_COORD_SECTION
   1  16.47       96.10
   2  16.47       94.44
   3  20.09       92.54
   4  22.39       93.37
   5  25.23       97.24
   6  22.00       96.05
   7  20.47       97.02
   8  17.20       96.29
   9  16.30       97.38
  10  14.05       98.12
  11  16.53       97.38
  12  21.52       95.59
  13  19.41       97.13
  14  20.09       94.55
EOF
"""


def _tsp(edge_weight_type: str, *coords: tuple[float, float], extra: str = "") -> str:
    """Text of a small TSPLIB file with the given nodes."""
    nodes = "\n".join(f"{i} {x} {y}" for i, (x, y) in enumerate(coords, start=1))
    return (
        f"NAME : tiny\nTYPE : TSP\n{extra}DIMENSION : {len(coords)}\n"
        f"EDGE_WEIGHT_TYPE : {edge_weight_type}\nNODE_COORD_SECTION\n{nodes}\nEOF\n"
    )


def _eil51_text() -> str:
    return (tsplib_dir() / "eil51.tsp").read_text()


def test_bundled_eil51_loads_with_51_nodes() -> None:
    inst = load_tsplib("eil51")
    assert "eil51" in bundled_instances()
    assert (inst.name, inst.dimension, inst.optimum) == ("eil51", 51, 426.0)
    assert inst.edge_weight_type is EdgeWeightType.EUC_2D
    assert inst.comment == "51-city problem (Christofides/Eilon)"
    assert inst.coords.shape == (51, 2)
    np.testing.assert_array_equal(inst.coords[0], [37, 52])
    np.testing.assert_array_equal(inst.coords[-1], [30, 40])
    assert load_tsplib("eil51.tsp").dimension == 51


def test_euc_2d_rounds_to_nearest_integer() -> None:
    d = load_tsplib("eil51").distance_matrix()
    # nodes 1 (37, 52) and 2 (49, 49): sqrt(12^2 + 3^2) = 12.369 -> 12
    assert d[0, 1] == d[1, 0] == 12.0
    np.testing.assert_array_equal(np.diag(d), 0.0)
    # halves round up (TSPLIB's nint), not to even: 2.5 -> 3; and 3-4-5 stays 5
    tiny = parse_tsplib(_tsp("EUC_2D", (0, 0), (0, 2.5), (3, 4))).distance_matrix()
    assert tiny[0, 1] == 3.0 and tiny[0, 2] == 5.0


def test_eil51_optimal_tour_has_length_426() -> None:
    d = load_tsplib("eil51").distance_matrix()
    assert tour_length(d, np.array(EIL51_OPT_TOUR) - 1) == 426.0


def test_ceil_2d_man_max_and_att_distances() -> None:
    pts = ((0, 0), (1, 1), (10, 0), (3, 4))
    assert parse_tsplib(_tsp("CEIL_2D", *pts)).distance_matrix()[0, 1] == 2.0  # ceil(1.414)
    assert parse_tsplib(_tsp("MAN_2D", *pts)).distance_matrix()[0, 3] == 7.0
    assert parse_tsplib(_tsp("MAX_2D", *pts)).distance_matrix()[0, 3] == 4.0
    att = parse_tsplib(_tsp("ATT", *pts)).distance_matrix()
    assert att[0, 3] == 2.0  # sqrt(25 / 10) = 1.58, nint 2 >= 1.58
    assert att[0, 2] == 4.0  # sqrt(100 / 10) = 3.16, nint 3 < 3.16 -> 4


def test_geo_matches_tsplib_burma14() -> None:
    inst = parse_tsplib(BURMA14, source="burma14.tsp")
    d = inst.distance_matrix()
    # first row of burma14's published (EXPLICIT) distance matrix
    expected = [0, 153, 510, 706, 966, 581, 455, 70, 160, 372, 157, 567, 342, 398]
    np.testing.assert_array_equal(d[0], expected)
    np.testing.assert_array_equal(d, d.T)
    assert inst.optimum == 3323.0
    assert solve_tsp(d, seed=0).length == 3323.0


def test_optimum_from_keyword_else_table_else_none() -> None:
    pts = ((0, 0), (0, 1), (1, 1), (1, 0))
    assert parse_tsplib(_tsp("EUC_2D", *pts)).optimum is None
    assert parse_tsplib(_tsp("EUC_2D", *pts, extra="OPTIMUM : 4\n")).optimum == 4.0


def test_instance_is_frozen_and_coords_read_only() -> None:
    inst = load_tsplib("eil51")
    with pytest.raises(dataclasses.FrozenInstanceError):
        inst.dimension = 3  # type: ignore[misc]
    with pytest.raises(ValueError):
        inst.coords[0, 0] = 1.0


def test_tolerates_crlf_missing_eof_and_other_sections() -> None:
    text = _eil51_text().replace("EOF\n", "DISPLAY_DATA_SECTION\n1 0 0\n")
    assert parse_tsplib(text.replace("\n", "\r\n")).dimension == 51


def _bad(tmp_path: Path, text: str, name: str = "eil51.tsp") -> ConfigError:
    """Load ``text`` from a file called ``name``; return the ConfigError, checked one-line."""
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_tsplib(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{name}: ")
    return info.value


def test_wrong_node_count(tmp_path: Path) -> None:
    err = _bad(tmp_path, _eil51_text().replace("51 30 40\n", ""))
    assert str(err) == "eil51.tsp: NODE_COORD_SECTION: expected 51 nodes, got 50"
    assert (err.source, err.field) == ("eil51.tsp", "NODE_COORD_SECTION")


def test_missing_dimension(tmp_path: Path) -> None:
    err = _bad(tmp_path, _eil51_text().replace("DIMENSION : 51\n", ""))
    assert err.field == "DIMENSION" and "missing" in str(err)


def test_non_numeric_coordinate(tmp_path: Path) -> None:
    err = _bad(tmp_path, _eil51_text().replace("\n5 40 30\n", "\n5 40 abc\n"))
    assert err.field == "NODE_COORD_SECTION"
    assert "node 5" in str(err) and "'abc'" in str(err)


def test_unsupported_edge_weight_type(tmp_path: Path) -> None:
    err = _bad(tmp_path, _eil51_text().replace("EUC_2D", "EXPLICIT"))
    assert err.field == "EDGE_WEIGHT_TYPE" and "'EXPLICIT'" in str(err)


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        ("TYPE : TSP", "TYPE : ATSP", "TYPE"),
        ("DIMENSION : 51", "DIMENSION : many", "DIMENSION"),
        ("EDGE_WEIGHT_TYPE : EUC_2D\n", "", "EDGE_WEIGHT_TYPE"),
        ("NODE_COORD_SECTION\n", "", None),  # the coordinates then read as a malformed header line
        ("\n5 40 30\n", "\n5 40\n", "NODE_COORD_SECTION"),
        ("\n5 40 30\n", "\n4 40 30\n", "NODE_COORD_SECTION"),  # node 4 twice
        ("\n5 40 30\n", "\n52 40 30\n", "NODE_COORD_SECTION"),
    ],
)
def test_other_malformed_files(tmp_path: Path, old: str, new: str, field: str | None) -> None:
    text = _eil51_text()
    assert old in text
    assert _bad(tmp_path, text.replace(old, new)).field == field


def test_missing_coordinate_section(tmp_path: Path) -> None:
    text = _eil51_text().split("NODE_COORD_SECTION")[0]
    assert _bad(tmp_path, text).field == "NODE_COORD_SECTION"


def test_unknown_file_or_name() -> None:
    with pytest.raises(ConfigError, match=r"^no_such_instance: .*bundled: .*eil51") as info:
        load_tsplib("no_such_instance")
    assert "\n" not in str(info.value)
