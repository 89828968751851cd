"""Benchmark suite files: layouts, planners, avoidance layers and seeds of a task, in two splits.

A suite file (``scenarios/suites/construction.yaml``) is versioned and names, per split, the
layouts and seeds to run every planner x avoidance layer on::

    suite: construction        # name (the default output directory says it)
    version: 1                 # bump when the suite changes: results of two versions do not pair
    planners: [shortest_path, stigmergy, layered_stigmergy]
    avoidance: [orca]
    set: {}                    # scenario overrides applied to every run (key.path: value)
    splits:
      dev:                     # to look at while designing
        seeds: {start: 0, count: 50}
        layouts:
          - {name: thesis, scenario: construction}           # a scenario file (or a bundled name)
          - name: tower5                                     # a placed structure, composed into a scenario
            structure: {shape: tower, origin: [2.6, 0.5], height: 5}
            agents: 5
            arena: [3.0, 1.0]
      holdout:                 # generated layouts and seeds never looked at while designing
        seeds: {start: 1000, count: 2}
        generator: {agents: [3, 20], max_arena: [6.0, 4.0]}  # defaults of the drawn layouts
        layouts:
          - {name: h1000, generator_seed: 1000, shape: wall}   # drawn as `pybullet-swarm layout` draws
          - {name: h1002, generator_seed: 1002, shape: ring, depots: 2}

A split may also name its own ``planners`` and ``avoidance`` (they replace the suite's). Seeds and
generator seeds from ``HOLDOUT_SEED`` up belong to the holdout split: a dev split that uses one,
or a holdout split that uses a lower one or a layout that is not drawn by the generator, is refused.

Bad files are refused with one line naming the file, the field and the expectation.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import pydantic
from pydantic import Field

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.validation import check_plain, read_yaml, validate

SPLITS = ("dev", "holdout")
HOLDOUT_SEED = 1000
"""Seeds (simulation and generator) from this one up are the holdout split's."""
MAX_SEEDS = 100_000
Name = Annotated[str, Field(min_length=1, max_length=80, pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")]
Seed = Annotated[int, Field(ge=0, le=2**31 - 1)]
AgentCount = Annotated[int, Field(ge=1, le=20)]
Size = Annotated[float, Field(gt=0.0, le=100.0)]


class _Model(pydantic.BaseModel):
    model_config = pydantic.ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


class SeedRange(_Model):
    """Seeds ``start .. start + count - 1``."""

    start: Seed = 0
    count: Annotated[int, Field(ge=1, le=MAX_SEEDS)]


class Generator(_Model):
    """What the layout generator (``experiment.layouts.random_layout``) is told; unset: drawn."""

    agents: AgentCount | Annotated[list[AgentCount], Field(min_length=2, max_length=2)] | None = None
    arena: Annotated[list[Size], Field(min_length=2, max_length=2)] | None = None
    max_arena: Annotated[list[Size], Field(min_length=2, max_length=2)] | None = None
    shape: str | None = None
    depots: Literal[1, 2] | None = None


class ScenarioLayout(_Model):
    """A scenario file (relative to the suite file) or a bundled scenario's name."""

    name: Name
    scenario: Annotated[str, Field(min_length=1, max_length=500)]
    description: str = ""


class ComposedLayout(_Model):
    """A placed structure (as a scenario's ``task.structure``) composed into a scenario
    (``experiment.layouts.compose_layout``: the swarm at the near end, a depot grid between)."""

    name: Name
    structure: Any
    agents: AgentCount
    arena: Annotated[list[Size], Field(min_length=2, max_length=2)]
    depots: Literal[1, 2] = 1
    description: str = ""


class GeneratedLayout(Generator):
    """A layout drawn by the generator from ``generator_seed`` (the split's ``generator`` gives defaults)."""

    name: Name
    generator_seed: Seed


Layout = Union[ScenarioLayout, ComposedLayout, GeneratedLayout]
_KINDS: tuple[tuple[str, type[_Model]], ...] = (
    ("scenario", ScenarioLayout),
    ("structure", ComposedLayout),
    ("generator_seed", GeneratedLayout),
)


class _Split(_Model):
    seeds: SeedRange | Annotated[list[Seed], Field(min_length=1, max_length=MAX_SEEDS)]
    planners: Annotated[list[Name], Field(min_length=1)] | None = None
    avoidance: Annotated[list[Name], Field(min_length=1)] | None = None
    generator: Generator = Generator()
    layouts: Annotated[list[dict[str, Any]], Field(min_length=1, max_length=1000)]


class _SuiteFile(_Model):
    suite: Name
    version: Annotated[int, Field(ge=1)]
    description: str = ""
    planners: Annotated[list[Name], Field(min_length=1)]
    avoidance: Annotated[list[Name], Field(min_length=1)] = ["orca"]
    set: dict[str, Any] = {}
    splits: dict[Literal["dev", "holdout"], _Split]


@dataclasses.dataclass(frozen=True)
class Split:
    """One split of a suite, validated.

    Attributes:
        name: ``dev`` or ``holdout``.
        seeds: simulation seeds of every configuration.
        planners: planner names.
        avoidance: avoidance layer names.
        generator: defaults of the generated layouts.
        layouts: the layouts, in file order.
    """

    name: str
    seeds: tuple[int, ...]
    planners: tuple[str, ...]
    avoidance: tuple[str, ...]
    generator: Generator
    layouts: tuple[Layout, ...]


@dataclasses.dataclass(frozen=True)
class Suite:
    """A validated suite file.

    Attributes:
        path: the file.
        name: the suite's name.
        version: its version.
        description: one line on what it measures.
        overrides: scenario overrides of every run (``key.path -> value``).
        splits: ``dev`` and ``holdout``.
        digest: SHA-256 (12 hex digits) of the file's text.
    """

    path: Path
    name: str
    version: int
    description: str
    overrides: dict[str, Any]
    splits: dict[str, Split]
    digest: str

    def split(self, name: str) -> Split:
        """The split ``name``; ``ConfigError`` for one the suite does not have."""
        if name not in self.splits:
            raise ConfigError(f"must be one of {', '.join(self.splits)}, got {name!r}", source="--split")
        return self.splits[name]

    def layout_data(self, layout: Layout, split: Split) -> dict[str, Any]:
        """Scenario data (as a file holds it, not validated) of one layout of ``split``."""
        return layout_data(layout, split.generator, self.path.parent, source=self.path.name)


def _layout(item: Any, field: str, source: str) -> Layout:
    if not isinstance(item, dict):
        raise ConfigError(f"must be a mapping, got {type(item).__name__}", source=source, field=field)
    kinds = [key for key, _ in _KINDS if key in item]
    if len(kinds) != 1:
        got = f"got {' and '.join(kinds)}" if kinds else f"got keys {', '.join(map(str, item)) or 'none'}"
        raise ConfigError(
            f"a layout names exactly one of scenario (a scenario file), structure (a placed structure) or "
            f"generator_seed (a drawn layout); {got}",
            source=source,
            field=field,
        )
    model = dict(_KINDS)[kinds[0]]
    return validate(model, item, source=source, prefix=field)  # type: ignore[return-value]


def _check_generator(g: Generator, field: str, source: str) -> None:
    from pybullet_swarm.experiment.layouts import SHAPES

    if g.shape is not None and g.shape not in SHAPES:
        raise ConfigError(f"must be one of {', '.join(SHAPES)}, got {g.shape!r}", source=source, field=f"{field}.shape")
    if isinstance(g.agents, list) and g.agents[0] > g.agents[1]:
        raise ConfigError(
            f"must be a range [lo, hi] with lo <= hi, got {g.agents}", source=source, field=f"{field}.agents"
        )
    if g.max_arena is not None and not (2.0 <= g.max_arena[0] <= 20.0 and 1.0 <= g.max_arena[1] <= 10.0):
        raise ConfigError(
            f"must be [Lx, Ly] m within 2..20 x 1..10, got {g.max_arena}", source=source, field=f"{field}.max_arena"
        )


def _split(name: str, raw: _Split, f: _SuiteFile, source: str) -> Split:
    where = f"splits.{name}"
    seeds = (
        tuple(range(raw.seeds.start, raw.seeds.start + raw.seeds.count))
        if isinstance(raw.seeds, SeedRange)
        else tuple(raw.seeds)
    )
    if len(set(seeds)) != len(seeds):
        raise ConfigError("must not repeat a seed", source=source, field=f"{where}.seeds")
    _check_generator(raw.generator, f"{where}.generator", source)
    layouts = tuple(_layout(item, f"{where}.layouts[{i}]", source) for i, item in enumerate(raw.layouts))
    seen: set[str] = set()
    for i, lay in enumerate(layouts):
        field = f"{where}.layouts[{i}]"
        if lay.name in seen:
            raise ConfigError(f"repeats the layout name {lay.name!r}", source=source, field=f"{field}.name")
        seen.add(lay.name)
        if isinstance(lay, GeneratedLayout):
            _check_generator(lay, field, source)
    holdout = name == "holdout"
    low = [s for s in seeds if (s >= HOLDOUT_SEED) != holdout]
    if low:
        want = f">= {HOLDOUT_SEED}" if holdout else f"< {HOLDOUT_SEED} (seeds from {HOLDOUT_SEED} up are the holdout's)"
        raise ConfigError(f"must all be {want}, got {low[0]}", source=source, field=f"{where}.seeds")
    for i, lay in enumerate(layouts):
        field = f"{where}.layouts[{i}]"
        if holdout and not isinstance(lay, GeneratedLayout):
            raise ConfigError(
                "holdout layouts are drawn by the generator (generator_seed), never placed by hand",
                source=source,
                field=field,
            )
        if isinstance(lay, GeneratedLayout) and (lay.generator_seed >= HOLDOUT_SEED) != holdout:
            want = f">= {HOLDOUT_SEED}" if holdout else f"< {HOLDOUT_SEED} (from {HOLDOUT_SEED} up: the holdout's)"
            raise ConfigError(
                f"must be {want}, got {lay.generator_seed}", source=source, field=f"{field}.generator_seed"
            )
    return Split(
        name=name,
        seeds=seeds,
        planners=tuple(raw.planners or f.planners),
        avoidance=tuple(raw.avoidance or f.avoidance),
        generator=raw.generator,
        layouts=layouts,
    )


def load_suite(path: str | Path) -> Suite:
    """Read and validate a suite file (a path, or the name of a bundled suite: ``construction``).

    Raises:
        ConfigError: one line naming the file, the field and the expectation.
    """
    p = resolve_suite_path(path)
    source = p.name
    data = read_yaml(p)
    if not isinstance(data, dict):
        raise ConfigError(
            f"must be a mapping (suite, version, planners, splits), got {type(data).__name__}", source=source
        )
    check_plain(data, source=source)
    f = validate(_SuiteFile, data, source=source)
    missing = [s for s in SPLITS if s not in f.splits]
    if missing:
        raise ConfigError(
            f"must hold both splits, dev and holdout; missing {', '.join(missing)}", source=source, field="splits"
        )
    for key in f.set:
        if not key or any(not part for part in str(key).split(".")):
            raise ConfigError(f"expected key.path names, got {key!r}", source=source, field="set")
    splits = {name: _split(name, f.splits[name], f, source) for name in SPLITS}  # type: ignore[index]
    return Suite(
        path=p.resolve(),
        name=f.suite,
        version=f.version,
        description=f.description,
        overrides=dict(f.set),
        splits=splits,
        digest=hashlib.sha256(p.read_bytes()).hexdigest()[:12],
    )


def suites_dir() -> Path:
    """The bundled suites (``scenarios/suites``, shipped with the package as the scenarios are)."""
    from pybullet_swarm.resources import scenarios_dir

    return scenarios_dir() / "suites"


def resolve_suite_path(path: str | Path) -> Path:
    """A suite file from a path or a bundled suite's name."""
    p = Path(path)
    if p.is_file():
        return p
    bundled = suites_dir() / f"{p.name}.yaml"
    if p.suffix == "" and bundled.is_file():
        return bundled
    raise ConfigError("no suite file (nor a bundled suite of that name in scenarios/suites)", source=str(path))


def layout_data(layout: Layout, defaults: Generator, base_dir: Path, *, source: str) -> dict[str, Any]:
    """Scenario data (as a file holds it, not validated) of a suite layout.

    Args:
        layout: the layout entry.
        defaults: the split's generator defaults (a generated layout's own values win).
        base_dir: where a ``scenario`` path is looked up first (the suite file's directory).
        source: the suite file's name, for errors.
    """
    from pybullet_swarm.experiment.layouts import compose_layout, random_layout
    from pybullet_swarm.experiment.scenario import resolve_scenario_path

    if isinstance(layout, ScenarioLayout):
        local = base_dir / layout.scenario
        try:
            data = read_yaml(local if local.is_file() else resolve_scenario_path(layout.scenario))
        except ConfigError as exc:
            raise ConfigError(
                f"{exc.detail} (a scenario file relative to the suite, or a bundled scenario's name)",
                source=source,
                field=f"layout {layout.name}.scenario",
            ) from None
        if not isinstance(data, dict):
            raise ConfigError("is not a scenario (a mapping of sections)", source=source, field=f"layout {layout.name}")
        data = copy.deepcopy(data)
    elif isinstance(layout, ComposedLayout):
        data = compose_layout(
            copy.deepcopy(layout.structure),
            agents=layout.agents,
            arena=layout.arena,
            name=layout.name,
            description=layout.description,
            depots=layout.depots,
        )
    else:
        merged = {**defaults.model_dump(exclude_none=True), **layout.model_dump(exclude_none=True)}
        agents = merged.get("agents")
        kwargs: dict[str, Any] = {
            "agents": tuple(agents) if isinstance(agents, list) else agents,
            "arena": merged.get("arena"),
            "shape": merged.get("shape"),
            "depots": merged.get("depots", 1),
        }
        if merged.get("max_arena") is not None:
            kwargs["max_arena"] = tuple(merged["max_arena"])
        try:
            data = random_layout(layout.generator_seed, **kwargs)
        except ConfigError as exc:
            raise ConfigError(exc.detail, source=source, field=f"layout {layout.name}") from None
    data["name"] = layout.name
    description = getattr(layout, "description", "")
    if description:
        data["description"] = description
    return data
