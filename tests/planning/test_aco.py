"""Tests of pybullet_swarm/planning/aco.py (and of the ``tsp`` subcommand that drives it)."""

from __future__ import annotations

import argparse
import itertools
import json

import numpy as np
import pydantic
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pybullet_swarm.cli import tsp as tsp_cli
from pybullet_swarm.planning.aco import (
    ACOParams,
    LocalSearch,
    Schedule,
    Variant,
    schedule_values,
    solve_tsp,
    tour_length,
    two_opt,
)
from pybullet_swarm.planning.tsplib import load_tsplib


def _random_instance(n: int, seed: int) -> np.ndarray:
    """(n, n) Euclidean distances of n uniform points in the unit square."""
    pts = np.random.default_rng(seed).random((n, 2))
    return np.linalg.norm(pts[:, None] - pts[None, :], axis=-1)


def _brute_force_optimum(dist: np.ndarray) -> float:
    """Shortest closed tour by enumerating all tours through city 0."""
    n = dist.shape[0]
    perms = np.array(list(itertools.permutations(range(1, n))))
    tours = np.hstack([np.zeros((len(perms), 1), dtype=int), perms])
    return float(dist[tours, np.roll(tours, -1, axis=1)].sum(axis=1).min())


def _has_improving_2opt_move(dist: np.ndarray, tour: np.ndarray) -> bool:
    n = len(tour)
    for i in range(n - 1):
        for j in range(i + 2, n if i else n - 1):
            a, b, c, d = tour[i], tour[i + 1], tour[j], tour[(j + 1) % n]
            if dist[a, c] + dist[b, d] < dist[a, b] + dist[c, d] - 1e-9:
                return True
    return False


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(5, 40), seed=st.integers(0, 2**32 - 1), neighbours=st.sampled_from([None, 3, 8]), or_opt=st.booleans()
)
def test_two_opt_never_lengthens_and_keeps_a_permutation(
    n: int, seed: int, neighbours: int | None, or_opt: bool
) -> None:
    dist = _random_instance(n, seed)
    tour = np.random.default_rng(seed + 1).permutation(n)
    better = two_opt(dist, tour, neighbours=neighbours, or_opt=or_opt)
    np.testing.assert_array_equal(np.sort(better), np.arange(n))
    assert tour_length(dist, better) <= tour_length(dist, tour) + 1e-9
    if neighbours is None:  # full neighbourhoods: a true 2-opt local optimum
        assert not _has_improving_2opt_move(dist, better)


def test_two_opt_fixes_a_crossing() -> None:
    # unit square visited corner-to-corner crosses itself: 2 + 2 sqrt(2) -> 4
    pts = np.array([[0, 0], [1, 1], [1, 0], [0, 1]], dtype=float)
    dist = np.linalg.norm(pts[:, None] - pts[None, :], axis=-1)
    square = np.array([[0, 0], [0, 1], [1, 1], [1, 0], [0.5, -0.5]], dtype=float)
    d5 = np.linalg.norm(square[:, None] - square[None, :], axis=-1)
    assert tour_length(dist, [0, 1, 2, 3]) == pytest.approx(2 + 2 * np.sqrt(2))
    assert tour_length(dist, [0, 2, 1, 3]) == pytest.approx(4.0)
    fixed = two_opt(d5, np.array([0, 2, 1, 3, 4]), neighbours=None)
    assert tour_length(d5, fixed) == pytest.approx(3 + np.sqrt(2))


@pytest.mark.parametrize(
    "params",
    [
        ACOParams(iterations=50),
        ACOParams(
            variant=Variant.AS,
            alpha=1,
            beta=2,
            rho=0.5,
            q0=0.0,
            ants=20,
            iterations=50,
            local_search=LocalSearch.NONE,
            candidates=None,
        ),
        ACOParams(iterations=50, schedule=Schedule.LINEAR, local_search=LocalSearch.TWO_OPT),
    ],
    ids=["acs-default", "as-plain", "acs-linear-2opt"],
)
def test_finds_brute_force_optimum_on_nine_cities(params: ACOParams) -> None:
    dist = _random_instance(9, seed=7)
    result = solve_tsp(dist, params, seed=1)
    assert result.length == pytest.approx(_brute_force_optimum(dist))


def test_result_is_consistent() -> None:
    dist = _random_instance(30, seed=3)
    result = solve_tsp(dist, ACOParams(iterations=40), seed=5)
    assert result.tour[0] == 0 and result.tour[1] < result.tour[-1]
    np.testing.assert_array_equal(np.sort(result.tour), np.arange(30))
    assert result.length == pytest.approx(tour_length(dist, result.tour))
    assert result.history.shape == (40,)
    assert np.all(np.diff(result.history) <= 0)
    assert result.history[-1] == pytest.approx(result.length)
    assert result.history[result.best_iteration] == pytest.approx(result.length)


def test_same_seed_same_tour() -> None:
    dist = _random_instance(40, seed=11)
    params = ACOParams(iterations=30, q0=0.5)
    a = solve_tsp(dist, params, seed=42)
    b = solve_tsp(dist, params, seed=42)
    c = solve_tsp(dist, params, rng=np.random.default_rng(42))
    np.testing.assert_array_equal(a.tour, b.tour)
    np.testing.assert_array_equal(a.history, b.history)
    np.testing.assert_array_equal(a.tour, c.tour)
    with pytest.raises(ValueError, match="seed, rng"):
        solve_tsp(dist, params, seed=1, rng=np.random.default_rng(1))


def test_tiny_instances_are_trivial() -> None:
    dist = _random_instance(3, seed=0)
    result = solve_tsp(dist, ACOParams(iterations=5), seed=0)
    assert sorted(result.tour) == [0, 1, 2]
    assert result.length == pytest.approx(dist[0, 1] + dist[1, 2] + dist[2, 0])


@pytest.mark.parametrize(
    ("schedule", "expected"),
    [
        (Schedule.CONSTANT, [(5.0, 10.0), (5.0, 10.0), (5.0, 10.0)]),
        (Schedule.LINEAR, [(0.0, 20.0), (5.0, 10.0), (10.0, 0.0)]),
        (Schedule.LINEAR_NO_FACTOR, [(0.0, 10.0), (2.5, 5.0), (5.0, 0.0)]),
    ],
)
def test_schedule_values(schedule: Schedule, expected: list[tuple[float, float]]) -> None:
    params = ACOParams(alpha=5.0, beta=10.0, iterations=100, schedule=schedule)
    got = [schedule_values(params, k) for k in (0, 50, 100)]
    np.testing.assert_allclose(got, expected)


def test_linear_schedule_keeps_the_nominal_means() -> None:
    params = ACOParams(alpha=5.0, beta=5.0, iterations=100, schedule=Schedule.LINEAR)
    values = np.array([schedule_values(params, k) for k in range(1, 101)])
    np.testing.assert_allclose(values.mean(axis=0), [5.05, 4.95])  # k = 1..n, as solve_tsp uses
    with pytest.raises(ValueError, match="k"):
        schedule_values(params, 101)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("alpha", -1.0),
        ("beta", float("nan")),
        ("rho", 1.5),
        ("q0", -0.1),
        ("xi", 2.0),
        ("ants", 0),
        ("iterations", 0),
        ("iterations", 2.5),
        ("candidates", 0),
        ("ls_neighbours", 0),
        ("tau0", 0.0),
        ("schedule", "quadratic"),
        ("variant", "mmas"),
        ("local_search", "3opt"),
        ("iterations", 10**9),
        ("ants", True),
        ("alpha", float("inf")),
    ],
)
def test_bad_params_name_the_field(field: str, value: object) -> None:
    with pytest.raises(pydantic.ValidationError) as err:
        ACOParams(**{field: value})  # type: ignore[arg-type]
    assert err.value.errors()[0]["loc"] == (field,)


def test_params_accept_enum_values_as_strings() -> None:
    params = ACOParams(
        variant="as",
        schedule="linear",  # type: ignore[arg-type]
        local_search="2opt",
    )
    assert params.variant is Variant.AS
    assert params.schedule is Schedule.LINEAR
    assert params.local_search is LocalSearch.TWO_OPT


@pytest.mark.parametrize(
    "dist",
    [
        np.ones((3, 4)),
        np.array([[0.0, 1.0], [2.0, 0.0]]),
        np.array([[0.0, -1.0], [-1.0, 0.0]]),
    ],
)
def test_bad_distances(dist: np.ndarray) -> None:
    with pytest.raises(ValueError, match="^dist: "):
        solve_tsp(dist, seed=0)


def test_eil51_mean_within_two_percent() -> None:
    dist = load_tsplib("eil51").distance_matrix()
    lengths = [solve_tsp(dist, seed=s).length for s in range(3)]
    assert np.mean(lengths) <= 426 * 1.02


def _cli(argv: list[str]) -> int:
    """Run the ``tsp`` subcommand as the main CLI would."""
    parser = argparse.ArgumentParser(prog="pybullet-swarm")
    tsp_cli.register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return int(args.func(args))


def test_cli_json_output(capsys: pytest.CaptureFixture[str]) -> None:
    code = _cli(["tsp", "eil51", "--runs", "2", "--seed", "3", "--iterations", "20", "--json"])
    out, err = capsys.readouterr()
    assert code == 0 and err == ""
    report = json.loads(out)
    assert {"instance", "runs", "mean", "std", "best", "optimum", "gap_percent"} <= set(report)
    assert (report["instance"], report["runs"], report["optimum"]) == ("eil51", 2, 426.0)
    assert report["best"] == min(report["lengths"]) >= 426
    assert report["gap_percent"] == pytest.approx(100 * (report["mean"] - 426) / 426)
    assert sorted(report["best_tour"]) == list(range(1, 52))
    seeded = solve_tsp(load_tsplib("eil51").distance_matrix(), ACOParams(iterations=20), seed=4)
    assert report["lengths"][1] == seeded.length  # run i uses seed + i


def test_cli_table_and_options(capsys: pytest.CaptureFixture[str]) -> None:
    code = _cli(
        [
            "tsp",
            "eil51",
            "--runs",
            "1",
            "--alpha",
            "1",
            "--beta",
            "3",
            "--evaporation",
            "0.2",
            "--ants",
            "5",
            "--iterations",
            "5",
            "--schedule",
            "linear",
            "--local-search",
            "none",
        ]
    )
    out, _ = capsys.readouterr()
    assert code == 0
    assert "eil51: mean" in out and "optimum 426" in out


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["tsp", "eil51", "--ants", "0"], "--ants: "),
        (["tsp", "eil51", "--evaporation", "1.5"], "--evaporation: "),
        (["tsp", "eil51", "--runs", "0"], "--runs: "),
        (["tsp", "no_such_instance"], "no_such_instance: "),
    ],
)
def test_cli_bad_input_exits_2(capsys: pytest.CaptureFixture[str], argv: list[str], needle: str) -> None:
    assert _cli(argv) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith("pybullet-swarm: error: ") and needle in err
    assert err.count("\n") == 1
