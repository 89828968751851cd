"""Ablation on a benchmark split: configurations that switch rules off, each paired with a baseline.

A configuration is one planner with some scenario overrides (``planner.params.claims=false``,
``avoidance_params.headway=false``) run over a split by :func:`benchmark.run_benchmark` into its own
directory (resumable), then compared with a baseline of the same planner on the runs both have
(:func:`benchmark.compare`: paired differences with bootstrap 95 % intervals).

The verdict follows the acceptance rule of ``docs/guides/benchmark.md``: a configuration *pays* when
switching its rules off makes a primary metric worse with an interval that excludes zero
(completion down; stalls, runs with a contact of any class or of one class, or the median time
up). The rules of a configuration that does not pay are deleted. :func:`results_table` writes the
comparisons as a results table (``docs/results/data/NAME.json``, rendered by the docs).
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pybullet_swarm.experiment import benchmark
from pybullet_swarm.experiment.rundir import atomic_write

#: the metrics of a table: (key in compare's output, column, True when a rise is worse)
METRICS = (
    ("completion_rate", "completion", False),
    ("stall_rate", "stalls", True),
    ("contact_rate_agent_agent", "a-a contact", True),
    ("contact_rate_any", "any contact", True),
    ("median_time_s", "median time [s]", True),
)


@dataclasses.dataclass(frozen=True)
class Ablation:
    """One configuration of an ablation.

    Attributes:
        name: its row in the table (``"rule: claims"``).
        planner: the planner it runs.
        overrides: ``key.path -> value`` on top of the suite's (``planner.params.claims`` -> False).
    """

    name: str
    planner: str
    overrides: tuple[tuple[str, Any], ...]

    @property
    def slug(self) -> str:
        """Its directory name: planner and name, in file-name characters."""
        words = self.name.split(": ", 1)[-1].split(" (")[0]
        return re.sub(r"[^A-Za-z0-9_.+-]+", "+", f"{self.planner}-{words}").strip("+")

    @property
    def rules(self) -> str:
        """What it switches off, for the table (the last component of each key)."""
        return ", ".join(k.rsplit(".", 1)[-1] for k, _ in self.overrides)


def switched_off(name: str, planner: str, section: str, rules: Sequence[str]) -> Ablation:
    """The configuration that sets the boolean rules ``section.RULE`` false."""
    return Ablation(name, planner, tuple((f"{section}.{r}", False) for r in rules))


def run_ablation(
    configs: Sequence[Ablation],
    out: Path,
    *,
    suite: str = "construction",
    split: str = "holdout",
    seeds: int | None = None,
    workers: int | None = None,
    baseline: Mapping[str, Any] | None = None,
    baseline_seeds: Mapping[str, int] | None = None,
    common: Sequence[tuple[str, Any]] = (),
) -> dict[str, dict[str, Any]]:
    """Run (or resume) every configuration into ``out/abl-SLUG``; returns name -> compare result.

    The baseline of each planner is ``baseline`` (a benchmark JSON with that planner's runs) when
    given, or else is run into ``out/base`` with ``baseline_seeds[planner]`` seeds per layout (the
    split's own seeds when absent). ``common`` overrides apply to the baseline run and every
    configuration alike (a study under another condition: ``(("sensing.state", "estimated"),)``);
    a given ``baseline`` must have been run under them.
    """
    bases: dict[str, Mapping[str, Any]] = {}
    results = {}
    for cfg in configs:
        if cfg.planner not in bases:
            if baseline is not None:
                bases[cfg.planner] = baseline
            else:
                n = (baseline_seeds or {}).get(cfg.planner)
                bases[cfg.planner] = benchmark.run_benchmark(
                    suite, split, out / "base", workers=workers, figure=False,
                    variant=benchmark.Variant(planners=(cfg.planner,), seeds=n, overrides=tuple(common)),
                ).data  # fmt: skip
        res = benchmark.run_benchmark(
            suite, split, out / f"abl-{cfg.slug}", workers=workers, figure=False,
            variant=benchmark.Variant(planners=(cfg.planner,), seeds=seeds, overrides=(*common, *cfg.overrides)),
        )  # fmt: skip
        results[cfg.name] = benchmark.compare(bases[cfg.planner], res.data)
    return results


def verdict(metrics: Mapping[str, Any]) -> str:
    """``pays (METRICS)`` when switching the rules off made a primary metric significantly worse: a column of
    the table, or the runs with a contact of one class (``contact_rate_load_structure`` -> "load-structure
    contact"; the benchmark records runs with a contact per class); else ``does not pay``. A metric that is
    significantly better with the rules off is named after it (``does not pay; better off: median time``):
    what the rules cost."""
    shown = {key for key, _, _ in METRICS}
    classes = [
        (k, k.removeprefix("contact_rate_").replace("_", "-") + " contact", True)
        for k in sorted(metrics)
        if k.startswith("contact_rate_") and k not in shown
    ]
    significant = [
        (col, (metrics[key]["diff"] > 0) == rise_is_worse)
        for key, col, rise_is_worse in (*METRICS, *classes)
        if key in metrics and metrics[key]["significant"]
    ]
    worse = [col for col, off_worse in significant if off_worse]
    better = [col for col, off_worse in significant if not off_worse]
    head = "pays (" + ", ".join(worse) + ")" if worse else "does not pay"
    return head + ("; better off: " + ", ".join(better) if better else "")


def _cell(x: Mapping[str, Any] | None) -> str:
    if x is None or x["ci"] is None:
        return "-"
    star = " *" if x["significant"] else ""
    return f"{x['a']:.3g} -> {x['b']:.3g} [{x['ci'][0]:+.3g}, {x['ci'][1]:+.3g}]{star}"


def results_table(
    results: Mapping[str, Mapping[str, Any]],
    configs: Sequence[Ablation],
    *,
    title: str,
    command: str,
    notes: Sequence[str] = (),
) -> dict[str, Any]:
    """The comparisons as a results table (the docs/results/data schema), one row per configuration."""
    by_name = {c.name: c for c in configs}
    rows = []
    commit = ""
    for name, res in results.items():
        (conf,) = res["configurations"]
        commit = commit or str(res["b"].get("commit", ""))
        m = conf["metrics"]
        rows.append([name, by_name[name].rules, conf["pairs"], *(_cell(m.get(k)) for k, _, _ in METRICS), verdict(m)])
    return {
        "title": title,
        "command": command,
        "commit": commit[:10],
        "date": datetime.date.today().isoformat(),
        "columns": ["configuration", "rules off", "pairs", *(c for _, c, _ in METRICS), "verdict"],
        "rows": rows,
        "notes": [
            "Each cell: baseline -> these rules off, over the paired runs (layout and seed), with the paired "
            "bootstrap 95 % interval of the difference; * marks an interval that excludes zero.",
            *notes,
            "A configuration pays when switching it off makes a primary metric significantly worse; rules in "
            "configurations that do not pay are deleted (docs/guides/benchmark.md).",
        ],
    }


def report(data: Mapping[str, Any], table: Path | None) -> None:
    """Print a results table's rows, one line each, and write it (atomically) to ``table`` when given."""
    for row in data["rows"]:
        print(" | ".join(str(c) for c in row))
    if table is not None:
        atomic_write(table, lambda f: f.write(json.dumps(data, indent=1) + "\n"))
        print(table)
