"""A run reproduces from its own ``scenario.yaml``: for every bundled scenario, a run with a planner, an
avoidance layer, a seed and ``--set`` overrides given on the command line, run again from the
``scenario.yaml`` it wrote, gives the same metrics (wall-clock timings aside), the same events and
the same time series; and that ``scenario.yaml`` names the planner, the layer, the seed and every
parameter with its resolved value."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from pybullet_swarm.cli.main import main
from pybullet_swarm.planning.registry import avoidance_layers, planners
from pybullet_swarm.resources import bundled_scenarios

#: one short waypoint (the bundled waypoint tasks last 30-80 s)
SHORT_WAYPOINTS = ["--set", "task.waypoints=[{t_s: 0, position: [0.0, 0.0, 1.0]}]"]

#: scenario -> command-line choices and overrides (every run shortened to a few simulated seconds)
CASES: dict[str, list[str]] = {
    "construction": ["--planner", "stigmergy", "--avoidance", "orca", "--seed", "3", "--set", "task.time_limit_s=12"],
    # 6 of the 50 agents (the start grid follows agents.count), for 2 simulated seconds
    "construction_large": [
        "--planner",
        "stigmergy",
        "--avoidance",
        "orca",
        "--seed",
        "2",
        "--set",
        "task.time_limit_s=2",
        "--set",
        "agents.count=6",
    ],
    "construction_single": [
        "--planner",
        "shortest_path",
        "--avoidance",
        "braitenberg",
        "--seed",
        "1",
        "--set",
        "task.time_limit_s=4",
        "--set",
        "planner.params.altitude_step=0.1",
    ],
    "estimation": [
        "--planner",
        "waypoints",
        "--avoidance",
        "orca",
        "--seed",
        "2",
        "--set",
        "task.time_limit_s=4",
        *SHORT_WAYPOINTS,
    ],
    "flocking": [
        "--planner",
        "reynolds",
        "--avoidance",
        "orca",
        "--seed",
        "4",
        "--set",
        "task.time_limit_s=3",
        "--set",
        "planner.params.w_cohesion=0.3",
    ],
    # 6 of the 30 agents, another planner than the file's
    "flocking_confined": [
        "--planner",
        "olfati_saber",
        "--avoidance",
        "none",
        "--seed",
        "9",
        "--set",
        "task.time_limit_s=3",
        "--set",
        "task.warmup_s=1",
        "--set",
        "agents.count=6",
    ],
    "flocking_obstacles": [
        "--planner",
        "vasarhelyi",
        "--avoidance",
        "none",
        "--seed",
        "10",
        "--set",
        "task.time_limit_s=3",
        "--set",
        "task.warmup_s=1",
        "--set",
        "agents.count=6",
        "--set",
        "planner.params.p_rep=0.2",
    ],
    # another planner and layer than the file's: the file's parameters of laplacian and braitenberg are dropped
    "formation": [
        "--planner",
        "reynolds",
        "--avoidance",
        "orca",
        "--seed",
        "5",
        "--set",
        "task.time_limit_s=3",
        "--set",
        "avoidance_params.time_horizon=1.0",
    ],
    "hover": [
        "--planner",
        "waypoints",
        "--avoidance",
        "braitenberg",
        "--seed",
        "6",
        "--set",
        "task.time_limit_s=3",
        *SHORT_WAYPOINTS,
        "--set",
        "avoidance_params.memory_s=1.0",
    ],
    "hover_swarm": [
        "--planner",
        "waypoints",
        "--avoidance",
        "orca",
        "--seed",
        "7",
        "--set",
        "task.time_limit_s=3",
        *SHORT_WAYPOINTS,
        "--set",
        "agents.count=4",
    ],
    "tour": [
        "--planner",
        "aco_tour",
        "--avoidance",
        "orca",
        "--seed",
        "8",
        "--set",
        "task.time_limit_s=3",
        "--set",
        "planner.params.iterations=20",
    ],
}


def _without_wall_clock(m: Any) -> Any:
    """Metrics without the wall-clock fields (wall_time_s, real_time_factor, *_ms timings)."""
    if isinstance(m, dict):
        return {
            k: _without_wall_clock(v)
            for k, v in m.items()
            if k not in ("wall_time_s", "real_time_factor") and not k.endswith("_ms")
        }
    return m


def _option(argv: list[str], name: str) -> str:
    return argv[argv.index(name) + 1]


def test_every_bundled_scenario_has_a_case() -> None:
    assert sorted(CASES) == sorted(bundled_scenarios())


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_run_reproduces_from_its_own_scenario_yaml(name: str, tmp_path: Path) -> None:
    argv = CASES[name]
    a, b = tmp_path / "A", tmp_path / "B"
    assert main(["run", name, *argv, "--out", str(a), "--no-plots", "--quiet"]) == 0
    assert main(["run", str(a / "scenario.yaml"), "--out", str(b), "--no-plots", "--quiet"]) == 0

    data = yaml.safe_load((a / "scenario.yaml").read_text())
    planner, avoidance, seed = _option(argv, "--planner"), _option(argv, "--avoidance"), int(_option(argv, "--seed"))
    assert (data["planner"]["name"], data["avoidance"], data["seed"]) == (planner, avoidance, seed)
    assert set(data["planner"]["params"]) == set(planners()[planner].params.model_fields)
    assert set(data["avoidance_params"]) == set(avoidance_layers()[avoidance].params.model_fields)
    assert data == yaml.safe_load((b / "scenario.yaml").read_text())  # the resolved scenario is a fixed point

    ma = json.loads((a / "metrics.json").read_text())
    mb = json.loads((b / "metrics.json").read_text())
    assert (ma["planner"], ma["avoidance"], ma["seed"]) == (planner, avoidance, seed)
    assert _without_wall_clock(ma) == _without_wall_clock(mb)
    assert (a / "events.csv").read_text() == (b / "events.csv").read_text()
    with np.load(a / "timeseries.npz") as ta, np.load(b / "timeseries.npz") as tb:
        assert sorted(ta.files) == sorted(tb.files)
        for key in ta.files:
            assert np.array_equal(ta[key], tb[key]), key


def test_the_resolved_scenario_holds_the_overrides_and_every_default(tmp_path: Path) -> None:
    argv = CASES["construction"]
    assert (
        main(
            [
                "run",
                "construction",
                *argv,
                "--set",
                "planner.params.fatigue=0.01",
                "--out",
                str(tmp_path),
                "--no-plots",
                "--quiet",
            ]
        )
        == 0
    )
    data = yaml.safe_load((tmp_path / "scenario.yaml").read_text())
    assert data["task"]["time_limit_s"] == 12.0
    params = data["planner"]["params"]
    assert params["fatigue"] == 0.01  # the override
    assert (params["cell_size"], params["ties"], params["release_dwell_s"]) == (0.1, "random", None)  # defaults
    assert data["avoidance_params"]["time_horizon"] == 1.5 and data["avoidance_params"]["shape"] == "box"


def test_formation_switched_to_another_planner_and_layer_drops_the_files_parameters(tmp_path: Path) -> None:
    assert main(["check", "formation", "--quiet"]) == 0
    from pybullet_swarm.experiment.scenario import load_scenario

    own = load_scenario("formation")
    assert own.planner.params["gain"] == 0.5 and own.avoidance_params.on_threshold == 0.55  # the file's
    other = load_scenario("formation", planner="reynolds", avoidance="orca")
    assert other.planner.params == planners()["reynolds"].params().model_dump(mode="json")
    assert other.avoidance_params == avoidance_layers()["orca"].params()
