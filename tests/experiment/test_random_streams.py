"""Random generators by name: a consumer's draws depend on the seed and its name only."""

from __future__ import annotations

import numpy as np

from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.experiment.simulation import Simulation
from pybullet_swarm.rng import named_rng, stream_key


def test_a_stream_depends_on_seed_and_name_only() -> None:
    a = named_rng(3, "planner/0").random(4)
    assert np.array_equal(a, named_rng(3, "planner/0").random(4))
    assert not np.array_equal(a, named_rng(3, "planner/1").random(4))
    assert not np.array_equal(a, named_rng(4, "planner/0").random(4))
    assert stream_key("range_noise") == stream_key("range_noise")
    assert stream_key("range_noise") != stream_key("range_noise ")


def _planner_draws(overrides: list[str]) -> tuple[np.ndarray, np.ndarray]:
    sc = load_scenario("construction", [*overrides, "planner.name=stigmergy", "agents.start_jitter=0.02"])
    sim = Simulation(sc, seed=5)
    try:
        assert sim.agent_planners is not None
        draws = np.array([pl.rng.random(3) for pl in sim.agent_planners])
        return draws, sim.starts.copy()
    finally:
        sim.close()


def test_switching_sensors_on_does_not_change_planner_draws_or_starts() -> None:
    base, starts = _planner_draws([])
    for extra in (
        ["sensing.range.enabled=true"],
        ["sensing.run_estimator=true"],
        ["sensing.state=estimated", "sensing.range.enabled=true"],
    ):
        draws, again = _planner_draws(extra)
        assert np.array_equal(draws, base), extra
        assert np.array_equal(again, starts), extra
    # and the agents' streams differ from each other
    assert len({tuple(row) for row in base}) == len(base)
