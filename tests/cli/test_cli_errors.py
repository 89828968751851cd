"""Bad input at the command line: exit code 2 and exactly one line on stderr, never a traceback.

``main(argv)`` is called in-process (fast); two cases go through a real subprocess for the real
exit code. A property-based test mutates the bundled ``hover.yaml`` in ways that are guaranteed
invalid (wrong types, deleted required fields, unknown keys, out-of-range numbers, broken YAML)
and a generic fuzz test in arbitrary ways (exit 0 or 2, never 1).
"""

from __future__ import annotations

import copy
import math
import subprocess
import sys
from pathlib import Path
from typing import Any, Callable

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pybullet_swarm.cli.main import main
from pybullet_swarm.resources import scenarios_dir

PREFIX = "pybullet-swarm: error: "
HOVER = scenarios_dir() / "hover.yaml"
HOVER_TEXT = HOVER.read_text(encoding="utf-8")
BASE: dict[str, Any] = yaml.safe_load(HOVER_TEXT)

FUZZ = settings(
    max_examples=150,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def run_cli(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, str, str]:
    """``main(argv)`` in-process: exit code, stdout, stderr."""
    capsys.readouterr()  # drop what earlier examples left
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code: int, out: str, err: str, *parts: str) -> str:
    """Exit 2, exactly one stderr line starting with the prefix and holding ``parts``; returns it."""
    assert code == 2, (code, out, err)
    assert "Traceback" not in out + err
    assert err.endswith("\n") and err.count("\n") == 1, err
    line = err[:-1]
    assert line.startswith(PREFIX), line
    for part in parts:
        assert part in line, (part, line)
    return line


def check_file(capsys: pytest.CaptureFixture[str], path: Path, *extra: str) -> tuple[int, str, str]:
    return run_cli(capsys, ["check", str(path), *extra])


def dump(data: Any) -> str:
    return yaml.safe_dump(data, sort_keys=False, allow_unicode=True)


# ---------------------------------------------------------- mutation helpers
Path_ = tuple[Any, ...]


def walk(node: Any, path: Path_ = ()) -> list[tuple[Path_, Any]]:
    """Every (path, value) below ``node``, containers included, root excluded."""
    out: list[tuple[Path_, Any]] = []
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        out.append(((*path, k), v))
        out.extend(walk(v, (*path, k)))
    return out


def get_at(data: Any, path: Path_) -> Any:
    for k in path:
        data = data[k]
    return data


def set_at(data: Any, path: Path_, value: Any) -> None:
    get_at(data, path[:-1])[path[-1]] = value


def del_at(data: Any, path: Path_) -> None:
    del get_at(data, path[:-1])[path[-1]]


def dotted(path: Path_) -> str:
    out = ""
    for k in path:
        out += f"[{k}]" if isinstance(k, int) else ("." if out else "") + k
    return out


LEAVES = walk(BASE)
CONTAINERS: list[Path_] = [()] + [p for p, v in LEAVES if isinstance(v, dict)]
NULLABLE = {("limits", "velocity"), ("arena", "height"), ("agents", "start"), ("agents", "origin")}

# required fields (deleting them is an error), and items of fixed-length lists
REQUIRED: list[Path_] = [("task",), ("task", "kind"), ("task", "time_limit_s"), ("task", "waypoints")]
REQUIRED += [p for p, _ in LEAVES if len(p) == 4 and p[:2] == ("task", "waypoints") and p[3] in ("t_s", "position")]
REQUIRED += [p for p, _ in LEAVES if p[:2] == ("arena", "size") and len(p) == 3]
REQUIRED += [p for p, _ in LEAVES if len(p) == 5 and p[3] == "position"]

texts = st.text(max_size=12)
finite = st.floats(allow_nan=False, allow_infinity=False)
numbers = st.one_of(st.integers(-(10**9), 10**9), finite)
text_lists = st.lists(texts, max_size=4)  # never a valid list of numbers or records
non_empty_dicts = st.dictionaries(texts, texts, min_size=1, max_size=3)


def wrong_type(path: Path_, value: Any) -> st.SearchStrategy[Any]:
    """Values of a type the field at ``path`` (now holding ``value``) cannot take."""
    if isinstance(value, bool):
        options = [numbers, texts, text_lists, non_empty_dicts, st.none()]
    elif isinstance(value, (int, float)):  # an int where a float is expected is valid: no numbers
        options = [texts, st.booleans(), text_lists, non_empty_dicts]
        if path not in NULLABLE:
            options.append(st.none())
    elif isinstance(value, str):
        options = [numbers, st.booleans(), text_lists, non_empty_dicts, st.none()]
    elif isinstance(value, list):  # arena.size, waypoints, positions
        options = [numbers, texts, st.booleans(), non_empty_dicts, st.none(), st.just([])]
    else:  # a section or a waypoint record ({} would be valid)
        options = [numbers, texts, st.booleans(), st.lists(texts, min_size=1, max_size=3)]
    return st.one_of(*options)


def _below(bound: float, *, strict: bool) -> st.SearchStrategy[Any]:
    """Numbers < bound (strict) or <= bound, as ints and floats (including -inf)."""
    top = bound - 1e-9 if strict else bound
    return st.one_of(
        st.floats(max_value=top, allow_nan=False),
        st.integers(min_value=-(10**30), max_value=math.ceil(top) - 1 if strict else math.floor(top)),
    )


def _above(bound: float) -> st.SearchStrategy[Any]:
    return st.one_of(
        st.floats(min_value=bound * (1 + 1e-9) + 1e-9), st.integers(min_value=int(bound) + 1, max_value=10**30)
    )


# field -> numbers outside its declared bounds (ge/gt/le of scenario.py)
OUT_OF_RANGE: dict[Path_, st.SearchStrategy[Any]] = {
    ("seed",): st.one_of(
        st.integers(max_value=-1, min_value=-(10**30)), st.integers(min_value=2**63, max_value=10**30)
    ),
    ("agents", "count"): st.one_of(st.integers(min_value=-(10**30), max_value=0), st.integers(2001, 10**30)),
    ("sim", "physics_hz"): st.one_of(st.integers(min_value=-(10**30), max_value=59), st.integers(10_001, 10**30)),
    ("sim", "gravity"): st.one_of(_below(0.0, strict=True), _above(100.0), st.just(math.nan)),
    ("arena", "size", 0): st.one_of(_below(0.0, strict=False), _above(1e4)),
    ("arena", "size", 1): st.one_of(_below(0.0, strict=False), _above(1e4)),
    ("limits", "velocity"): st.one_of(_below(0.0, strict=False), _above(1e6), st.just(math.nan)),
    ("limits", "acceleration"): st.one_of(_below(0.0, strict=False), _above(1e6)),
    ("task", "time_limit_s"): st.one_of(_below(0.0, strict=False), _above(1e5)),
    ("task", "tolerance_m"): st.one_of(_below(0.0, strict=False), _above(100.0)),
    ("task", "hold_s"): st.one_of(_below(0.0, strict=True), _above(1e4)),
}
for _rate in ("control_hz", "planner_hz", "record_hz"):
    OUT_OF_RANGE[("sim", _rate)] = st.one_of(
        st.integers(min_value=-(10**30), max_value=0), st.integers(241, 10**30)
    )  # > physics_hz or > le
for _p, _ in LEAVES:
    if len(_p) == 4 and _p[3] == "t_s":
        OUT_OF_RANGE[_p] = st.one_of(_below(0.0, strict=True), _above(1e5))
    if len(_p) == 5 and _p[3] == "position":
        OUT_OF_RANGE[_p] = st.sampled_from([math.nan, math.inf, -math.inf])
OUT_OF_RANGE_PATHS = sorted(OUT_OF_RANGE, key=repr)


@st.composite
def invalid_scenarios(draw: Callable[..., Any]) -> tuple[str, str]:
    """(what was done, YAML text) of a mutation of hover.yaml that is guaranteed invalid."""
    data = copy.deepcopy(BASE)
    kind = draw(st.sampled_from(["wrong_type", "delete", "unknown_key", "out_of_range"]))
    if kind == "wrong_type":
        path, value = draw(st.sampled_from(LEAVES))
        new = draw(wrong_type(path, value))
        set_at(data, path, new)
        what = f"{dotted(path)} = {new!r}"
    elif kind == "delete":
        path = draw(st.sampled_from(REQUIRED))
        del_at(data, path)
        what = f"del {dotted(path)}"
    elif kind == "unknown_key":
        path = draw(st.sampled_from(CONTAINERS))
        key = "zz_" + draw(st.text(alphabet="abcxyz_019", max_size=8))
        value = draw(st.one_of(st.none(), numbers, texts, text_lists))
        get_at(data, path)[key] = value
        what = f"{dotted((*path, key))} = {value!r}"
    else:
        path = draw(st.sampled_from(OUT_OF_RANGE_PATHS))
        new = draw(OUT_OF_RANGE[path])
        set_at(data, path, new)
        what = f"{dotted(path)} = {new!r}"
    return what, dump(data)


# a JSON-like value of any shape, for the generic fuzz
any_value = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-(10**6), 10**6), st.floats(), st.text(max_size=8)),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=3)),
    max_leaves=8,
)

BREAKERS = [
    "[",
    "]",
    "{",
    "}",
    "'",
    '"',
    "\t",
    ": ",
    "- ",
    "&a ",
    "*a",
    "!!int ",
    "%",
    "@",
    "`",
    "|",
    ">",
    ",",
    "\n  ",
    "\n",
    "#",
    "? ",
]


@st.composite
def any_scenarios(draw: Callable[..., Any]) -> tuple[str, str]:
    """(what was done, text) of an arbitrary mutation of hover.yaml: valid or not."""
    kind = draw(st.sampled_from(["value", "truncate", "inject", "cut"]))
    if kind == "value":
        data = copy.deepcopy(BASE)
        path = draw(st.sampled_from([p for p, _ in LEAVES] + [(*c, "zz") for c in CONTAINERS]))
        new = draw(any_value)
        set_at(data, path, new)
        return f"{dotted(path)} = {new!r}", dump(data)
    text = HOVER_TEXT
    i = draw(st.integers(0, len(text)))
    if kind == "truncate":
        return f"truncate at {i}", text[:i]
    if kind == "inject":
        piece = draw(st.sampled_from(BREAKERS))
        return f"insert {piece!r} at {i}", text[:i] + piece + text[i:]
    j = draw(st.integers(i, min(len(text), i + 20)))
    return f"cut {i}:{j}", text[:i] + text[j:]


# -------------------------------------------------------- explicit bad YAML
def _mut(**changes: Any) -> Callable[[], str]:
    """Text of hover.yaml with dotted paths set (value ...) or deleted (value DELETE)."""

    def build() -> str:
        data = copy.deepcopy(BASE)
        for key, value in changes.items():
            path: Path_ = tuple(int(k) if k.isdigit() else k for k in key.split("__"))
            if value is DELETE:
                del_at(data, path)
            else:
                set_at(data, path, value)
        return dump(data)

    return build


DELETE = object()
COUNT_LINE = HOVER_TEXT.splitlines().index("  count: 1") + 1  # 1-based line of agents.count

EXPLICIT: list[tuple[str, Callable[[], str], list[str], str | tuple[str, ...]]] = [
    ("count_zero", _mut(agents__count=0), [], "bad.yaml: agents.count: must be >= 1, got 0"),
    ("count_text", _mut(agents__count="five"), [], "bad.yaml: agents.count: must be a valid integer, got 'five'"),
    ("unknown_top", _mut(colour="red"), [], "bad.yaml: colour: unknown field, got 'red'"),
    ("unknown_nested", _mut(sim__phyics_hz=240), [], "bad.yaml: sim.phyics_hz: unknown field, got 240"),
    ("missing_task", _mut(task=DELETE), [], "bad.yaml: task: is required"),
    ("missing_time_limit", _mut(task__time_limit_s=DELETE), [], "bad.yaml: task.time_limit_s: is required"),
    (
        "unknown_task_kind",
        _mut(task__kind="dance"),
        [],
        "bad.yaml: task.kind: must be one of construction, flock, route, tour, waypoints, got 'dance'",
    ),
    (
        "task_kind_list",
        _mut(task__kind=["waypoints"]),
        [],
        "bad.yaml: task.kind: must be one of construction, flock, route, tour, waypoints, got ['waypoints']",
    ),
    (
        "control_50",
        _mut(sim__control_hz=50),
        [],
        "bad.yaml: sim.control_hz: must divide sim.physics_hz (240) into an integer ratio, got 50",
    ),
    (
        "record_7",
        _mut(sim__record_hz=7),
        [],
        "bad.yaml: sim.record_hz: must divide sim.physics_hz (240) into an integer ratio, got 7",
    ),
    ("velocity_negative", _mut(limits__velocity=-1), [], "bad.yaml: limits.velocity: must be >= 0.001, got -1"),
    (
        "velocity_short",
        _mut(limits__velocity=[1, 2]),
        [],
        "bad.yaml: limits.velocity: must have at least 3 items, got [1, 2]",
    ),
    ("velocity_item", _mut(limits__velocity=[1, 0, 1]), [], "bad.yaml: limits.velocity[1]: must be >= 0.001, got 0"),
    (
        "start_count",
        _mut(agents__count=2, agents__start=[[1.0, 1.0, 0.1]]),
        [],
        "bad.yaml: agents.start: must hold agents.count (2) positions, got 1",
    ),
    (
        "outside_arena",
        _mut(agents__start=[[3.5, 1.0, 0.1]]),
        [],
        ("bad.yaml: agents.start[0]: agent 0 starts at (3.5, 1), outside the arena",),
    ),
    ("layout_outside_arena", _mut(agents__count=400), [], ("bad.yaml: agents.count: ", "outside the arena")),
    (
        "overlapping",
        _mut(agents__count=2, agents__start=[[1.0, 1.0, 0.1], [1.0, 1.02, 0.1]]),
        [],
        ("bad.yaml: agents.start: agents 0 and 1 start overlapping",),
    ),
    (
        "unknown_vehicle",
        _mut(agents__vehicle="quad999"),
        [],
        ("bad.yaml: agents.vehicle: unknown vehicle 'quad999', expected one of", "quad150"),
    ),
    (
        "decreasing_times",
        _mut(task__waypoints__2__t_s=3),
        [],
        "bad.yaml: task.waypoints[2].t_s: waypoint times must not decrease, got 3 after 8",
    ),
    (
        "nan_waypoint",
        _mut(task__waypoints__1__position=[math.nan, 0.0, 1.0]),
        [],
        "bad.yaml: task.waypoints[1].position[0]: must be a finite number, got nan",
    ),
    (
        "unclosed_bracket",
        lambda: HOVER_TEXT.replace("size: [3.0, 3.0]", "size: [3.0, 3.0"),
        [],
        ("bad.yaml: malformed YAML at line ", "expected ',' or ']'"),
    ),
    (
        "unclosed_brace",
        lambda: "sim: {physics_hz: 240\n",
        [],
        ("bad.yaml: malformed YAML at line 2, column 1: expected ',' or '}', but got '<stream end>'",),
    ),
    (
        "tab_indent",
        lambda: HOVER_TEXT.replace("\n  count: 1", "\n\tcount: 1"),
        [],
        (
            f"bad.yaml: malformed YAML at line {COUNT_LINE}, column 1: found character '\\t' that cannot start any token",
        ),
    ),
    (
        "duplicate_key",
        lambda: HOVER_TEXT + "seed: 1\n",
        [],
        ("bad.yaml: malformed YAML at line", "duplicate key 'seed'"),
    ),
    (
        "bad_date",
        lambda: HOVER_TEXT.replace("seed: 0", "seed: 2024-02-30"),
        [],
        ("bad.yaml: seed: cannot read !!timestamp '2024-02-30' (day is out of range for month) (line ",),
    ),
    ("empty", lambda: "", [], "bad.yaml: must be a mapping of scenario sections, got NoneType"),
    (
        "top_level_list",
        lambda: "- name: hover\n- seed: 0\n",
        [],
        "bad.yaml: must be a mapping of scenario sections, got list",
    ),
    ("top_level_scalar", lambda: "hover\n", [], "bad.yaml: must be a mapping of scenario sections, got str"),
    (
        "set_without_equals",
        lambda: HOVER_TEXT,
        ["--set", "agents.count"],
        "--set: expected key.path=value, got 'agents.count'",
    ),
    (
        "set_not_a_number",
        lambda: HOVER_TEXT,
        ["--set", "agents.count=abc"],
        "bad.yaml: agents.count: must be a valid integer, got 'abc'",
    ),
    (
        "set_inside_scalar",
        lambda: HOVER_TEXT,
        ["--set", "sim.physics_hz.x=1"],
        "bad.yaml: sim.physics_hz: must be a mapping to set sim.physics_hz.x inside it, got 240",
    ),
    (
        "set_bad_yaml",
        lambda: HOVER_TEXT,
        ["--set", "agents.count=[1"],
        "--set: agents.count: value is not valid YAML, got '[1'",
    ),
    (
        "set_rate",
        lambda: HOVER_TEXT,
        ["--set", "sim.record_hz=7"],
        "bad.yaml: sim.record_hz: must divide sim.physics_hz (240) into an integer ratio, got 7",
    ),
]


@pytest.mark.parametrize(("build", "extra", "expected"), [c[1:] for c in EXPLICIT], ids=[c[0] for c in EXPLICIT])
def test_explicit_bad_scenarios(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    build: Callable[[], str],
    extra: list[str],
    expected: str | tuple[str, ...],
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(build(), encoding="utf-8")
    code, out, err = check_file(capsys, path, *extra)
    if isinstance(expected, str):
        assert_one_line_error(code, out, err)
        assert err == PREFIX + expected + "\n"
    else:
        assert_one_line_error(code, out, err, *expected)
    assert out == ""


def test_file_that_does_not_exist(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "missing.yaml"
    line = assert_one_line_error(*check_file(capsys, missing))
    assert line == f"{PREFIX}{missing}: file not found"


@pytest.mark.parametrize("name", ["nosuch", "x" * 300])
def test_unknown_bundled_name(capsys: pytest.CaptureFixture[str], name: str) -> None:
    assert_one_line_error(
        *run_cli(capsys, ["check", name]), f"{name}: no scenario file or bundled scenario named", "bundled: "
    )


@pytest.mark.parametrize(
    "argv",
    [
        [],
        ["frobnicate"],
        ["check"],
        ["check", "hover", "--bogus"],
        ["run", "hover", "--seed", "abc"],
        ["run", "hover", "--seed", "-1"],
        ["design", "--vehicle", "nosuch"],
        ["design", "--vehicle", "v" * 300],
    ],
)
def test_usage_errors_are_one_line(capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    assert_one_line_error(*run_cli(capsys, argv))


def test_binary_and_directory_inputs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    binary = tmp_path / "bin.yaml"
    binary.write_bytes(b"\x80\x81\xfe\xff")
    assert_one_line_error(*check_file(capsys, binary), "bin.yaml", "cannot read file")
    folder = tmp_path / "folder.yaml"
    folder.mkdir()
    assert_one_line_error(*check_file(capsys, folder), "folder.yaml: file not found")


# ------------------------------------------------------------- property tests
@FUZZ
@given(case=invalid_scenarios())
def test_guaranteed_invalid_mutations_exit_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], case: tuple[str, str]
) -> None:
    what, text = case
    path = tmp_path / "mutant.yaml"
    path.write_text(text, encoding="utf-8")
    code, out, err = check_file(capsys, path)
    assert code == 2, (what, code, err)
    assert_one_line_error(code, out, err, "mutant.yaml: ")
    assert out == ""


@FUZZ
@given(
    line=st.integers(0, len(HOVER_TEXT.splitlines()) - 1), piece=st.sampled_from(["\t", "'", '"', "[", "{", "]", "}"])
)
def test_broken_yaml_at_a_line_start_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], line: int, piece: str
) -> None:
    assert "'" not in HOVER_TEXT and '"' not in HOVER_TEXT  # a quote is never closed
    lines = HOVER_TEXT.splitlines(keepends=True)
    lines[line] = piece + lines[line]
    path = tmp_path / "broken.yaml"
    path.write_text("".join(lines), encoding="utf-8")
    assert_one_line_error(*check_file(capsys, path), "broken.yaml: malformed YAML at line ")


@FUZZ
@given(case=any_scenarios())
def test_any_mutation_exits_0_or_2_never_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], case: tuple[str, str]
) -> None:
    what, text = case
    path = tmp_path / "fuzz.yaml"
    path.write_text(text, encoding="utf-8")
    code, out, err = check_file(capsys, path)
    assert code in (0, 2), (what, code, err)
    assert "Traceback" not in out + err
    if code == 2:
        assert_one_line_error(code, out, err, "fuzz.yaml")
    else:
        assert err == ""
        assert isinstance(yaml.safe_load(out), dict)


@FUZZ
@given(
    key=st.sampled_from(
        [".".join(map(str, p)) for p, _ in LEAVES if all(isinstance(k, str) for k in p)]
        + ["sim.physics_hz.x", "task.waypoints.0", "zz", "agents.start"]
    ),
    raw=st.one_of(st.text(max_size=15), st.sampled_from(["[1", "{", "'", "null", "-1", "1e999", "[1, 2]", ".nan"])),
)
def test_any_override_exits_0_or_2_never_1(capsys: pytest.CaptureFixture[str], key: str, raw: str) -> None:
    code, out, err = run_cli(capsys, ["check", "hover", "--set", f"{key}={raw}"])
    assert code in (0, 2), (key, raw, code, err)
    if code == 2:
        assert_one_line_error(code, out, err)
    else:
        assert isinstance(yaml.safe_load(out), dict)


# ------------------------------------------------------------- check output
@pytest.mark.parametrize(
    ("argv", "count"),
    [
        (["check", "hover"], 1),
        (["check", "hover", "--set", "agents.count=3"], 3),
        (["check", "hover_swarm", "--set", "agents.count=25"], 25),
    ],
)
def test_check_prints_the_resolved_scenario(capsys: pytest.CaptureFixture[str], argv: list[str], count: int) -> None:
    code, out, err = run_cli(capsys, argv)
    assert (code, err) == (0, "")
    data = yaml.safe_load(out)
    assert isinstance(data, dict)
    assert data["agents"]["count"] == count
    assert data["sim"]["physics_hz"] == 240
    assert data["task"]["kind"] == "waypoints"


def test_check_output_is_a_valid_scenario(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli(capsys, ["check", "hover", "--set", "agents.count=2", "--set", "agents.spacing=1.0"])
    assert code == 0
    resolved = tmp_path / "resolved.yaml"
    resolved.write_text(out)
    code, again, _ = run_cli(capsys, ["check", str(resolved)])
    assert code == 0 and yaml.safe_load(again) == yaml.safe_load(out)


def test_check_quiet(capsys: pytest.CaptureFixture[str]) -> None:
    assert run_cli(capsys, ["check", "hover", "--quiet"]) == (0, "", "")


# ------------------------------------------------- planner and avoidance parameters
STIGMERGY = ["construction", "--set", "planner.name=stigmergy"]
ORCA = ["hover", "--set", "avoidance=orca"]


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        # the case: an unknown parameter
        (
            [*STIGMERGY, "--set", "planner.params.no_such_parameter=1"],
            "construction.yaml: planner.params.no_such_parameter: unknown field, got 1",
        ),
        (
            [*STIGMERGY, "--set", "planner.params.fatigue=fast"],
            "construction.yaml: planner.params.fatigue: must be a valid number, got 'fast'",
        ),
        (
            [*STIGMERGY, "--set", "planner.params.fatigue=true"],
            "construction.yaml: planner.params.fatigue: must be a valid number, got True",
        ),
        (
            [*STIGMERGY, "--set", "planner.params.fatigue=-1"],
            "construction.yaml: planner.params.fatigue: must be >= 0.0, got -1",
        ),
        (
            [*STIGMERGY, "--set", "planner.params.cell_size=.nan"],
            "construction.yaml: planner.params.cell_size: must be a finite number, got nan",
        ),
        (
            [*STIGMERGY, "--set", "planner.params.ties=last"],
            "construction.yaml: planner.params.ties: must be 'random', 'nearest' or 'first', got 'last'",
        ),
        ([*ORCA, "--set", "avoidance_params.horizon=2"], "hover.yaml: avoidance_params.horizon: unknown field, got 2"),
        (
            [*ORCA, "--set", "avoidance_params.max_neighbours=2.5"],
            "hover.yaml: avoidance_params.max_neighbours: must be a valid integer, got 2.5",
        ),
        (
            [*ORCA, "--set", "avoidance_params.max_neighbours=100000"],
            "hover.yaml: avoidance_params.max_neighbours: must be <= 100, got 100000",
        ),
        (
            [*ORCA, "--set", "avoidance_params.responsibility=0"],
            "hover.yaml: avoidance_params.responsibility: must be > 0.0, got 0",
        ),
        (
            ["formation", "--set", "avoidance_params.off_threshold=0.9"],
            "formation.yaml: avoidance_params.off_threshold: must be <= on_threshold (0.55), got 0.9",
        ),
        (
            ["hover", "--set", "avoidance_params.time_horizon=1"],  # the default layer, none, has no parameters
            "hover.yaml: avoidance_params.time_horizon: unknown field, got 1",
        ),
        (["hover", "--set", "planner.params.x=1"], "hover.yaml: planner.params.x: unknown field, got 1"),
        (["hover", "--set", "planner.name=nosuch"], "hover.yaml: planner.name: must be one of "),
        (
            ["hover", "--set", "planner.name=stigmergy"],
            "hover.yaml: planner.name: planner 'stigmergy' does not solve 'waypoints' tasks (it solves construction)",
        ),
        (["hover", "--set", "avoidance=nosuch"], "hover.yaml: avoidance: must be one of braitenberg, none, orca"),
    ],
)
def test_check_refuses_bad_planner_and_avoidance_parameters(
    capsys: pytest.CaptureFixture[str], argv: list[str], expected: str
) -> None:
    assert_one_line_error(*run_cli(capsys, ["check", *argv]), PREFIX + expected)
    # run refuses the same, before anything is simulated
    assert_one_line_error(*run_cli(capsys, ["run", *argv, "--out", "/nonexistent/never"]), PREFIX + expected)


def test_check_prints_every_parameter_resolved(capsys: pytest.CaptureFixture[str]) -> None:
    from pybullet_swarm.planning.orca import OrcaParams
    from pybullet_swarm.planning.shortest_path import ShortestPathParams
    from pybullet_swarm.planning.stigmergy import StigmergyParams

    code, out, err = run_cli(
        capsys,
        [
            "check",
            "construction",
            "--set",
            "planner.name=stigmergy",
            "--set",
            "planner.params.fatigue=0.5",
            "--set",
            "avoidance=orca",
        ],
    )
    assert (code, err) == (0, "")
    data = yaml.safe_load(out)
    assert data["planner"] == {
        "name": "stigmergy",
        "params": {**StigmergyParams().model_dump(mode="json"), "fatigue": 0.5},
    }
    assert data["avoidance"] == "orca" and data["avoidance_params"] == OrcaParams().model_dump(mode="json")
    code, out, _ = run_cli(capsys, ["check", "construction"])  # no planner named: the task's default, resolved
    planner = yaml.safe_load(out)["planner"]
    assert planner == {"name": "shortest_path", "params": ShortestPathParams().model_dump(mode="json")}
    assert {k: planner["params"][k] for k in ("preset", "arrive_tol", "release_clearance", "altitude_step")} == {
        "preset": None,
        "arrive_tol": 0.01,
        "release_clearance": 0.004,
        "altitude_step": 0.2,
    }


# ------------------------------------------------------------ real processes
def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pybullet_swarm.cli.main", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (("run", "hover", "--set", "agents.count=0"), "hover.yaml: agents.count: must be >= 1, got 0"),
        (("run", "nosuch"), "nosuch: no scenario file or bundled scenario named 'nosuch'"),
    ],
)
def test_exit_code_of_the_real_process(tmp_path: Path, args: tuple[str, ...], expected: str) -> None:
    proc = _cli(*args, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith(PREFIX + expected)
    assert not (tmp_path / "runs").exists()  # nothing was run


def test_check_refuses_a_bidi_override_in_the_name(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = tmp_path / "spoof.yaml"
    data = copy.deepcopy(BASE)
    data["name"] = "run\u202egpj.exe"
    path.write_text(yaml.safe_dump(data, allow_unicode=True), encoding="utf-8")
    line = assert_one_line_error(*check_file(capsys, path), "spoof.yaml: name: ", "U+202E")
    assert "\u202e" not in line


def test_a_reader_that_stops_early_gets_no_error(tmp_path):
    """``pybullet-swarm benchmark ... --dry-run | head -1``: the command stops quietly when its reader closes the
    pipe. Its 189 kB of lines do not fit the pipe's buffer (64 kB), so the reader always leaves first."""
    args = ["benchmark", "construction", "--split", "holdout", "--dry-run", "--seeds", "100", "--quiet"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "pybullet_swarm.cli.main", *args],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        bufsize=0,
    )
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.read(10)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 0, err
    assert "error" not in err, err
