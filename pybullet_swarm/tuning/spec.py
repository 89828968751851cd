"""What a study tunes and how its trials are scored (``TuneSpec``), and the samplers it may use."""

from __future__ import annotations

import dataclasses
import enum
import math
from pathlib import Path
from typing import Any, Mapping, Sequence

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.tuning.objective import (
    DEFAULT_OBJECTIVE,
    DEFAULT_PENALTY,
    Objective,
    parse_objectives,
    split_expressions,
)
from pybullet_swarm.tuning.space import ParamSpec, check_params, parse_param


class SamplerKind(str, enum.Enum):
    """Optuna samplers a study can use."""

    TPE = "tpe"  # tree-structured Parzen estimator (single and multi-objective)
    NSGA2 = "nsga2"  # NSGA-II genetic algorithm (multi-objective; single too)
    CMAES = "cmaes"  # covariance matrix adaptation evolution strategy (single objective)
    RANDOM = "random"  # uniform random search (the baseline of the others)


@dataclasses.dataclass(frozen=True)
class TuneSpec:
    """What a study tunes and how trials are scored.

    Args:
        scenario: scenario YAML file or bundled name.
        params: the search space: ``ParamSpec`` or ``key.path=low:high[:log][:int]`` texts.
        planner: planner name (None: the scenario's).
        avoidance: avoidance layer (None: the scenario's).
        objectives: objective expressions (one: single-objective; several: Pareto front).
        directions: ``minimize``/``maximize`` per objective (None: all minimised).
        trials: finished trials the study should hold.
        seeds_per_trial: K, runs per trial (seeds ``seed_start .. seed_start + K - 1``, shared by all trials).
        seed_start: first seed.
        sampler: the Optuna sampler.
        sampler_seed: seed of the sampler.
        penalty: added in the worse direction to each objective of a run that does not complete.
        overrides: ``key.path=value`` applied to every run (not tuned).
        study_name: name of the study in the storage (default ``<scenario>-<planner>-<avoidance>``).
        baseline: parameter values run as the first trial of a new study (e.g. the defaults).
        enqueue: more parameter values run next in a new study (e.g. another study's trials, whose
            runs ``runs.csv`` already holds when the studies share a directory).

    Raises:
        ConfigError: a bad parameter range, objective, direction, budget or sampler.
    """

    scenario: str | Path
    params: Sequence[ParamSpec | str]
    planner: str | None = None
    avoidance: str | None = None
    objectives: Sequence[str] | str = (DEFAULT_OBJECTIVE,)
    directions: Sequence[str] | str | None = None
    trials: int = 30
    seeds_per_trial: int = 3
    seed_start: int = 0
    sampler: SamplerKind | str = SamplerKind.TPE
    sampler_seed: int = 0
    penalty: float = DEFAULT_PENALTY
    overrides: Mapping[str, Any] | Sequence[str] = ()
    study_name: str | None = None
    baseline: Mapping[str, float] | None = None
    enqueue: Sequence[Mapping[str, float]] = ()

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 - frozen: normalised once, here
        set_("params", check_params([p if isinstance(p, ParamSpec) else parse_param(p) for p in self.params]))
        texts = split_expressions(self.objectives) if isinstance(self.objectives, str) else list(self.objectives)
        objs = parse_objectives(
            self.objectives, self.directions, source="--objectives" if len(texts) > 1 else "--objective"
        )
        set_("_objectives", objs)
        for name, low in (("trials", 1), ("seeds_per_trial", 1), ("seed_start", 0), ("sampler_seed", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < low:
                raise ConfigError(f"must be an integer >= {low}, got {v!r}", source="--" + name.replace("_", "-"))
        try:
            set_("sampler", SamplerKind(self.sampler))
        except ValueError:
            raise ConfigError(
                f"must be one of {', '.join(k.value for k in SamplerKind)}, got {self.sampler!r}", source="--sampler"
            ) from None
        if self.sampler is SamplerKind.CMAES and len(objs) > 1:
            raise ConfigError("CMA-ES optimises one objective; use nsga2 or tpe for --objectives", source="--sampler")
        if not (isinstance(self.penalty, (int, float)) and math.isfinite(self.penalty) and self.penalty >= 0):
            raise ConfigError(f"must be a number >= 0, got {self.penalty!r}", source="--penalty")
        keys = {p.key for p in self.param_specs}
        set_("enqueue", tuple(dict(e) for e in self.enqueue))
        for name, given in (
            ("baseline", [self.baseline] if self.baseline is not None else []),
            ("enqueue", self.enqueue),
        ):
            for values in given:
                if set(values) != keys:
                    raise ConfigError(
                        f"needs a value for exactly the tuned keys {sorted(keys)}, got {sorted(values)}", source=name
                    )

    @property
    def objective_list(self) -> tuple[Objective, ...]:
        """The parsed objectives."""
        return self._objectives  # type: ignore[attr-defined, no-any-return]

    @property
    def param_specs(self) -> tuple[ParamSpec, ...]:
        """The parsed search space (``params`` after ``__post_init__`` normalised it)."""
        return tuple(p for p in self.params if isinstance(p, ParamSpec))

    @property
    def sampler_kind(self) -> SamplerKind:
        """The sampler (``sampler`` after ``__post_init__`` normalised it)."""
        return SamplerKind(self.sampler)

    @property
    def seeds(self) -> tuple[int, ...]:
        """The seeds every trial runs."""
        return tuple(range(self.seed_start, self.seed_start + self.seeds_per_trial))

    @property
    def multi(self) -> bool:
        """True with more than one objective."""
        return len(self.objective_list) > 1

    def to_json(self) -> dict[str, Any]:
        """What determines a study's results (stored with it; a resume must match)."""
        return {
            "params": [p.to_json() for p in self.param_specs],
            "objectives": [o.text for o in self.objective_list],
            "directions": [o.direction.value for o in self.objective_list],
            "seeds": list(self.seeds),
            "penalty": float(self.penalty),
        }
