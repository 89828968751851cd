"""Planner optimisation on the testbed's own metrics: ``pybullet-swarm tune``.

A study samples scenario fields (planner parameters, or any ``key.path``) within given ranges
with an Optuna sampler (TPE, NSGA-II, CMA-ES or random), runs every sampled configuration over
the same K seeds through the sweep executors, scores each run with objective expressions over
its flattened metrics and writes ``trials.csv``, ``best.yaml`` and figures. Studies live in an
Optuna storage (an SQLite file in the output directory by default) and resume after a kill.
"""

from __future__ import annotations

from pybullet_swarm.tuning.objective import Direction, Objective, parse_objectives
from pybullet_swarm.tuning.space import ParamSpec, parse_param
from pybullet_swarm.tuning.study import SamplerKind, TuneResult, TuneSpec, run_tuning

__all__ = [
    "Direction",
    "Objective",
    "ParamSpec",
    "SamplerKind",
    "TuneResult",
    "TuneSpec",
    "parse_objectives",
    "parse_param",
    "run_tuning",
]
