"""Shared fixtures: small scenarios for physics tests."""

from __future__ import annotations

from typing import Any

import pytest

from pybullet_swarm.experiment.scenario import Scenario, load_scenario
from pybullet_swarm.experiment.simulation import Simulation


def physics_scenario(start_z: float = 1.0, vehicle: str = "quad150", **extra: Any) -> Scenario:
    """One agent starting at (1.5, 1.5, start_z) with a task that never completes by itself."""
    overrides: dict[str, Any] = {
        "agents.vehicle": vehicle,
        "agents.start": [[1.5, 1.5, start_z]],
        "task.time_limit_s": 1000.0,
        "task.waypoints": [{"t_s": 0.0, "position": [0.0, 0.0, 500.0]}],
    }
    overrides.update(extra)
    return load_scenario("hover", overrides)


@pytest.fixture
def make_sim():
    """Factory of simulations that are closed after the test."""
    sims: list[Simulation] = []

    def factory(scenario: Scenario, **kw: Any) -> Simulation:
        sim = Simulation(scenario, **kw)
        sims.append(sim)
        return sim

    yield factory
    for s in sims:
        s.close()
