"""The large layouts of the benchmark: 50 agents with 100 boxes (``construction_large``), and a 1,000-agent
hover swarm. ``check`` builds the large construction run; the slow tests fly both for a few seconds."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.cli.main import main
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.experiment.simulation import Simulation
from pybullet_swarm.types import ExitStatus


def test_check_builds_the_large_construction_layout(capsys: pytest.CaptureFixture[str]) -> None:
    assert (
        main(["check", "construction_large", "--set", "planner.name=stigmergy", "--set", "avoidance=orca", "--quiet"])
        == 0
    )
    s = load_scenario("construction_large")
    boxes, slots = np.asarray(s.task.boxes), np.asarray(s.task.structure)
    assert (s.agents.count, len(boxes), len(slots)) == (50, 100, 100)
    starts = s.start_positions(0.0)
    assert len(starts) == 50
    # the start grid lies between depot and wall, clear of both by more than an airframe
    assert starts[:, 0].min() > boxes[:, 0].max() + 0.2
    assert starts[:, 0].max() < slots[:, 0].min() - 0.2
    assert np.all((starts[:, :2] > 0.0) & (starts[:, :2] < np.asarray(s.arena.size)))


@pytest.mark.slow
def test_fifty_agents_build_the_large_layout_with_stigmergy_and_orca(make_sim) -> None:
    sim = make_sim(
        load_scenario("construction_large", {"task.time_limit_s": 25.0}), planner="stigmergy", avoidance="orca"
    )
    result = sim.run()
    assert result.exit_status is ExitStatus.TIMEOUT
    assert result.metrics["grasps"] >= 5  # the swarm took boxes from the depot
    assert np.all(sim.max_height > 0.2)  # every agent took off


@pytest.mark.slow
def test_a_thousand_agents_hover() -> None:
    scenario = load_scenario(
        "hover_swarm",
        {
            "agents.count": 1000,
            "agents.vehicle": "cf2x",
            "agents.spacing": 0.3,
            "task.time_limit_s": 3.0,
            "task.waypoints": [{"t_s": 0.0, "position": [0.0, 0.0, 0.3]}],
            "task.hold_s": 100.0,
        },
    )
    with Simulation(scenario, record=False) as sim:
        start = sim.state_array[:, :3].copy()
        assert sim.run().exit_status is ExitStatus.TIMEOUT
        z = sim.state_array[:, 2]
        assert np.all(np.abs(z - (start[:, 2] + 0.3)) < 0.05)  # every agent climbed to its set-point and holds
        assert np.allclose(sim.state_array[:, :2], start[:, :2], atol=0.05)
