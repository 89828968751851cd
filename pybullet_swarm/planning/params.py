"""Parameter models of planners and avoidance layers: typed, ranged and described.

Every planner and avoidance layer declares its parameters as a subclass of ``Params`` (a frozen,
strict pydantic model: unknown names, wrong types, NaN and infinity are refused). Each field has
a default, a one-line ``description`` and a range (``Field(ge=..., le=...)``) that is physical
(a length is positive) and computational (a value that sizes an array keeps it small).

The scenario validates ``planner.params`` and ``avoidance_params`` against these models when it
is loaded; the tuner reads the ranges from them (``describe``); ``pybullet-swarm list`` prints
them. Checks that need the scenario (the arena's size for a grid, the number of agents for an
adjacency matrix) go in ``check_for``, called at load with a ``PlanContext``; checks that need the
task's layout (altitudes derived from a structure's height) go in ``check_layout``, called at load
with the ``TaskInfo`` the agents will be told.

A model may offer **presets**: named sets of values (``PRESETS``), chosen with its ``preset``
field (``planner.params.preset: thesis``). The preset's values are defaults: a parameter given
explicitly beside the preset keeps its given value (``{preset: thesis, claims: true}`` is the
thesis preset with neighbour claims switched back on). A preset is refused at load by a model
that has none. The validated model holds ``preset`` and every value, so a resolved scenario
names both (and reproduces the run: its explicit values equal the preset's).
"""

from __future__ import annotations

import dataclasses
import enum
import types
import typing
from typing import Any, ClassVar, Literal, Mapping, Union

import annotated_types
import pydantic

from pybullet_swarm.memory import DEFAULT_BUDGET, ENV_VAR, format_bytes

if typing.TYPE_CHECKING:  # pragma: no cover
    from pybullet_swarm.planning.base import TaskInfo

MEMORY_BUDGET_BYTES = DEFAULT_BUDGET
"""bytes: largest memory a plug-in's arrays (a pheromone grid, a memory of echoes) may need by
default; a configuration that needs more is refused at load, saying how much it would need. The
scenario passes the configured budget (``pybullet_swarm.memory.memory_budget``) in ``PlanContext``."""


class Preset(str, enum.Enum):
    """Named sets of parameter values (a model's ``preset`` field)."""

    THESIS = "thesis"  # the thesis's algorithms as its chapters and appendix code write them: every extension off
    PAPER = "paper"  # a published algorithm alone, as its paper writes it (ORCA: every extension rule off)


class Params(pydantic.BaseModel):
    """Base of every parameter model: frozen, strict, no unknown names, finite numbers only.

    A model with presets declares a ``preset: Preset | None`` field and ``PRESETS`` (preset ->
    ``{field: value}``); see the module's docstring for how a preset is applied.
    """

    model_config = pydantic.ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)

    #: preset -> values of the fields it sets (plain data, validated like given values)
    PRESETS: ClassVar[Mapping[Preset, Mapping[str, Any]]] = {}

    @pydantic.model_validator(mode="before")
    @classmethod
    def _apply_preset(cls, data: Any) -> Any:
        """Fill the fields a chosen preset sets and that are not given explicitly."""
        if not isinstance(data, dict) or data.get("preset") is None:
            return data
        name = data["preset"]
        if "preset" not in cls.model_fields or not cls.PRESETS:
            raise ParamRuleError("preset", f"these parameters have no presets, got {_quoted(name)}")
        try:
            preset: Preset | None = Preset(name)
        except ValueError:
            preset = None
        if preset is None or preset not in cls.PRESETS:
            choices = " | ".join(p.value for p in cls.PRESETS)
            raise ParamRuleError("preset", f"must be one of {choices}, got {_quoted(name)}")
        return {**cls.PRESETS[preset], **data}

    def check_for(self, context: PlanContext) -> None:
        """Refuse values that do not fit the scenario (raise ``ParamRuleError``); none by default."""

    def check_layout(self, info: TaskInfo) -> None:
        """Refuse values that cannot work with the task's static layout (``TaskInfo``, as the agents are told
        it when the run starts), raising ``ConfigError`` naming the field; none by default. Called when the
        scenario is loaded, so that what a run would refuse when it starts is refused by ``check`` and
        before a sweep starts."""


def _quoted(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def preset_values(model: type[Params], preset: Preset | str) -> dict[str, Any]:
    """Every value a model takes under ``preset`` with nothing else given (plain data)."""
    return model.model_validate({"preset": Preset(preset).value}).model_dump(mode="json")


def extensions(model: type[Params], preset: Preset | str = Preset.THESIS) -> dict[str, tuple[Any, Any]]:
    """The fields a preset sets to a value other than the default: ``{field: (preset value, default)}``
    (plain data), in the model's field order. For the thesis preset: the model's extensions of the thesis."""
    chosen = preset_values(model, preset)
    default = model().model_dump(mode="json")
    return {
        k: (chosen[k], default[k])
        for k in model.model_fields
        if k != "preset" and k in model.PRESETS.get(Preset(preset), {}) and chosen[k] != default[k]
    }


class NoParams(Params):
    """A plug-in without parameters."""


class ParamRuleError(ValueError):
    """A rule between parameters (or between a parameter and the scenario) is broken.

    Raised inside a model validator or ``check_for``; ``field`` names the parameter to blame, so
    that the one-line error names it (``avoidance_params.off_threshold: ...``).
    """

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field


@dataclasses.dataclass(frozen=True)
class PlanContext:
    """What ``Params.check_for`` may know of the scenario.

    Attributes:
        arena_size: (Lx, Ly) m.
        n_agents: swarm size.
        time_limit_s: s, the task's time limit.
        planner_hz: Hz, planner rate.
        range_rays: rays per agent of the range sensors (``sensing.range.rays``).
        memory_budget: bytes, largest memory a plug-in's arrays may need.
    """

    arena_size: tuple[float, float]
    n_agents: int
    time_limit_s: float
    planner_hz: int
    range_rays: int = 8
    memory_budget: int = MEMORY_BUDGET_BYTES


def check_memory(field: str, needed: float, budget: int, what: str) -> None:
    """Refuse (``ParamRuleError`` on ``field``) when ``needed`` bytes exceed ``budget``."""
    if needed > budget:
        raise ParamRuleError(
            field,
            f"{what} would need about {format_bytes(needed)}, above the memory budget of "
            f"{format_bytes(budget)} (set {ENV_VAR} to allow more)",
        )


# ------------------------------------------------------------------ description
@dataclasses.dataclass(frozen=True)
class ParamInfo:
    """One parameter as ``list`` shows it and the tuner reads it.

    Attributes:
        name: field name.
        type: the type as text (``float``, ``int``, ``float | null``, ``random | nearest`` ...).
        default: the default value (plain data).
        description: one line.
        numeric: True when the value is a number (int or float, possibly null).
        integer: True for an integer parameter.
        low: smallest value (None: unbounded); ``low_open``: the bound itself is excluded.
        high: largest value (None: unbounded); ``high_open``: the bound itself is excluded.
    """

    name: str
    type: str
    default: Any
    description: str
    numeric: bool = False
    integer: bool = False
    low: float | None = None
    low_open: bool = False
    high: float | None = None
    high_open: bool = False

    def range_text(self) -> str:
        """``[0, 1]``, ``(0, 10]``, ``>= 0``, ``> 0`` or ``-`` when not a number."""
        if not self.numeric:
            return "-"
        if self.low is None and self.high is None:
            return "any"
        if self.high is None:
            return f"{'>' if self.low_open else '>='} {self.low:g}"
        if self.low is None:
            return f"{'<' if self.high_open else '<='} {self.high:g}"
        return f"{'(' if self.low_open else '['}{self.low:g}, {self.high:g}{')' if self.high_open else ']'}"

    def contains(self, value: float) -> bool:
        """True when ``value`` lies in the range."""
        if self.low is not None and (value < self.low or (self.low_open and value == self.low)):
            return False
        return not (self.high is not None and (value > self.high or (self.high_open and value == self.high)))


def describe(model: type[pydantic.BaseModel]) -> list[ParamInfo]:
    """Every field of a parameter model with its type, default, range and description."""
    out = []
    presets: Mapping[Preset, Any] = getattr(model, "PRESETS", {})
    for name, f in model.model_fields.items():
        default = f.get_default(call_default_factory=True)
        info = field_info(name, f.annotation, f.metadata, default=_plain(default), description=f.description or "")
        if name == "preset" and presets:  # the presets this model has, not every one of the enum
            info = dataclasses.replace(info, type=" | ".join([*(p.value for p in presets), "null"]))
        out.append(info)
    return out


def field_info(
    name: str, annotation: Any, metadata: list[Any], *, default: Any = None, description: str = ""
) -> ParamInfo:
    """A ``ParamInfo`` from a field's annotation and its constraint metadata (``Ge``, ``Lt`` ...).

    Constraints inside ``Annotated`` members of a union (``float | list[float]``) are read from
    the numeric member.
    """
    kind, inner = _numeric(annotation)
    bounds = _bounds([*metadata, *inner]) if kind else {}
    return ParamInfo(
        name=name,
        type=type_text(annotation),
        default=default,
        description=description,
        numeric=kind is not None,
        integer=kind is int,
        **bounds,
    )


def _numeric(annotation: Any) -> tuple[type | None, list[Any]]:
    """(int or float, constraints of that member) when the annotation is a number (or null), else (None, [])."""
    meta: list[Any] = []
    if typing.get_origin(annotation) is typing.Annotated:
        annotation, *meta = typing.get_args(annotation)
        meta = [m for x in meta for m in (getattr(x, "metadata", None) or [x])]
    if annotation in (int, float):
        return annotation, meta
    if _is_union(annotation):
        found: tuple[type | None, list[Any]] = (None, [])
        for member in typing.get_args(annotation):
            if member is type(None):
                continue
            kind, inner = _numeric(member)
            if kind is None:
                continue
            if found[0] is not None and found[0] is not kind:
                return None, []
            found = (kind, [*meta, *inner])
        return found
    return None, []


def _is_union(annotation: Any) -> bool:
    return typing.get_origin(annotation) in (Union, types.UnionType)


def _bounds(metadata: list[Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for m in metadata:
        if isinstance(m, annotated_types.Ge):
            out.update(low=_number(m.ge), low_open=False)
        elif isinstance(m, annotated_types.Gt):
            out.update(low=_number(m.gt), low_open=True)
        elif isinstance(m, annotated_types.Le):
            out.update(high=_number(m.le), high_open=False)
        elif isinstance(m, annotated_types.Lt):
            out.update(high=_number(m.lt), high_open=True)
    return out


def _number(bound: Any) -> float:
    return float(bound)


def type_text(annotation: Any) -> str:
    """A short text for a field's type: ``float``, ``int | null``, ``box | sphere``, ``list[float]``."""
    if typing.get_origin(annotation) is typing.Annotated:
        annotation = typing.get_args(annotation)[0]
    if annotation is type(None):
        return "null"
    if isinstance(annotation, type) and issubclass(annotation, enum.Enum):
        return " | ".join(str(m.value) for m in annotation)
    if typing.get_origin(annotation) is Literal:
        return " | ".join(str(a) for a in typing.get_args(annotation))
    if _is_union(annotation):
        return " | ".join(type_text(a) for a in typing.get_args(annotation))
    origin = typing.get_origin(annotation)
    if origin is not None:
        args = ", ".join(type_text(a) for a in typing.get_args(annotation))
        return f"{getattr(origin, '__name__', str(origin))}[{args}]"
    return getattr(annotation, "__name__", str(annotation))


def _plain(value: Any) -> Any:
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value


__all__ = [
    "MEMORY_BUDGET_BYTES",
    "NoParams",
    "ParamInfo",
    "ParamRuleError",
    "Params",
    "PlanContext",
    "Preset",
    "check_memory",
    "describe",
    "extensions",
    "field_info",
    "preset_values",
    "type_text",
]
