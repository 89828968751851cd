"""Parameter presets: ``preset: thesis`` resolves to the documented values of every extension switch,
explicit values win over it, it is refused where a planner has none, and a run's scenario.yaml
written with it reproduces the run."""

from __future__ import annotations

import json
from pathlib import Path

import pydantic
import pytest
import yaml

import pybullet_swarm
from pybullet_swarm.cli.main import main
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.planning.params import Preset, extensions, preset_values
from pybullet_swarm.planning.registry import planners
from pybullet_swarm.planning.shortest_path import ShortestPathParams
from pybullet_swarm.planning.stigmergy import LayeredStigmergyParams, StigmergyParams

#: the thesis's values as the planners' docstrings document them (every extension off)
THESIS_STIGMERGY = {
    "cell_size": 0.1,
    "box_pheromone": 1.0,
    "goal_pheromone": -1.0,
    "trail_pheromone": 0.2,
    "fatigue": 0.0,
    "local_radius": 0.2,
    "distance_scale": None,
    "ties": "first",
    "claims": False,
    "wide_view": False,
    "view_window": 0.15,
    "layout_altitudes": False,
    "drift_breakoff": False,
    "descent_timeout_s": None,
    "release_over_neighbours": False,
    "clear_spent_goals": False,
    "raise_drop_point": False,
    "search_near": False,
    "queue_at_slots": False,
}
THESIS_LAYERED = {
    **THESIS_STIGMERGY,
    "presence_pheromone": 2.0,
    "presence_fatigue": 2.0,
    "lookahead": 0.1,
    "detour": False,
}
THESIS_SHORTEST_PATH = {
    "altitude_step": 0.0,
    "retry_slots": False,
    "wait_beside": False,
    "spaced_descents": False,
    "release_over_neighbours": False,
    "wake_lanes": False,
    "plumb_legs": False,
    "soft_landing": False,
    "swap_boxes": False,
    "round_parked": False,
    "wake_clear": False,
    "wait_away": False,
    "park_clear": False,
    "recentre_box": False,
    "held_pass": False,
}


@pytest.mark.parametrize(
    "model, documented",
    [
        (ShortestPathParams, THESIS_SHORTEST_PATH),
        (StigmergyParams, THESIS_STIGMERGY),
        (LayeredStigmergyParams, THESIS_LAYERED),
    ],
)
def test_the_thesis_preset_resolves_to_the_documented_values(model, documented):
    got = preset_values(model, "thesis")
    assert got["preset"] == "thesis"
    assert {k: got[k] for k in documented} == documented
    default = model().model_dump(mode="json")
    untouched = set(model.model_fields) - set(documented) - {"preset"}
    assert {k: got[k] for k in untouched} == {k: default[k] for k in untouched}  # everything else as by default
    assert default["preset"] is None


def test_the_extensions_are_exactly_the_switches_the_preset_turns_off():
    assert list(extensions(ShortestPathParams)) == [
        "altitude_step",
        "retry_slots",
        "wait_beside",
        "spaced_descents",
        "release_over_neighbours",
        "wake_lanes",
        "plumb_legs",
        "soft_landing",
        "swap_boxes",
        "round_parked",
        "wake_clear",
        "wait_away",
        "park_clear",
        "held_pass",
        "recentre_box",
    ]
    assert list(extensions(StigmergyParams)) == [
        "ties",
        "claims",
        "wide_view",
        "layout_altitudes",
        "drift_breakoff",
        "descent_timeout_s",
        "release_over_neighbours",
        "raise_drop_point",
        "clear_spent_goals",
        "search_near",
        "queue_at_slots",
    ]
    assert list(extensions(LayeredStigmergyParams)) == [
        *extensions(StigmergyParams),
        "lookahead",
        "detour",
    ]
    assert extensions(LayeredStigmergyParams)["lookahead"] == (0.1, 0.2)  # (thesis, default)


def test_explicit_values_win_over_the_preset():
    p = LayeredStigmergyParams(preset="thesis", claims=True, lookahead=0.3)
    assert (p.preset, p.claims, p.lookahead, p.wide_view) == (Preset.THESIS, True, 0.3, False)
    assert StigmergyParams(preset=None).claims is True  # no preset: the defaults


def test_an_unknown_preset_or_a_preset_of_a_planner_without_presets_is_refused_at_load():
    with pytest.raises(pydantic.ValidationError, match="must be one of thesis, got 'paper'"):
        StigmergyParams(preset="paper")
    without = [name for name, entry in planners().items() if not entry.params.PRESETS]
    assert {"reynolds", "laplacian", "aco_tour", "waypoints"} <= set(without)
    for name in without:
        with pytest.raises(pydantic.ValidationError, match="these parameters have no presets"):
            planners()[name].params.model_validate({"preset": "thesis"})
    with pytest.raises(
        ConfigError,
        match=r"^flocking\.yaml: planner\.params\.preset: these parameters have no "
        r"presets, got 'thesis'$",
    ):
        pybullet_swarm.load_scenario("flocking", {"planner.params.preset": "thesis"}, planner="reynolds")
    with pytest.raises(ConfigError) as err:
        pybullet_swarm.load_scenario("construction", {"planner.params.preset": "paper"}, planner="stigmergy")
    assert err.value.field == "planner.params.preset"


def test_the_resolved_scenario_names_the_preset_and_every_value():
    sc = pybullet_swarm.load_scenario(
        "construction", {"planner.params.preset": "thesis", "planner.params.claims": True}, planner="layered_stigmergy"
    )
    params = sc.data["planner"]["params"]
    assert params == {**preset_values(LayeredStigmergyParams, "thesis"), "claims": True}
    again = pybullet_swarm.load_scenario("construction", {"planner.params": params}, planner="layered_stigmergy")
    assert again.planner_params == sc.planner_params  # a fixed point: explicit values = preset's


def test_a_run_with_the_preset_reproduces_from_its_own_scenario_yaml(tmp_path: Path):
    a, b = tmp_path / "A", tmp_path / "B"
    argv = [
        "--planner",
        "stigmergy",
        "--seed",
        "2",
        "--set",
        "task.time_limit_s=6",
        "--set",
        "planner.params.preset=thesis",
        "--set",
        "planner.params.claims=true",
    ]
    assert main(["run", "construction", *argv, "--out", str(a), "--no-plots", "--quiet"]) == 0
    data = yaml.safe_load((a / "scenario.yaml").read_text())
    assert data["planner"]["params"]["preset"] == "thesis" and data["planner"]["params"]["claims"] is True
    assert data["planner"]["params"]["wide_view"] is False
    assert main(["run", str(a / "scenario.yaml"), "--out", str(b), "--no-plots", "--quiet"]) == 0
    ma, mb = (json.loads((d / "metrics.json").read_text()) for d in (a, b))
    for m in (ma, mb):
        m.pop("wall_time_s")
        m.pop("real_time_factor")
    assert ma == mb
    assert (a / "events.csv").read_text() == (b / "events.csv").read_text()
