"""pybullet_swarm: a testbed for quadrotor swarms in PyBullet.

Scripted use::

    import pybullet_swarm as ps
    scenario = ps.load_scenario("hover", overrides={"agents.vehicle": "cf2x"})
    result = ps.run(scenario, seed=1)            # nothing written unless out= is given
    result.exit_status, result.metrics["tracking_rmse_m"], result.timeseries.positions.shape
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

__all__ = [
    "ConfigError",
    "ExitStatus",
    "RunResult",
    "Scenario",
    "Simulation",
    "SwarmState",
    "Sweep",
    "load_scenario",
    "load_vehicle",
    "run",
    "run_sweep",
]

if TYPE_CHECKING:  # pragma: no cover
    from pybullet_swarm.errors import ConfigError
    from pybullet_swarm.experiment.runner import run
    from pybullet_swarm.experiment.scenario import Scenario, load_scenario
    from pybullet_swarm.experiment.simulation import RunResult, Simulation
    from pybullet_swarm.types import ExitStatus, SwarmState
    from pybullet_swarm.vehicle import load_vehicle

_LAZY = {
    "ConfigError": "pybullet_swarm.errors",
    "run": "pybullet_swarm.experiment.runner",
    "Scenario": "pybullet_swarm.experiment.scenario",
    "load_scenario": "pybullet_swarm.experiment.scenario",
    "RunResult": "pybullet_swarm.experiment.simulation",
    "Simulation": "pybullet_swarm.experiment.simulation",
    "ExitStatus": "pybullet_swarm.types",
    "SwarmState": "pybullet_swarm.types",
    "load_vehicle": "pybullet_swarm.vehicle",
    "Sweep": "pybullet_swarm.experiment.sweep",
    "run_sweep": "pybullet_swarm.experiment.sweep",
}


def __getattr__(name: str) -> Any:
    """Import the public API lazily, so that ``import pybullet_swarm`` stays cheap."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'pybullet_swarm' has no attribute {name!r}")
