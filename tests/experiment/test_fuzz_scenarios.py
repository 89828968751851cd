"""Property-based fuzz of every bundled scenario: ``check`` answers 0 or 2 in one line, and what it
accepts a short ``run`` neither refuses nor fails on.

Each example mutates one bundled scenario one to three times: a value of the wrong type, NaN or
infinity, a huge or tiny number, a scaled number, a plausible number (-1000 .. 3000), an unknown
field, a deleted field, shared YAML aliases, an alias bomb, a recursive alias or a YAML tag. Then

- ``pybullet-swarm check`` exits 0, or 2 with exactly one ``pybullet-swarm: error:`` line naming
  the file; no warning is emitted either way;
- when ``check`` accepts, the scenario with its time limit clamped to ``RUN_SECONDS`` runs to an
  exit status without raising (no ``ConfigError``: what ``check`` accepts, ``run`` accepts; no
  other exception: exit 1 is for bugs) and without warnings.

The suite runs a small, fixed set of examples (a fixed seed); ``scripts/fuzz_scenarios.py`` runs
many more, at random, and prints the outcomes by mutation.

Plug-in parameters (``planner``, ``planner.params``, ``avoidance``, ``avoidance_params``) are
validated at load against each plug-in's model: besides the generic mutations, ``PLUGIN_MUTATIONS``
picks a registered planner or avoidance layer and sets one of its parameters to a value at, inside
or beyond the bounds of its model (a new kind of plug-in adds its mutation there).
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import math
import tempfile
import warnings
from pathlib import Path
from typing import Any, Callable

import pytest
import yaml
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st

from pybullet_swarm.cli.main import main
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.resources import bundled_scenarios, scenarios_dir

PREFIX = "pybullet-swarm: error: "
RUN_SECONDS = 0.3  # s, time limit of the short run of an accepted mutant
FILE = "mutant.yaml"

Path_ = tuple[Any, ...]
SCENARIOS: dict[str, dict[str, Any]] = {
    name: yaml.safe_load((scenarios_dir() / f"{name}.yaml").read_text(encoding="utf-8")) for name in bundled_scenarios()
}

#: Sections of plug-in parameters. The generic mutations (types, NaN, huge numbers ...) reach
#: them like any other section; ``PLUGIN_MUTATIONS`` adds mutations that know each plug-in's model.
PLUGIN_SECTIONS: tuple[Path_, ...] = (("planner",), ("avoidance",), ("avoidance_params",))
#: Generic mutations also touch the plug-in sections (their parameters are validated at load).
MUTATE_PLUGIN_SECTIONS = True


def _planner_names() -> list[str]:
    from pybullet_swarm.planning.registry import planners

    return sorted(planners())


def _avoidance_names() -> list[str]:
    from pybullet_swarm.planning.registry import avoidance_layers

    return sorted(avoidance_layers())


def _edge_values(info: Any) -> st.SearchStrategy[Any]:
    """Values at, just inside and just outside a parameter's range, plus its default and junk."""
    values: list[Any] = [info.default, None, "x", True, [1.0], math.nan, -1, 0, 1e6]
    for bound in (info.low, info.high):
        if bound is not None:
            values += [bound, bound * (1 + 1e-9) + 1e-12, bound * (1 - 1e-9) - 1e-12, bound * 10, bound / 10]
    if info.integer:
        values += [int(v) for v in values if is_number(v) and math.isfinite(v) and abs(v) < 1e12]
    return st.sampled_from(values)


def _mutate_planner(draw: Callable[..., Any], data: dict[str, Any]) -> str:
    """Choose a registered planner (fit for the task or not) and set one of its parameters to an edge value."""
    from pybullet_swarm.planning.params import describe
    from pybullet_swarm.planning.registry import planners

    name = draw(st.sampled_from(_planner_names()))
    infos = describe(planners()[name].params)
    planner = data.setdefault("planner", {})
    if not isinstance(planner, dict):
        return "planner is not a mapping"
    if planner.get("name") != name or not isinstance(planner.get("params"), dict):
        planner["params"] = {}
    planner["name"] = name
    if not infos:
        return f"planner.name = {name}"
    info = draw(st.sampled_from(infos))
    value = draw(_edge_values(info))
    planner.setdefault("params", {})[info.name] = value
    return f"planner {name}: params.{info.name} = {value!r}"


def _mutate_avoidance(draw: Callable[..., Any], data: dict[str, Any]) -> str:
    """Choose a registered avoidance layer and set one of its parameters to an edge value."""
    from pybullet_swarm.planning.params import describe
    from pybullet_swarm.planning.registry import avoidance_layers

    name = draw(st.sampled_from(_avoidance_names()))
    infos = describe(avoidance_layers()[name].params)
    if data.get("avoidance") != name or not isinstance(data.get("avoidance_params"), dict):
        data["avoidance_params"] = {}
    data["avoidance"] = name
    if not infos:
        return f"avoidance = {name}"
    info = draw(st.sampled_from(infos))
    value = draw(_edge_values(info))
    data["avoidance_params"][info.name] = value
    return f"avoidance {name}: {info.name} = {value!r}"


#: Mutations of plug-in parameters: ``mutation(draw, data) -> description`` edits ``data`` in place.
#: A new kind of plug-in adds its own here.
PLUGIN_MUTATIONS: list[Callable[[Callable[..., Any], dict[str, Any]], str]] = [_mutate_planner, _mutate_avoidance]


# ------------------------------------------------------------------ helpers
def walk(node: Any, path: Path_ = (), seen: set[int] | None = None) -> list[tuple[Path_, Any]]:
    """Every (path, value) below ``node``, containers included, root excluded; a container met again
    (shared by an earlier alias mutation, or an alias bomb) is listed but not entered twice."""
    seen = set() if seen is None else seen
    out: list[tuple[Path_, Any]] = []
    if id(node) in seen:
        return out
    seen.add(id(node))
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        out.append(((*path, k), v))
        out.extend(walk(v, (*path, k), seen))
    return out


def plugin_paths(path: Path_) -> bool:
    """True for a path inside a plug-in section that the generic mutations leave alone."""
    return not MUTATE_PLUGIN_SECTIONS and any(path[: len(p)] == p for p in PLUGIN_SECTIONS)


def get_at(data: Any, path: Path_) -> Any:
    for k in path:
        data = data[k]
    return data


def set_at(data: Any, path: Path_, value: Any) -> None:
    get_at(data, path[:-1])[path[-1]] = value


def dotted(path: Path_) -> str:
    out = ""
    for k in path:
        out += f"[{k}]" if isinstance(k, int) else ("." if out else "") + str(k)
    return out


def is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def nested_bomb(depth: int, width: int) -> list[Any]:
    """A list of ``width`` copies of a list of ... ``depth`` levels: dumped with anchors, tiny as text."""
    node: list[Any] = ["lol"] * width
    for _ in range(depth - 1):
        node = [node] * width
    return node


# --------------------------------------------------------------- mutations
WRONG_TYPES = st.one_of(
    st.text(max_size=8),
    st.booleans(),
    st.none(),
    st.lists(st.text(max_size=4), max_size=3),
    st.dictionaries(st.text(max_size=4), st.integers(), min_size=1, max_size=2),
)
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf])
HUGE = st.sampled_from([1e308, -1e308, 1e30, -1e30, 10**30, -(10**30), 2**63, 1e15, 1e6, -1e6, 10**4000])
TINY = st.sampled_from([1e-300, -1e-300, 5e-324, 1e-13, 1e-12, 1e-9, 0, 0.0, -0.0, 1, -1])
FACTORS = st.sampled_from([-1.0, 0.5, 2.0, 10.0, 100.0, 1000.0])
TAGS = st.sampled_from(
    [
        "!!int abc",
        "!!float x",
        "!!binary AAAA",
        "!!python/object:os.system ls",
        "!!timestamp 1",
        "!!set {a}",
        "!!omap [a: 1]",
        "!!str 1",
        "!!null ''",
        "!!bool maybe",
    ]
)
NEAR = st.one_of(st.floats(-1e3, 1e3, allow_nan=False), st.integers(-10, 3000), st.floats(0, 2, allow_nan=False))
KINDS = (
    "type",
    "nonfinite",
    "huge",
    "tiny",
    "scale",
    "near",
    "unknown",
    "delete",
    "alias_share",
    "alias_bomb",
    "alias_cycle",
    "tag",
    "plugin",
)


def _mutate_once(
    draw: Callable[..., Any], data: dict[str, Any], tags: list[str], kinds: tuple[str, ...] = KINDS
) -> tuple[str, str]:
    """Apply one drawn mutation (of one of ``kinds``) to ``data`` in place; returns (kind, what was done).

    A YAML tag is written as a placeholder ``@@TAGk@@`` whose text ``tags[k]`` replaces it after dumping.
    """
    kind = draw(st.sampled_from([k for k in kinds if k != "plugin" or PLUGIN_MUTATIONS]))
    everything = [(p, v) for p, v in walk(data) if not plugin_paths(p)]
    leaves = [(p, v) for p, v in everything if not isinstance(v, (dict, list))]
    numbers = [(p, v) for p, v in leaves if is_number(v)] or leaves
    mappings = [()] + [p for p, v in everything if isinstance(v, dict)]
    containers = [p for p, v in everything if isinstance(v, (dict, list))]
    if not leaves or kind == "unknown":
        path = draw(st.sampled_from(mappings))
        key = "zz_" + draw(st.text(alphabet="abcxyz_019", max_size=6))
        get_at(data, path)[key] = draw(st.one_of(st.none(), st.integers(), st.text(max_size=6)))
        return "unknown", f"add {dotted((*path, key))}"
    if kind == "plugin":
        return kind, draw(st.sampled_from(PLUGIN_MUTATIONS))(draw, data)
    if kind == "type":
        path, _ = draw(st.sampled_from(leaves))
        new = draw(WRONG_TYPES)
        set_at(data, path, new)
        return kind, f"{dotted(path)} = {new!r}"
    if kind in ("nonfinite", "huge", "tiny", "scale", "near"):
        path, old = draw(st.sampled_from(numbers))
        if kind == "scale" and is_number(old):
            new = old * draw(FACTORS)
        else:
            new = draw({"nonfinite": NON_FINITE, "huge": HUGE, "tiny": TINY, "scale": TINY, "near": NEAR}[kind])
        set_at(data, path, new)
        return kind, f"{dotted(path)} = {new!r}"
    if kind == "delete":
        path = draw(st.sampled_from([p for p in (p for p, _ in everything) if isinstance(p[-1], str)]))
        del get_at(data, path[:-1])[path[-1]]
        return kind, f"del {dotted(path)}"
    if kind == "alias_share":
        target = draw(st.sampled_from([p for p, _ in everything]))
        source = draw(st.sampled_from(containers)) if containers else target
        if target[: len(source)] == source:
            return kind, f"{dotted(target)} left (inside {dotted(source)})"
        set_at(data, target, get_at(data, source))  # the same object twice: dumped as &anchor / *alias
        return kind, f"{dotted(target)} = *{dotted(source)}"
    if kind == "alias_bomb":
        path = draw(st.sampled_from([p for p, _ in everything]))
        depth = draw(st.integers(2, 12))
        set_at(data, path, nested_bomb(depth, 9))
        return kind, f"{dotted(path)} = 9^{depth} alias bomb"
    if kind == "alias_cycle":
        path = draw(st.sampled_from([p for p, _ in everything]))
        loop: list[Any] = [1]
        loop.append(loop)
        set_at(data, path, loop)
        return kind, f"{dotted(path)} = recursive alias"
    path, _ = draw(st.sampled_from(leaves))  # a YAML tag where a value was
    tags.append(draw(TAGS))
    set_at(data, path, f"@@TAG{len(tags) - 1}@@")
    return "tag", f"{dotted(path)} = {tags[-1]}"


@st.composite
def mutants(draw: Callable[..., Any], max_mutations: int = 1, kinds: tuple[str, ...] = KINDS) -> tuple[str, str, str]:
    """(scenario name, ``name: kind: what was done``, YAML text) of 1 .. ``max_mutations`` mutations
    (of ``kinds``) of one bundled scenario (kind ``multi`` for several)."""
    name = draw(st.sampled_from(sorted(SCENARIOS)))
    data = copy.deepcopy(SCENARIOS[name])
    tags: list[str] = []
    done = [_mutate_once(draw, data, tags, kinds) for _ in range(draw(st.integers(1, max_mutations)))]
    text = yaml.safe_dump(data, sort_keys=False, allow_unicode=True)
    for k, tag in enumerate(tags):
        text = text.replace(f"'@@TAG{k}@@'", tag).replace(f"@@TAG{k}@@", tag)
    kind = done[0][0] if len(done) == 1 else "multi"
    return name, f"{name}: {kind}: {'; '.join(w for _, w in done)}", text


# ------------------------------------------------------------------ outcome
@dataclasses.dataclass
class Outcome:
    """What one mutant did: ``check`` exit code and stderr, then the short run's result."""

    code: int
    err: str
    out: str
    check_warnings: list[str]
    run: str | None = None  # exit status of the short run, or None when not run
    run_error: BaseException | None = None
    run_warnings: list[str] = dataclasses.field(default_factory=list)


def _visible(caught: list[warnings.WarningMessage]) -> list[str]:
    """Warnings a user would see (deprecations are for developers)."""
    return [
        f"{w.category.__name__}: {w.message}"
        for w in caught
        if not issubclass(w.category, (DeprecationWarning, PendingDeprecationWarning))
    ]


def try_mutant(text: str, workdir: Path, *, plots: bool = False) -> Outcome:
    """``check`` the mutant in-process; when accepted, run it for ``RUN_SECONDS``."""
    from pybullet_swarm.experiment.runner import run
    from pybullet_swarm.experiment.scenario import load_scenario

    path = workdir / FILE
    path.write_text(text, encoding="utf-8")
    # real files (with a file descriptor), as a terminal or a pipe would be: what Bullet's C code
    # prints is silenced at the descriptor, as in the command
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        with (
            warnings.catch_warnings(record=True) as caught,
            contextlib.redirect_stdout(out),
            contextlib.redirect_stderr(err),
        ):
            warnings.simplefilter("always")
            code = main(["check", str(path), "--quiet"])
        out.seek(0)
        err.seek(0)
        outcome = Outcome(code, err.read(), out.read(), _visible(caught))
    if code != 0:
        return outcome
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            scenario = load_scenario(path)
            limit = min(float(scenario.task.time_limit_s), RUN_SECONDS)
            scenario = dataclasses.replace(scenario, task=scenario.task.model_copy(update={"time_limit_s": limit}))
            result = run(scenario, out=workdir / "run", plots=plots, quiet=True)
            outcome.run = result.exit_status.value
        except Exception as exc:  # noqa: BLE001 - classified by the caller
            outcome.run_error = exc
    outcome.run_warnings = _visible(caught)
    return outcome


def assert_property(what: str, o: Outcome) -> None:
    """The fuzz property (see the module docstring)."""
    assert o.code in (0, 2), (what, o.code, o.err)
    assert not o.check_warnings, (what, o.check_warnings)
    if o.code == 2:
        assert o.err.count("\n") == 1 and o.err.startswith(PREFIX) and FILE in o.err, (what, o.err)
        assert o.out == "", (what, o.out)
        return
    assert o.err == "", (what, o.err)
    assert not isinstance(o.run_error, ConfigError), (what, "check accepted what run refuses", o.run_error)
    assert o.run_error is None, (what, repr(o.run_error))
    assert not o.run_warnings, (what, o.run_warnings)


# a fixed seed: the same examples on every run (no flaky test), drawn at random rather than
# simplest-first (derandomize=True keeps to the first values of every choice)
FUZZ = settings(
    max_examples=60,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


#: Mutations that often leave a valid scenario: the short run is exercised mostly by these.
PLAUSIBLE = ("near", "scale", "tiny", "delete", "plugin", "alias_share")


@seed(23)
@FUZZ
@given(case=mutants(max_mutations=3))
def test_mutated_bundled_scenarios_check_in_one_line_and_run(
    tmp_path_factory: pytest.TempPathFactory, case: tuple[str, str, str]
) -> None:
    _, what, text = case
    assert_property(what, try_mutant(text, tmp_path_factory.mktemp("fuzz")))


@seed(2)
@settings(FUZZ, max_examples=40)
@given(case=mutants(kinds=PLAUSIBLE))
def test_plausible_mutations_that_check_accepts_run(
    tmp_path_factory: pytest.TempPathFactory, case: tuple[str, str, str]
) -> None:
    _, what, text = case
    assert_property(what, try_mutant(text, tmp_path_factory.mktemp("fuzz")))


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_every_bundled_scenario_passes_unmutated(tmp_path: Path, name: str) -> None:
    text = (scenarios_dir() / f"{name}.yaml").read_text(encoding="utf-8")
    o = try_mutant(text, tmp_path)
    assert o.code == 0 and o.run is not None, (o.err, o.run_error)
    assert_property(name, o)


def test_every_kind_of_mutation_is_drawn() -> None:
    seen: set[str] = set()

    @settings(
        max_examples=300,
        database=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.data_too_large, HealthCheck.too_slow],
    )
    @given(case=mutants())
    def collect(case: tuple[str, str, str]) -> None:
        seen.add(case[1].split(": ")[1])

    collect()
    assert seen == set(KINDS)
