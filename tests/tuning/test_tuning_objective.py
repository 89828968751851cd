"""Objective expressions and parameter ranges: parsing, evaluation, refusals, scores of incomplete runs."""

from __future__ import annotations

import math

import pytest

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.tuning.objective import (
    DEFAULT_OBJECTIVE,
    Direction,
    MissingMetric,
    check_names,
    parse_objective,
    parse_objectives,
    score_run,
    split_expressions,
)
from pybullet_swarm.tuning.space import ParamSpec, check_params, parse_param

ROW = {
    "exit_status": "completed",
    "completion_time_s": 120.0,
    "sim_time_s": 121.0,
    "collisions.agent_agent": 3,
    "collisions.total": 4,
    "path_length_m.total": 50.0,
    "energy_j": 2.0,
}


def test_default_objective_is_time_plus_twenty_seconds_per_agent_collision() -> None:
    obj = parse_objective(DEFAULT_OBJECTIVE)
    assert obj.names == ("completion_time_s", "collisions.agent_agent")
    assert obj.evaluate(ROW) == pytest.approx(120.0 + 20 * 3)
    assert obj.direction is Direction.MINIMIZE


@pytest.mark.parametrize(
    "text, expected",
    [
        ("2 ** 3 - 1", 7.0),
        ("-completion_time_s / 4", -30.0),
        ("max(collisions.agent_agent, 10) + min(1, 2, 3)", 11.0),
        ("sqrt(energy_j * 8) + abs(-2) + log(exp(1.5))", 4.0 + 2.0 + 1.5),
        ("path_length_m.total // 7", 7.0),
        ("collisions.total - collisions.agent_agent", 1.0),
    ],
)
def test_expressions_evaluate_to_their_closed_forms(text: str, expected: float) -> None:
    assert parse_objective(text).evaluate(ROW) == pytest.approx(expected)


@pytest.mark.parametrize(
    "text",
    [
        "__import__('os').system('true')",  # a call of something not whitelisted
        "completion_time_s.__class__()",  # a call of an attribute
        "lambda: 1",
        "completion_time_s if True else 0",
        "completion_time_s > 3",
        "'abc'",
        "True + 1",
        "[1, 2][0]",
        "energy_j[0]",
        "max(energy_j, key=abs)",
        "sqrt(1, 2)",
        "1 +",
        "",
    ],
)
def test_anything_outside_the_whitelist_is_refused_in_one_line(text: str) -> None:
    with pytest.raises(ConfigError) as err:
        parse_objective(text)
    msg = str(err.value)
    assert msg.startswith("--objective: ") and "\n" not in msg


def test_unknown_metric_names_are_refused_with_the_closest_known_ones() -> None:
    objs = parse_objectives("completion_time_s + 20 * colisions.agent_agent")
    with pytest.raises(ConfigError) as err:
        check_names(objs, ROW)
    msg = str(err.value)
    assert "\n" not in msg
    assert "unknown metric 'colisions.agent_agent'" in msg and "did you mean collisions.agent_agent" in msg
    check_names(parse_objectives(DEFAULT_OBJECTIVE), ROW)  # known names pass


def test_objectives_split_at_top_level_commas_with_their_directions() -> None:
    assert split_expressions("max(a, b),c") == ["max(a, b)", "c"]
    objs = parse_objectives("completion_time_s,collisions.agent_agent", "minimize,max")
    assert [o.direction for o in objs] == [Direction.MINIMIZE, Direction.MAXIMIZE]
    with pytest.raises(ConfigError, match="--directions: needs one direction per objective"):
        parse_objectives("a,b", "minimize")
    with pytest.raises(ConfigError, match="--directions: must be minimize or maximize"):
        parse_objectives("a", "sideways")
    with pytest.raises(ConfigError, match="must not repeat"):
        parse_objectives("a,a")


def test_an_incomplete_run_scores_its_time_reached_plus_the_penalty() -> None:
    objs = parse_objectives([DEFAULT_OBJECTIVE, "collisions.agent_agent"], ["minimize", "maximize"])
    timeout = {**ROW, "exit_status": "timeout", "completion_time_s": None, "sim_time_s": 500.0}
    assert score_run(objs, ROW, 100.0) == (pytest.approx(180.0), pytest.approx(3.0))
    # completion time stands in as the 500 s reached; +100 when minimising, -100 when maximising
    assert score_run(objs, timeout, 100.0) == (pytest.approx(500 + 60 + 100), pytest.approx(3 - 100))
    with pytest.raises(MissingMetric, match="the run failed: boom"):
        score_run(objs, {"exit_status": "error", "error": "boom"})
    with pytest.raises(MissingMetric, match="energy_j"):
        score_run(parse_objectives("energy_j"), {**ROW, "energy_j": None})
    assert math.isnan(parse_objective("1 / (energy_j - 2)").evaluate(ROW))  # division by zero: no score


def test_parameter_ranges_parse_and_bad_ones_are_refused_in_one_line() -> None:
    p = parse_param("planner.params.fatigue=0.001:0.1:log")
    assert p == ParamSpec("planner.params.fatigue", 0.001, 0.1, log=True)
    assert parse_param("agents.count=2:8:int").integer
    assert parse_param("a.b=-1:1").text() == "a.b=-1:1"
    for bad, needle in [
        ("a.b=1", "expected key.path=low:high"),
        ("a.b", "expected key.path=low:high"),
        ("a.b=2:1", "needs low < high"),
        ("a.b=0:1:log", "log range needs low > 0"),
        ("a.b=x:1", "must be numbers"),
        ("a.b=0:1:cubic", "modifiers"),
        ("a.b=0.5:2:int", "integer bounds"),
        ("a..b=0:1", "expected a key.path"),
        ("a.b=0:inf", "finite"),
    ]:
        with pytest.raises(ConfigError, match=needle) as err:
            parse_param(bad)
        assert str(err.value).startswith("--param") and "\n" not in str(err.value)
    with pytest.raises(ConfigError, match="overlaps"):
        check_params([parse_param("planner.params=0:1"), parse_param("planner.params.x=0:1")])
    with pytest.raises(ConfigError, match="at least one"):
        check_params([])
