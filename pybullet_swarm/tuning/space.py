"""The search space of a study: ``--param key.path=low:high[:log][:int]``."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable, Sequence

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.planning.params import ParamInfo


@dataclasses.dataclass(frozen=True)
class ParamSpec:
    """One tuned scenario field.

    Attributes:
        key: the scenario's ``key.path`` (as for ``--set``), e.g. ``planner.params.fatigue``.
        low: smallest value (inclusive).
        high: largest value (inclusive, > low).
        log: sample uniformly in log space (needs low > 0).
        integer: integer values only (both bounds integers).
    """

    key: str
    low: float
    high: float
    log: bool = False
    integer: bool = False

    def __post_init__(self) -> None:
        src = "--param"
        if not isinstance(self.key, str) or not self.key or any(not p for p in self.key.split(".")):
            raise ConfigError(f"expected a key.path, got {self.key!r}", source=src)
        for name in ("low", "high"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"{name} must be a finite number, got {v!r}", source=src, field=self.key)
        if not self.low < self.high:
            raise ConfigError(f"needs low < high, got {self.low!r}:{self.high!r}", source=src, field=self.key)
        if self.log and self.low <= 0:
            raise ConfigError(f"a log range needs low > 0, got {self.low!r}", source=src, field=self.key)
        if self.integer and not (float(self.low).is_integer() and float(self.high).is_integer()):
            raise ConfigError(
                f"an int range needs integer bounds, got {self.low!r}:{self.high!r}", source=src, field=self.key
            )

    def distribution(self) -> Any:
        """The Optuna distribution of this parameter."""
        import optuna

        if self.integer:
            return optuna.distributions.IntDistribution(int(self.low), int(self.high), log=self.log)
        return optuna.distributions.FloatDistribution(float(self.low), float(self.high), log=self.log)

    def text(self) -> str:
        """The ``--param`` text of this spec."""
        mods = (":log" if self.log else "") + (":int" if self.integer else "")
        return f"{self.key}={self.low:g}:{self.high:g}{mods}"

    def to_json(self) -> dict[str, Any]:
        """Plain data (stored with the study, compared on resume)."""
        return {"key": self.key, "low": self.low, "high": self.high, "log": self.log, "integer": self.integer}


def parse_param(text: str) -> ParamSpec:
    """Parse ``key.path=low:high[:log][:int]``.

    Raises:
        ConfigError: one line naming ``--param`` and what was expected.
    """
    if not isinstance(text, str) or "=" not in text:
        raise ConfigError(f"expected key.path=low:high[:log][:int], got {text!r}", source="--param")
    key, _, rng = text.partition("=")
    key = key.strip()
    parts = [p.strip() for p in rng.split(":")]
    if len(parts) < 2 or any(not p for p in parts):
        raise ConfigError(f"expected key.path=low:high[:log][:int], got {text!r}", source="--param")
    mods = parts[2:]
    bad = [m for m in mods if m not in ("log", "int")]
    if bad or len(set(mods)) != len(mods):
        raise ConfigError(f"modifiers must be log and/or int, got {':'.join(mods)!r}", source="--param", field=key)
    try:
        low, high = float(parts[0]), float(parts[1])
    except ValueError:
        raise ConfigError(
            f"low and high must be numbers, got {parts[0]!r}:{parts[1]!r}", source="--param", field=key
        ) from None
    return ParamSpec(key=key, low=low, high=high, log="log" in mods, integer="int" in mods)


def check_params(params: Sequence[ParamSpec]) -> tuple[ParamSpec, ...]:
    """At least one parameter, no key twice, no key inside another.

    Raises:
        ConfigError: an empty space or overlapping keys.
    """
    params = tuple(params)
    if not params:
        raise ConfigError("needs at least one --param key.path=low:high", source="--param")
    keys = [p.key for p in params]
    for i, k in enumerate(keys):
        for other in keys[i + 1 :]:
            if k == other or other.startswith(k + ".") or k.startswith(other + "."):
                raise ConfigError(f"overlaps {other!r}", source="--param", field=k)
    return params


def check_ranges(params: Sequence[ParamSpec], lookup: Callable[[str], ParamInfo | None]) -> None:
    """Refuse ranges the parameter models do not allow: a key that names no number, a range that
    leaves the field's range, an integer field without ``:int``.

    Args:
        params: the search space.
        lookup: key -> the field's type and range (``experiment.scenario.field_info`` of the study's
            resolved scenario), None when the key names no field.

    Raises:
        ConfigError: one line naming ``--param`` and the key.
    """
    for p in params:
        info = lookup(p.key)
        if info is None:
            raise ConfigError(
                "names no field of the scenario, of the planner's parameters or of the avoidance layer's parameters",
                source="--param",
                field=p.key,
            )
        if not info.numeric:
            raise ConfigError(f"is not a number ({info.type}) and cannot be tuned", source="--param", field=p.key)
        if info.integer and not p.integer:
            raise ConfigError(
                f"is an integer: give its range with :int, e.g. {p.key}={math.ceil(p.low)}:{math.floor(p.high)}:int",
                source="--param",
                field=p.key,
            )
        if not (info.contains(p.low) and info.contains(p.high)):
            raise ConfigError(
                f"the range {p.low:g}:{p.high:g} leaves the parameter's range {info.range_text()}",
                source="--param",
                field=p.key,
            )


__all__ = ["ParamSpec", "check_params", "check_ranges", "parse_param"]


def planner_search_space(planner: str) -> list[ParamSpec]:
    """The default search space a planner's parameter model declares (``TUNED``: field -> (low, high, log)),
    as ``planner.params.*`` keys; empty when it declares none."""
    from pybullet_swarm.planning.registry import planners

    entry = planners().get(planner)
    tuned = getattr(entry.params, "TUNED", None) if entry is not None else None
    return [
        ParamSpec(key=f"planner.params.{k}", low=float(lo), high=float(hi), log=bool(log))
        for k, (lo, hi, log) in (tuned or {}).items()
    ]
