"""The flock task: refused input, metrics keys, every flocking planner on both scenarios, determinism."""

from __future__ import annotations

import pytest

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.experiment.simulation import Simulation
from pybullet_swarm.metrics.flock import FLOCK_KEYS

SMALL = ["agents.count=6", "task.time_limit_s=12", "task.warmup_s=4", "arena.size=[8.0, 8.0]", "agents.spacing=1.0"]


@pytest.mark.parametrize("scenario", ["flocking_confined", "flocking_obstacles"])
@pytest.mark.parametrize("planner", ["vasarhelyi", "olfati_saber", "reynolds"])
def test_bundled_scenarios_load_with_every_flocking_planner(scenario: str, planner: str) -> None:
    s = load_scenario(scenario, planner=planner)
    assert s.planner.name == planner and s.agents.count == 30 and s.arena.walls


@pytest.mark.parametrize(
    ("override", "field"),
    [("task.warmup_s=700", "task.warmup_s"), ("task.altitude=3.0", "task.altitude"), ("task.r_coll=-1", "task.r_coll")],
)
def test_bad_input_is_refused_naming_the_field(override: str, field: str) -> None:
    with pytest.raises(ConfigError, match=field.replace(".", r"\.")):
        load_scenario("flocking_confined", [override])


def test_metrics_keys_and_determinism() -> None:
    runs = []
    for _ in range(2):
        with Simulation(load_scenario("flocking_confined", SMALL)) as sim:
            runs.append(sim.run())
    a, b = runs
    assert list(a.metrics["flock"]) == list(FLOCK_KEYS)
    assert a.metrics["flock"] == b.metrics["flock"]
    assert (a.timeseries.positions == b.timeseries.positions).all()
    assert a.metrics["flock"]["max_cluster"] == 6.0
    assert a.metrics["flock_min_distance_m"] > 0.3
