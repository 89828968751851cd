"""The construction suite script: its layouts load with every planner, its table and figure, a tiny run."""

from __future__ import annotations

import copy
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from pybullet_swarm.experiment.scenario import apply_choices, build_scenario

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "construction_suite.py"


def _load():
    spec = importlib.util.spec_from_file_location("construction_suite", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(mod)
    return mod


suite = _load()


@pytest.mark.parametrize("name", list(suite.LAYOUTS))
def test_every_layout_loads_with_every_planner(name):
    data = suite.layout_data(name)
    for planner in suite.PLANNERS:
        s = build_scenario(apply_choices(copy.deepcopy(data), planner=planner, source=name), source=name)
        assert len(s.task.boxes) >= len(s.task.structure)


def test_the_suite_covers_what_it_promises():
    loaded = {n: build_scenario(suite.layout_data(n), source=n) for n in suite.LAYOUTS}
    assert len(loaded) >= 12
    agents = [s.agents.count for s in loaded.values()]
    assert min(agents) <= 3 and max(agents) == 20
    assert max(tuple(s.arena.size) for s in loaded.values()) == (6.0, 3.0)
    slots = {n: np.asarray(s.task.structure) for n, s in loaded.items()}

    def solid(p):  # two slots side by side at the box size
        d = np.abs(p[:, None, :] - p[None, :, :])
        return bool(np.any(np.isclose(d.max(axis=2), 0.1) & np.isclose(d[..., 2], 0.0)))

    assert solid(slots["solid_wall"]) and solid(slots["slab"]) and solid(slots["solid_stepped_wall"])
    assert len(slots["tower5"]) == 5 and np.ptp(slots["tower5"][:, 2]) == pytest.approx(0.4)
    assert isinstance(suite.layout_data("two_towers")["task"]["structure"], list)


def test_table_markdown_and_figure_from_rows(tmp_path):
    rows = [
        {"planner": "stigmergy", "avoidance": "orca", "exit_status": "completed", "completion_time_s": 100.0,
         "efficiency": 0.4, "boxes_placed": 5, "boxes_total": 5, "collisions.agent_agent": 0},
        {"planner": "stigmergy", "avoidance": "orca", "exit_status": "stalled", "boxes_placed": 2, "boxes_total": 5,
         "collisions.agent_agent": 2},
        {"planner": "shortest_path", "avoidance": "none", "exit_status": "crashed", "boxes_placed": 1,
         "boxes_total": 5, "collisions.agent_agent": 1, "collisions.agent_structure": 3, "crash_cause": "wake"},
    ]  # fmt: skip
    table = suite.table_rows("tower5", rows)
    by = {r["configuration"]: r for r in table}
    assert by["stigmergy + orca"]["completed"] == 1 and by["stigmergy + orca"]["stalled"] == 1
    assert by["stigmergy + orca"]["completion_rate"] == 0.5 and by["stigmergy + orca"]["efficiency_median"] == 0.4
    assert by["stigmergy + orca"]["contacts_agent_agent_per_run"] == 1.0
    assert by["shortest_path"]["crashed"] == 1 and math.isnan(by["shortest_path"]["completion_time_median_s"])
    text = suite.markdown(table)
    assert "| tower5 | stigmergy + orca | 1/2 | 0 |" in text
    assert by["shortest_path"]["crashed_wake"] == 1 and by["shortest_path"]["crashed_other"] == 0
    assert "| tower5 | shortest_path | 0/1 | 1 (0 / 1 / 0) |" in text
    from pybullet_swarm.plotting.suite_plots import suite_figure

    assert suite_figure(table, tmp_path / "suite.png").stat().st_size > 1000


def test_a_tiny_suite_runs_and_writes_its_table(tmp_path, capsys):
    out = tmp_path / "suite"
    args = ["--layouts", "tower5", "--planners", "shortest_path", "--avoidance", "none", "--seeds", "1"]
    assert suite.main([*args, "--workers", "1", "--out", str(out), "--quiet"]) == 0
    assert "| tower5 | shortest_path | 1/1 |" in (out / "suite.md").read_text()
    assert (out / "suite.png").is_file() and (out / "layouts" / "tower5.yaml").is_file()
