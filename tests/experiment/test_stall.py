"""Stall detection: a run whose task makes no progress for the task's stall time ends as stalled."""

from __future__ import annotations

import csv
import json

import pybullet_swarm
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.types import ExitStatus

# one agent, a box three times heavier than it can lift: it grasps the box, then hangs there for ever
HEAVY = {"task.box_mass": 0.3, "task.stall_time_s": 20.0, "task.time_limit_s": 200.0}


def test_a_run_that_cannot_progress_ends_stalled_and_names_what_each_agent_was_doing(tmp_path):
    res = pybullet_swarm.run(load_scenario("construction_single", HEAVY), seed=0, out=tmp_path / "run", plots=False)
    assert res.exit_status is ExitStatus.STALLED
    m = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert m["exit_status"] == "stalled" and m["boxes_placed"] == 0
    grasp = next(e for e in res.events if e.kind == "grasp")  # the last progress: the first grasp
    assert 20.0 <= m["sim_time_s"] - grasp.time_s <= 20.2
    rows = list(csv.DictReader((tmp_path / "run" / "events.csv").open()))
    stalled = [r for r in rows if r["kind"] == "stalled"]
    agents = [r for r in rows if r["kind"] == "stalled_agent"]
    assert len(stalled) == 1 and "no task progress for 20 s" in stalled[0]["detail"]
    assert [r["a"] for r in agents] == ["agent0"]
    assert agents[0]["b"] == grasp.b  # the box it holds
    assert "phase lift" in agents[0]["detail"] and "target" in agents[0]["detail"]


def test_stall_detection_can_be_switched_off():
    sc = load_scenario("construction_single", {**HEAVY, "task.stall_time_s": None, "task.time_limit_s": 40.0})
    res = pybullet_swarm.run(sc, seed=0)
    assert res.exit_status is ExitStatus.TIMEOUT
    assert not any(e.kind.startswith("stalled") for e in res.events)


def test_decentralised_agents_say_their_phase_and_the_box_they_go_for():
    sc = load_scenario("construction", {**HEAVY, "task.stall_time_s": 3.5})
    res = pybullet_swarm.run(sc, planner="stigmergy", seed=0)
    assert res.exit_status is ExitStatus.STALLED  # the agents take off and head for boxes: none grasped in 3.5 s
    assert res.metrics["sim_time_s"] == 3.5
    agents = [e for e in res.events if e.kind == "stalled_agent"]
    assert [e.a for e in agents] == [f"agent{i}" for i in range(5)]
    assert all(e.detail.startswith("phase ") and " box " in e.detail for e in agents)


def test_progress_counts_first_grasps_and_new_heights_of_the_structure(make_sim):
    sim = make_sim(load_scenario("construction_single"))
    c = sim.task
    assert c.progress() == 0 and c.stall_time_s == 150.0
    c.ever_grasped[3] = True
    assert c.progress() == 1
    c.slot_box[:2] = [0, 1]
    c.most_placed = max(c.most_placed, c.boxes_placed)
    assert c.progress() == 3
    c.slot_box[1] = -1  # a box knocked out and put back is no progress
    c.slot_box[1] = 1
    assert c.progress() == 3
