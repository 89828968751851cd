"""Tests of pybullet_swarm/experiment/scenario.py: loading, overrides, schema and semantic checks.

Every bad scenario must raise one ``ConfigError`` of one line, ``file: field.path: expectation,
got value``, with ``.source`` and ``.field`` set; never a pydantic, YAML or Python error.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import (
    Scenario,
    apply_overrides,
    build_scenario,
    load_scenario,
    parse_override,
    resolve_scenario_path,
)
from pybullet_swarm.resources import bundled_scenarios, scenarios_dir

HOVER = scenarios_dir() / "hover.yaml"


def hover_data() -> dict[str, Any]:
    """The bundled hover scenario as plain data (a fresh copy)."""
    return yaml.safe_load(HOVER.read_text(encoding="utf-8"))


def _set(data: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    return apply_overrides(data, {path: value}, source="test")


def bad(data: Any, *, source: str = "bad.yaml") -> ConfigError:
    """Build ``data``; return the ConfigError, checked to be one line naming the source."""
    with pytest.raises(ConfigError) as info:
        build_scenario(data, source=source)
    err = info.value
    text = str(err)
    assert "\n" not in text
    assert text.startswith(f"{source}: ")
    assert err.source == source
    if err.field:
        assert text.startswith(f"{source}: {err.field}: ")
    return err


def bad_file(tmp_path: Path, text: str, name: str = "bad.yaml", overrides: Any = ()) -> ConfigError:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_scenario(path, overrides)
    assert "\n" not in str(info.value)
    assert name in str(info.value)
    return info.value


# ------------------------------------------------------------------ valid scenarios
@pytest.mark.parametrize("name", bundled_scenarios())
def test_bundled_scenarios_load_and_resolved_data_round_trips(name: str) -> None:
    s = load_scenario(name)
    assert isinstance(s, Scenario)
    assert s.source == f"{name}.yaml"
    again = build_scenario(copy.deepcopy(dict(s.data)), source="again.yaml")
    assert again.data == s.data
    # the resolved data are plain YAML
    assert yaml.safe_load(yaml.safe_dump(dict(s.data))) == dict(s.data)


def test_hover_resolved_defaults() -> None:
    s = load_scenario("hover")
    assert s.agents.count == 1 and s.agents.vehicle == "quad150"
    assert s.sim.physics_hz == 240 and s.sim.control_hz == 48
    assert s.task.time_limit_s == 40.0 and len(s.task.waypoints) == 4
    assert s.velocity_limits().tolist() == [0.5, 0.5, 0.5]
    assert s.start_positions(0.1).shape == (1, 3)


def test_int_where_float_expected_is_valid() -> None:
    data = _set(hover_data(), "task.time_limit_s", 40)
    data["task"]["waypoints"][0]["t_s"] = 0
    s = build_scenario(data, source="ok.yaml")
    assert s.task.time_limit_s == 40.0


@pytest.mark.parametrize("velocity", [None, 0.25, 2, [0.5, 0.5, 1.0]])
def test_velocity_limit_forms(velocity: Any) -> None:
    s = build_scenario(_set(hover_data(), "limits.velocity", velocity), source="ok.yaml")
    v = s.velocity_limits()
    if velocity is None:
        assert v is None
    else:
        assert v is not None and v.shape == (3,)


def test_overrides_by_mapping_and_by_text_agree() -> None:
    a = load_scenario("hover_swarm", {"agents.count": 4, "sim.record_hz": 40})
    b = load_scenario("hover_swarm", ["agents.count=4", "sim.record_hz=40"])
    assert a.data == b.data
    assert a.agents.count == 4 and a.sim.record_hz == 40


def test_with_overrides_validates_again() -> None:
    s = load_scenario("hover")
    assert s.with_overrides(["agents.count=1", "seed=7"]).seed == 7
    with pytest.raises(ConfigError) as info:
        s.with_overrides({"agents.count": 0})
    assert info.value.field == "agents.count"
    assert str(info.value) == "hover.yaml: agents.count: must be >= 1, got 0"


# ------------------------------------------------------------------------- rates
@pytest.mark.parametrize(
    ("override", "field", "got"),
    [
        ("sim.control_hz=50", "sim.control_hz", "50"),
        ("sim.record_hz=7", "sim.record_hz", "7"),
        ("sim.planner_hz=11", "sim.planner_hz", "11"),
        ("sim.contact_hz=50", "sim.contact_hz", "50"),
        ("sim.control_hz=480", "sim.control_hz", "480"),  # faster than physics
        ("sim.physics_hz=250", "sim.control_hz", "48"),  # 48 no longer divides
    ],
)
def test_non_dividing_rates_name_the_field(override: str, field: str, got: str) -> None:
    with pytest.raises(ConfigError) as info:
        load_scenario("hover", overrides=[override])
    err = info.value
    assert err.field == field
    assert err.source == "hover.yaml"
    physics = 250 if "physics" in override else 240
    assert str(err) == (f"hover.yaml: {field}: must divide sim.physics_hz ({physics}) into an integer ratio, got {got}")


def test_non_dividing_rate_by_mapping_override() -> None:
    with pytest.raises(ConfigError) as info:
        load_scenario("hover", overrides={"sim.record_hz": 7})
    assert info.value.field == "sim.record_hz"


@pytest.mark.parametrize(
    ("field", "value"),
    [("control_hz", 0), ("record_hz", -20), ("physics_hz", 59), ("physics_hz", 10_001), ("contact_hz", 8)],
)
def test_out_of_range_rates(field: str, value: int) -> None:
    err = bad(_set(hover_data(), f"sim.{field}", value))
    assert err.field == f"sim.{field}"
    assert str(err).endswith(f", got {value}")


@settings(max_examples=60, deadline=None, database=None)
@given(rate=st.integers(min_value=1, max_value=600))
def test_record_rate_valid_exactly_when_it_divides_physics(rate: int) -> None:
    data = _set(hover_data(), "sim.record_hz", rate)
    if 240 % rate == 0:
        assert build_scenario(data, source="r.yaml").sim.record_hz == rate
    else:
        assert bad(data, source="r.yaml").field == "sim.record_hz"


# --------------------------------------------------------------- schema errors
@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        ("agents.count", 0, "agents.count: must be >= 1, got 0"),
        ("agents.count", 2001, "agents.count: must be <= 2000, got 2001"),
        ("agents.count", "five", "agents.count: must be a valid integer, got 'five'"),
        ("agents.count", 1.0, "agents.count: must be a valid integer, got 1.0"),
        ("agents.count", True, "agents.count: must be a valid integer, got True"),
        ("sim.gravity", "9.81", "sim.gravity: must be a valid number, got '9.81'"),
        ("sim.phyics_hz", 240, "sim.phyics_hz: unknown field, got 240"),
        ("bogus", 1, "bogus: unknown field, got 1"),
        ("sim", None, "sim: must be a valid dictionary, got None"),
        ("arena.size", [3.0], "arena.size: must have at least 2 items, got [3.0]"),
        ("arena.size", [3.0, -1.0], "arena.size[1]: must be > 0.0, got -1.0"),
        ("arena.height", 0, "arena.height: must be > 0.0, got 0"),
        ("limits.velocity", -1, "limits.velocity: must be >= 0.001, got -1"),
        ("limits.velocity", [1, 2], "limits.velocity: must have at least 3 items, got [1, 2]"),
        ("limits.velocity", [1, 2, 3, 4], "limits.velocity: must have at most 3 items, got [1, 2, 3, 4]"),
        ("limits.velocity", [1, -2, 3], "limits.velocity[1]: must be >= 0.001, got -2"),
        ("limits.velocity", "fast", "limits.velocity: must be a valid number or a valid list, got 'fast'"),
        ("limits.velocity", 2e6, "limits.velocity: must be <= 1000000.0, got 2000000.0"),
        ("limits.acceleration", None, "limits.acceleration: must be a valid number or a valid list, got None"),
        ("collisions", "soft", "collisions: must be 'physical' or 'ghost', got 'soft'"),
        ("seed", -1, "seed: must be >= 0, got -1"),
        ("task.time_limit_s", 0, "task.time_limit_s: must be > 0.0, got 0"),
        ("task.kind", "dance", "task.kind: must be one of construction, flock, route, tour, waypoints, got 'dance'"),
        (
            "task.kind",
            ["waypoints"],
            "task.kind: must be one of construction, flock, route, tour, waypoints, got ['waypoints']",
        ),
        ("task.kind", {"a": 1}, "task.kind: must be one of construction, flock, route, tour, waypoints, got {'a': 1}"),
        ("task.relative", "yes", "task.relative: must be a valid boolean, got 'yes'"),
        ("task.waypoints", [], "task.waypoints: must have at least 1 item, got []"),
        ("task.waypoints", [1], "task.waypoints[0]: must be a valid dictionary, got 1"),
        ("task.speed", 1, "task.speed: unknown field, got 1"),
        ("planner.params", [1], "planner.params: must be a valid dictionary, got [1]"),
    ],
)
def test_schema_errors_are_one_line(path: str, value: Any, message: str) -> None:
    err = bad(_set(hover_data(), path, value))
    assert str(err) == f"bad.yaml: {message}"
    assert err.field == message.split(": ")[0]


@pytest.mark.parametrize(
    ("path", "message"),
    [
        ("task", "task: is required"),
        ("task.kind", "task.kind: is required"),
        ("task.time_limit_s", "task.time_limit_s: is required"),
        ("task.waypoints", "task.waypoints: is required"),
    ],
)
def test_missing_required_fields(path: str, message: str) -> None:
    data = hover_data()
    *parents, last = path.split(".")
    node = data
    for p in parents:
        node = node[p]
    del node[last]
    assert str(bad(data)) == f"bad.yaml: {message}"


def test_missing_waypoint_position() -> None:
    data = hover_data()
    del data["task"]["waypoints"][2]["position"]
    assert str(bad(data)) == "bad.yaml: task.waypoints[2].position: is required"


@pytest.mark.parametrize("value", [float("nan"), float("inf"), float("-inf")])
def test_non_finite_numbers_are_refused(value: float) -> None:
    data = hover_data()
    data["task"]["waypoints"][1]["position"][0] = value
    err = bad(data)
    assert err.field == "task.waypoints[1].position[0]"
    assert "must be a finite number" in str(err)
    assert "must be a finite number" in str(bad(_set(hover_data(), "sim.gravity", value)))


@pytest.mark.parametrize("key", [1, None, True, 1.5])
def test_non_string_keys(key: Any) -> None:
    data = hover_data()
    data["sim"][key] = 1
    err = bad(data)
    assert str(err) == f"bad.yaml: sim: keys must be strings, got {key!r}"
    data = hover_data()
    data[key] = 1
    assert str(bad(data)) == f"bad.yaml: keys must be strings, got {key!r}"


@pytest.mark.parametrize("data", [None, [], [1, 2], "hover", 42])
def test_top_level_must_be_a_mapping(data: Any) -> None:
    err = bad(data)
    assert str(err).startswith("bad.yaml: must be a mapping of scenario sections, got ")


# -------------------------------------------------------------- semantic errors
def test_start_positions_count_must_match() -> None:
    data = _set(hover_data(), "agents.count", 2)
    data["agents"]["start"] = [[1.0, 1.0, 0.1]]
    err = bad(data)
    assert str(err) == "bad.yaml: agents.start: must hold agents.count (2) positions, got 1"


def test_start_outside_the_arena() -> None:
    err = bad(_set(hover_data(), "agents.start", [[10.0, 1.0, 0.1]]))
    assert err.field == "agents.start[0]"
    assert "outside the arena [0, 3] x [0, 3] m" in str(err)


def test_start_below_the_ground() -> None:
    err = bad(_set(hover_data(), "agents.start", [[1.0, 1.0, -0.5]]))
    assert err.field == "agents.start[0]"
    assert "below the ground" in str(err)


def test_layout_too_large_for_the_arena() -> None:
    err = bad(_set(hover_data(), "agents.count", 100))
    assert err.field == "agents.count"
    assert "outside the arena" in str(err)


def test_overlapping_starts() -> None:
    data = _set(hover_data(), "agents.count", 2)
    data["agents"]["start"] = [[1.0, 1.0, 0.1], [1.05, 1.0, 0.1]]
    err = bad(data)
    assert err.field == "agents.start"
    assert "agents 0 and 1 start overlapping" in str(err)
    data = _set(_set(hover_data(), "agents.count", 4), "agents.spacing", 0.01)
    assert bad(data).field == "agents.spacing"


def test_unknown_vehicle() -> None:
    err = bad(_set(hover_data(), "agents.vehicle", "nosuch"))
    assert err.field == "agents.vehicle"
    assert "unknown vehicle 'nosuch'" in str(err)


def test_vehicle_name_too_long_for_the_file_system() -> None:
    err = bad(_set(hover_data(), "agents.vehicle", "v" * 300))
    assert err.field == "agents.vehicle"


def test_waypoint_times_must_not_decrease() -> None:
    data = hover_data()
    data["task"]["waypoints"][2]["t_s"] = 5
    err = bad(data)
    assert str(err) == "bad.yaml: task.waypoints[2].t_s: waypoint times must not decrease, got 5 after 8"


def test_last_waypoint_after_the_time_limit() -> None:
    err = bad(_set(hover_data(), "task.time_limit_s", 10))
    assert err.field == "task.waypoints"
    assert "after the time limit 10 s" in str(err)


# ------------------------------------------------------- plain data from YAML
def test_cyclic_alias_is_refused(tmp_path: Path) -> None:
    text = HOVER.read_text() + "planner:\n  params: {loop: &a [1, *a]}\n"
    err = bad_file(tmp_path, text)
    assert err.field == "planner.params.loop[1]"
    assert "cyclic YAML alias" in str(err)


def test_shared_alias_is_fine(tmp_path: Path) -> None:
    text = HOVER.read_text().replace("limits:\n", "limits:\n  velocity: &v [0.5, 0.5, 0.4]\n  acceleration: *v\n", 1)
    text = "\n".join(line for line in text.splitlines() if not line.startswith(("  velocity: 0", "  acceleration: 1")))
    path = tmp_path / "ok.yaml"
    path.write_text(text)
    s = load_scenario(path)
    assert s.limits.velocity == s.limits.acceleration == [0.5, 0.5, 0.4]


@pytest.mark.parametrize("depth", [40, 2000])
def test_deep_nesting_is_refused(tmp_path: Path, depth: int) -> None:
    text = HOVER.read_text() + "planner:\n  params: {x: " + "[" * depth + "]" * depth + "}\n"
    err = bad_file(tmp_path, text)
    assert "nested" in str(err)


def test_duplicate_keys_are_refused(tmp_path: Path) -> None:
    text = HOVER.read_text()
    line = len(text.splitlines()) + 1  # the second `sim:` section
    err = bad_file(tmp_path, text + "sim:\n  physics_hz: 480\n")
    assert str(err) == f"bad.yaml: malformed YAML at line {line}, column 1: found duplicate key 'sim'"


def test_merge_keys_still_work(tmp_path: Path) -> None:
    # a merged key overridden by an explicit one is not a duplicate
    text = HOVER.read_text().replace("sim:\n", "sim:\n  <<: {gravity: 9.0, drag_coefficient: 0.1}\n", 1)
    path = tmp_path / "ok.yaml"
    path.write_text(text)
    s = load_scenario(path)
    assert s.sim.gravity == 9.81 and s.sim.drag_coefficient == 0.1


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ("2020-13-45", "bad.yaml: seed: cannot read !!timestamp '2020-13-45' (month must be in 1..12)"),
        ("!!int abc", "bad.yaml: seed: cannot read !!int 'abc' (invalid literal for int() with base 10: 'abc')"),
        ("!!float abc", "bad.yaml: seed: cannot read !!float 'abc' (could not convert string to float: 'abc')"),
        ("9" * 5000, "bad.yaml: seed: cannot read !!int '9999"),
        (
            "!!python/object:os.system x",
            "bad.yaml: malformed YAML at line 4, column 7: could not determine a constructor",
        ),
    ],
)
def test_unreadable_yaml_values(tmp_path: Path, value: str, expected: str) -> None:
    err = bad_file(tmp_path, HOVER.read_text().replace("seed: 0", f"seed: {value}"))
    assert str(err).startswith(expected)


@pytest.mark.parametrize(
    "text",
    ["sim: [1, 2\n", "sim:\n\tphysics_hz: 240\n", "name: 'unterminated\n", "a: {b: 1\n", "a: b: c\n"],
)
def test_malformed_yaml(tmp_path: Path, text: str) -> None:
    err = bad_file(tmp_path, text)
    assert str(err).startswith("bad.yaml: malformed YAML at line ")


def test_huge_hex_integer_is_refused_not_crashing(tmp_path: Path) -> None:
    big = "0x" + "f" * 3000  # parses without the decimal digit limit, cannot be printed
    err = bad_file(tmp_path, HOVER.read_text() + f"planner:\n  params: {{x: {big}}}\n")
    assert err.field == "planner.params.x"
    err = bad_file(tmp_path, HOVER.read_text().replace("count: 1", f"count: {big}"))
    assert err.field == "agents.count"


# ------------------------------------------------------------------ overrides
@pytest.mark.parametrize(
    ("text", "key", "value"),
    [
        ("agents.count=5", "agents.count", 5),
        ("limits.velocity=[1, 2, 3]", "limits.velocity", [1, 2, 3]),
        ("limits.velocity=null", "limits.velocity", None),
        ("limits.velocity=", "limits.velocity", None),
        ("name=a=b", "name", "a=b"),
        (" seed = 3", "seed", 3),
    ],
)
def test_parse_override(text: str, key: str, value: Any) -> None:
    assert parse_override(text) == (key, value)


@pytest.mark.parametrize("text", ["agents.count", "=1", "agents..count=1", ".x=1", "x.=1"])
def test_parse_override_errors(text: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_override(text)
    assert str(info.value) == f"--set: expected key.path=value, got {text!r}"


@pytest.mark.parametrize("raw", ["[1", "{a: 1", "2020-13-45", "{a: 1, a: 2}"])
def test_parse_override_bad_yaml_value(raw: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_override(f"agents.count={raw}")
    assert info.value.field == "agents.count"
    assert str(info.value) == f"--set: agents.count: value is not valid YAML, got {raw!r}"


def test_override_inside_a_scalar_or_list() -> None:
    with pytest.raises(ConfigError) as info:
        load_scenario("hover", ["sim.physics_hz.x=1"])
    assert str(info.value) == "hover.yaml: sim.physics_hz: must be a mapping to set sim.physics_hz.x inside it, got 240"
    with pytest.raises(ConfigError) as info:
        load_scenario("hover", ["task.waypoints.0.t_s=1"])
    assert info.value.field == "task.waypoints"


def test_override_creates_sections_and_bad_values_are_reported() -> None:
    s = load_scenario("hover", {"avoidance": "orca", "avoidance_params.time_horizon": 2})
    assert s.avoidance_params.time_horizon == 2.0 and s.data["avoidance_params"]["time_horizon"] == 2.0
    with pytest.raises(ConfigError) as info:
        load_scenario("hover", ["agents.count=abc"])
    assert str(info.value) == "hover.yaml: agents.count: must be a valid integer, got 'abc'"
    with pytest.raises(ConfigError) as info:
        load_scenario("hover", ["sim.nosuch=1"])
    assert str(info.value) == "hover.yaml: sim.nosuch: unknown field, got 1"


@pytest.mark.parametrize("key", [1, "", "a..b"])
def test_mapping_override_with_bad_key(key: Any) -> None:
    with pytest.raises(ConfigError):
        load_scenario("hover", {key: 1})


def test_override_on_a_non_mapping_file(tmp_path: Path) -> None:
    err = bad_file(tmp_path, "- 1\n- 2\n", overrides=["agents.count=2"])
    assert str(err) == "bad.yaml: must be a mapping of scenario sections, got list"


# --------------------------------------------------------------- resolution
def test_resolve_by_name_path_and_bare_file_name(tmp_path: Path) -> None:
    assert resolve_scenario_path("hover") == HOVER
    assert resolve_scenario_path("hover.yaml") == HOVER
    assert resolve_scenario_path(HOVER) == HOVER
    own = tmp_path / "mine.yml"
    own.write_text(HOVER.read_text())
    assert resolve_scenario_path(own) == own


@pytest.mark.parametrize("name", ["nosuch", "nosuch.yaml", "x" * 300, "y" * 300 + ".yaml"])
def test_resolve_unknown(name: str, tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        resolve_scenario_path(name)
    assert "\n" not in str(info.value)
    with pytest.raises(ConfigError) as info:
        resolve_scenario_path(tmp_path / "missing.yaml")
    assert str(info.value) == f"{tmp_path / 'missing.yaml'}: file not found"


@pytest.mark.parametrize("text", ["", "# only a comment\n", "---\n"])
def test_empty_files(tmp_path: Path, text: str) -> None:
    err = bad_file(tmp_path, text)
    assert str(err) == "bad.yaml: must be a mapping of scenario sections, got NoneType"


def test_binary_file(tmp_path: Path) -> None:
    path = tmp_path / "bin.yaml"
    path.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    assert "cannot read file" in str(info.value)


@settings(max_examples=40, deadline=None, database=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(count=st.integers(min_value=-5, max_value=40), spacing=st.floats(min_value=-1.0, max_value=2.0))
def test_layout_property(count: int, spacing: float) -> None:
    """Any count and spacing is either a valid swarm inside the arena or a one-line error."""
    data = hover_data()
    data["agents"].update(count=count, spacing=spacing)
    try:
        s = build_scenario(data, source="p.yaml")
    except ConfigError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("p.yaml: agents.")
    else:
        starts = s.start_positions(0.05)
        assert starts.shape == (count, 3)
        assert ((starts[:, :2] > 0) & (starts[:, :2] < 3.0)).all()


@pytest.mark.parametrize("field", ["name", "description"])
@pytest.mark.parametrize(
    ("char", "what"),
    [
        ("\u202e", "bidirectional control character U+202E"),
        ("\u2066", "bidirectional control character U+2066"),
        ("\u200f", "bidirectional control character U+200F"),
        ("\x1b", "control character U+001B"),
        ("\n", "control character U+000A"),
        ("\x85", "control character U+0085"),
        ("\u2028", "control character U+2028"),
    ],
)
def test_text_fields_with_control_or_bidi_characters_are_refused(field: str, char: str, what: str) -> None:
    data = hover_data()
    data[field] = f"ab{char}cd"
    err = bad(data)
    assert err.field == field
    assert f"got a {what} at position 2" in str(err)


def test_text_fields_in_other_scripts_are_drawable() -> None:
    data = hover_data()
    data["name"] = "سرب-群れ-Schwarm"
    data["description"] = "Ελληνικά, עברית (right to left without overrides), emoji 🛸"
    s = build_scenario(data, source="ok.yaml")
    assert s.name == data["name"] and s.description == data["description"]


# ------------------------------------------------------------ parameters that follow the layout
def _hidden_slot_layout() -> dict:
    """A generated layout (two structures) with a slot that agents at the default view radius see neither
    from beside the structure nor from above it."""
    from pybullet_swarm.experiment.layouts import random_layout

    return random_layout(1006, agents=(3, 20), max_arena=(6.0, 4.0), shape="several")


def test_an_unset_view_radius_is_derived_from_the_layout_for_every_planner():
    from pybullet_swarm.experiment.runner import build_run
    from pybullet_swarm.experiment.scenario import apply_choices

    data = _hidden_slot_layout()
    assert data["task"].get("view_radius") is None
    for planner in ("stigmergy", "layered_stigmergy"):
        s = build_scenario(apply_choices(copy.deepcopy(data), planner=planner, source="t"), source="t")
        assert s.task.view_radius == pytest.approx(0.496)  # more than the default two agent radii
        assert s.data["task"]["view_radius"] == pytest.approx(0.496)  # the resolved scenario reproduces it
        build_run(build_scenario(copy.deepcopy(s.data), source="again"))
    s = build_scenario(apply_choices(copy.deepcopy(data), planner="shortest_path", source="t"), source="t")
    assert s.task.view_radius is None  # a planner that needs no more keeps the default


def test_a_view_radius_the_user_set_too_small_is_refused_saying_what_would_work():
    from pybullet_swarm.experiment.scenario import apply_choices

    data = apply_choices(_hidden_slot_layout(), planner="stigmergy", source="t")
    data["task"]["view_radius"] = 0.2
    with pytest.raises(ConfigError) as err:
        build_scenario(copy.deepcopy(data), source="mine.yaml")
    assert err.value.field == "task.view_radius" and "at least 0.496 m" in str(err.value)
    assert str(err.value).startswith("mine.yaml: task.view_radius: ")
    data["task"]["view_radius"] = 0.5
    assert build_scenario(data, source="mine.yaml").task.view_radius == 0.5
