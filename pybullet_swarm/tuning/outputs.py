"""What a study writes into its directory: ``trials.csv``, ``best.yaml``, ``study.json`` and figures.

``best.yaml`` is a scenario override file: a flat mapping of ``key.path: value`` (``planner.name``,
``avoidance``, the study's fixed ``--set`` overrides and the tuned values), applied with ``pybullet-swarm run SCENARIO -c best.yaml``
or, key by key, with ``--set key.path=value``. For a multi-objective study it holds the Pareto-optimal
trial with the best first objective, and ``pareto/trial-<n>.yaml`` holds every Pareto-optimal trial.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
import functools
from typing import Any, Mapping, Sequence

import yaml

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.results import RunsTable, format_cell, plain_cell
from pybullet_swarm.experiment.rundir import atomic_write, write_json

from pybullet_swarm.tuning.spec import TuneSpec

TRIALS_CSV = "trials.csv"
BEST_YAML = "best.yaml"
STUDY_JSON = "study.json"


# ------------------------------------------------------------------ records
def value_columns(spec: TuneSpec) -> list[str]:
    """``value`` (one objective) or ``value_0``, ``value_1``, ... (several)."""
    n = len(spec.objective_list)
    return ["value"] if n == 1 else [f"value_{i}" for i in range(n)]


def trial_records(study: Any, spec: TuneSpec) -> list[dict[str, Any]]:
    """Every trial of a study as a flat record (one ``trials.csv`` row each), in trial order."""
    from optuna.trial import TrialState

    complete = [t for t in study.trials if t.state is TrialState.COMPLETE]
    pareto = {t.number for t in study.best_trials} if complete else set()
    cols = value_columns(spec)
    out = []
    for t in study.trials:
        rec: dict[str, Any] = {"trial": t.number, "state": t.state.name.lower()}
        values = t.values if t.values is not None else [None] * len(cols)
        rec.update(dict(zip(cols, values)))
        for p in spec.param_specs:
            rec[p.key] = t.params.get(p.key)
        rec["completed"] = t.user_attrs.get("completed")
        rec.update({k: v for k, v in t.user_attrs.items() if k.startswith("mean.")})
        rec["pareto" if spec.multi else "best"] = t.number in pareto
        rec["baseline"] = bool(t.user_attrs.get("baseline", False))
        rec["retry_of"] = t.user_attrs.get("retry_of")
        rec["seeds"] = plain_cell(t.user_attrs.get("seeds"))
        rec["per_seed"] = plain_cell(t.user_attrs.get("per_seed"))
        rec["duration_s"] = None if t.duration is None else round(t.duration.total_seconds(), 3)
        rec["error"] = t.user_attrs.get("error")
        out.append(rec)
    return out


def best_records(study: Any, spec: TuneSpec) -> list[dict[str, Any]]:
    """The best trial (one objective) or the Pareto-optimal trials sorted by the first objective."""
    from optuna.trial import TrialState

    if not study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)):
        return []
    by_number = {r["trial"]: r for r in trial_records(study, spec)}
    best = sorted(study.best_trials, key=lambda t: (_sign(spec, 0) * t.values[0], t.number))
    return [by_number[t.number] for t in best]


def _sign(spec: TuneSpec, i: int) -> float:
    from pybullet_swarm.tuning.objective import Direction

    return 1.0 if spec.objective_list[i].direction is Direction.MINIMIZE else -1.0


def best_overrides(record: Mapping[str, Any], spec: TuneSpec, *, planner: str, avoidance: str) -> dict[str, Any]:
    """The override mapping of a trial: the planner, the avoidance layer, the study's fixed ``--set``
    overrides and the tuned values (everything a run needs on top of the scenario file)."""
    from pybullet_swarm.experiment.scenario import parse_override

    out: dict[str, Any] = {"planner.name": planner, "avoidance": avoidance}
    fixed = (
        spec.overrides.items()
        if isinstance(spec.overrides, Mapping)
        else (parse_override(o) if isinstance(o, str) else tuple(o) for o in spec.overrides)
    )
    out.update(dict(fixed))
    for p in spec.param_specs:
        v = record[p.key]
        out[p.key] = int(v) if p.integer else float(v)
    return out


# ------------------------------------------------------------------ writing
def write_trials_csv(path: Path, records: Sequence[Mapping[str, Any]]) -> Path:
    """Write the trial records as CSV (atomically)."""
    import csv
    import io

    cols: dict[str, None] = {}
    for r in records:
        cols.update(dict.fromkeys(r))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(cols))
    for r in records:
        w.writerow([format_cell(plain_cell(r.get(c))) for c in cols])
    atomic_write(path, lambda fh: fh.write(buf.getvalue()))
    return path


def write_best_yaml(
    path: Path, record: Mapping[str, Any], spec: TuneSpec, *, study_name: str, planner: str, avoidance: str
) -> Path:
    """Write one trial as a scenario override file, with how it scored and how to run it as comments."""
    overrides = best_overrides(record, spec, planner=planner, avoidance=avoidance)
    cols = value_columns(spec)
    scores = ", ".join(f"{o.direction.value} {o.text} = {record[c]:.6g}" for o, c in zip(spec.objective_list, cols))
    seeds = record.get("seeds") or ""
    sets = " ".join(f"--set {k}={_yaml_scalar(v)}" for k, v in overrides.items())
    header = (
        f"# pybullet-swarm tune: trial {record['trial']} of study {study_name!r} on {spec.scenario}\n"
        f"# {scores} (mean over seeds {seeds}; {100 * (record.get('completed') or 0):.0f} % of runs completed)\n"
        f"# apply: pybullet-swarm run {spec.scenario} -c {path.name} --seed {spec.seed_start}\n"
        f"#    or: pybullet-swarm run {spec.scenario} {sets}\n"
    )
    text = header + yaml.safe_dump(overrides, sort_keys=False)
    atomic_write(path, lambda fh: fh.write(text))
    return path


def _yaml_scalar(v: Any) -> str:
    return yaml.safe_dump(v, default_flow_style=True).strip().removesuffix("...").strip()


def read_overrides_file(path: str | Path) -> list[tuple[str, Any]]:
    """The ``(key.path, value)`` pairs of an override file (``best.yaml``); nested mappings are
    flattened into dotted keys.

    Raises:
        ConfigError: a missing or unreadable file, or one that is not a mapping.
    """
    from pybullet_swarm.validation import read_yaml

    p = Path(path)
    if not p.is_file():
        raise ConfigError("file not found", source=str(path))
    data = read_yaml(p)
    if data is None:
        return []
    if not isinstance(data, dict):
        raise ConfigError(f"must be a mapping of key.path: value, got {type(data).__name__}", source=p.name)
    out: list[tuple[str, Any]] = []

    def walk(node: Mapping[Any, Any], prefix: str) -> None:
        for k, v in node.items():
            if not isinstance(k, str) or not k:
                raise ConfigError(f"keys must be key.path text, got {k!r}", source=p.name)
            key = f"{prefix}{k}"
            if isinstance(v, dict) and v:
                walk(v, key + ".")
            else:
                out.append((key, v))

    walk(data, "")
    return out


def _value_of(i: int, trial: Any) -> float:
    return float(trial.values[i])


def param_importances(study: Any, spec: TuneSpec) -> dict[str, dict[str, float]]:
    """Importance of each parameter per objective: ``optuna.importance.get_param_importances`` with
    PED-ANOVA (Optuna's evaluator that needs no scikit-learn: how differently a parameter is
    distributed in the best 10 % of trials than in all of them); empty below two completed trials."""
    import warnings

    import optuna
    from optuna.trial import TrialState

    complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    if len(complete) < 2 or len(spec.param_specs) < 1:
        return {}
    out: dict[str, dict[str, float]] = {}
    for i, obj in enumerate(spec.objective_list):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                imp = optuna.importance.get_param_importances(
                    study,
                    evaluator=optuna.importance.PedAnovaImportanceEvaluator(),
                    target=functools.partial(_value_of, i),
                )
        except (RuntimeError, ValueError, ZeroDivisionError, ImportError):
            continue
        vals = {k: float(v) for k, v in imp.items() if math.isfinite(float(v))}
        if vals:
            out[obj.text] = vals
    return out


def write_outputs(
    study: Any, spec: TuneSpec, out: Path, *, planner: str, avoidance: str, scenario_name: str, figures: bool = True
) -> list[Path]:
    """Write ``trials.csv``, ``study.json``, ``best.yaml`` (and ``pareto/``) and the figures."""
    records = trial_records(study, spec)
    files = [write_trials_csv(out / TRIALS_CSV, records)]
    best = best_records(study, spec)
    if best:
        files.append(
            write_best_yaml(
                out / BEST_YAML, best[0], spec, study_name=study.study_name, planner=planner, avoidance=avoidance
            )
        )
        if spec.multi:
            for rec in best:
                files.append(
                    write_best_yaml(
                        out / "pareto" / f"trial-{rec['trial']}.yaml",
                        rec,
                        spec,
                        study_name=study.study_name,
                        planner=planner,
                        avoidance=avoidance,
                    )
                )
    importances = param_importances(study, spec) if figures else {}
    summary = {
        "study": study.study_name,
        "scenario": str(spec.scenario),
        "scenario_name": scenario_name,
        "planner": planner,
        "avoidance": avoidance,
        "sampler": spec.sampler_kind.value,
        "objectives": [{"expression": o.text, "direction": o.direction.value} for o in spec.objective_list],
        "params": [p.to_json() for p in spec.param_specs],
        "seeds": list(spec.seeds),
        "penalty": spec.penalty,
        "trials": len(records),
        "complete": sum(1 for r in records if r["state"] == "complete"),
        "best": [{k: _plain(v) for k, v in r.items()} for r in best],
        "importances": importances,
        "updated": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
    write_json(out / STUDY_JSON, summary)
    files.append(out / STUDY_JSON)
    if figures and any(r["state"] == "complete" for r in records):
        from pybullet_swarm.plotting.tuning_plots import plot_history, plot_importance, plot_pareto

        labels = [o.text for o in spec.objective_list]
        minimise = [_sign(spec, i) > 0 for i in range(len(labels))]
        cols = value_columns(spec)
        files.append(
            plot_history(
                records,
                cols,
                labels,
                minimise,
                out / "plots" / "history.png",
                title=f"{scenario_name}: {planner} ({spec.sampler_kind.value})",
            )
        )  # type: ignore
        if importances:
            files.append(plot_importance(importances, out / "plots" / "importance.png", title=f"{planner}"))
        if spec.multi:
            files.append(
                plot_pareto(
                    records,
                    cols[:2],
                    labels[:2],
                    minimise[:2],
                    out / "plots" / "pareto.png",
                    title=f"{scenario_name}: {planner}, Pareto front",
                )
            )
    return files


def _plain(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def runs_table(out: Path) -> RunsTable:
    """The ``runs.csv`` of a study directory (one row per run of any trial)."""
    from pybullet_swarm.experiment.results import RUNS_CSV

    return RunsTable(Path(out) / RUNS_CSV)


__all__ = [
    "BEST_YAML",
    "STUDY_JSON",
    "TRIALS_CSV",
    "best_overrides",
    "best_records",
    "param_importances",
    "read_overrides_file",
    "runs_table",
    "trial_records",
    "value_columns",
    "write_best_yaml",
    "write_outputs",
    "write_trials_csv",
]
