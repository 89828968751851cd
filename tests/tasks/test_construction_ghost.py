"""Ghost mode counts what physical mode counts: the same overlaps of agents and carried boxes, placed in
both modes, give the same contact pairs and the same counts per class (agent with agent, agent with a
carried box, carried box with carried box, carried box with the structure)."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.tasks.construction import PLACED

MIDFIELD = np.array([1.6, 0.5, 0.8])  # m, clear of the depot, the structure and the agents' starts


def _sim(make_sim, mode: str):
    """The construction task held still from outside: no planner acts, rotors at hover speed."""
    sim = make_sim(load_scenario("construction", {"collisions": mode, "agents.start_jitter": 0.0}))
    sim.set_targets(sim.state.positions)
    sim.set_open_loop(np.full((sim.n, 4), sim.params.hover_rotor_speed(sim.scenario.sim.gravity)), motor_state=True)
    return sim


def _carry(sim, agent: int, box: int, at) -> None:
    """Agent ``agent`` grasps box ``box`` and is put, with the box under it, at ``at`` (3,) m."""
    c = sim.task
    sim.world.reset_agent(agent, c.grasp_points()[box])
    assert c.grasp(agent, sim.world.agent_bodies[agent], c.grasp_points()[box], sim.time) == box
    _move(sim, agent, at)


def _move(sim, agent: int, at) -> None:
    """Put an agent (and the box it holds, if any) at ``at`` (3,) m."""
    at = np.asarray(at, dtype=float)
    sim.world.reset_agent(agent, at)
    held = sim.task.carrying(sim.n)[agent]
    if held >= 0:
        sim.world.reset_body(sim.task.bodies[held], at - [0.0, 0.0, sim.task.grasp_height])


def _agent_agent(sim) -> None:
    _move(sim, 0, MIDFIELD)
    _move(sim, 1, MIDFIELD + [0.1, 0.0, 0.0])  # 15 cm airframes 10 cm apart


def _agent_in_carried_box(sim) -> None:
    _carry(sim, 0, 0, MIDFIELD)
    _move(sim, 1, MIDFIELD - [0.0, 0.0, sim.task.grasp_height])  # in the box agent 0 holds


def _carried_boxes(sim) -> None:
    # the 10 cm boxes overlap by 1 cm along x and z (agent 1 then also reaches into agent 0's box)
    _carry(sim, 0, 0, MIDFIELD)
    _carry(sim, 1, 1, MIDFIELD + [0.09, 0.0, -0.09])


def _carried_box_on_structure(sim) -> None:
    c = sim.task
    sim.world.reset_body(c.bodies[2], c.slots[0])
    c.update(sim.time)
    assert c.state[2] == PLACED
    _carry(sim, 0, 0, c.slots[0] + [0.0, 0.0, 0.09 + c.grasp_height])  # 1 cm into the placed box


CASES = {
    "agent_agent": (_agent_agent, lambda c: [("agent", 0), ("agent", 1)], {"agent_agent": 1}),
    "agent_in_carried_box": (_agent_in_carried_box, lambda c: [("agent", 1), ("box", 0)], {"agent_box": 1}),
    "carried_boxes": (_carried_boxes, lambda c: [("box", 0), ("box", 1)], {"agent_box": 1, "load_load": 1}),
    "carried_box_on_structure": (
        _carried_box_on_structure,
        lambda c: [("box", 0), ("box", 2)],
        {"load_structure": 1},
    ),
}


def _body(sim, ref: tuple[str, int]) -> int:
    kind, k = ref
    return sim.world.agent_bodies[k] if kind == "agent" else sim.task.bodies[k]


def _place_and_step(make_sim, mode: str, case: str):
    place, refs, _ = CASES[case]
    sim = _sim(make_sim, mode)
    place(sim)
    sim.step(1)
    a, b = (_body(sim, r) for r in refs(sim))
    touching = (min(a, b), max(a, b)) in sim.world.contact_pairs()
    sim.step(4)
    return sim, touching


@pytest.mark.parametrize("case", list(CASES))
def test_the_same_overlap_counts_the_same_in_ghost_and_physical_mode(make_sim, case):
    counts, touching = {}, {}
    for mode in ("physical", "ghost"):
        sim, touching[mode] = _place_and_step(make_sim, mode, case)
        counts[mode] = dict(sim.contacts.counts)
        assert sim.exit_status.value == "running"
    expected = {k: 0 for k in counts["physical"]} | CASES[case][2]
    assert counts["physical"] == expected
    assert counts["ghost"] == expected
    assert touching == {"physical": True, "ghost": True}


def test_ghost_mode_passes_a_carried_box_through_an_agent(make_sim):
    """Ghost mode lets the agent stay inside the box (no contact response) and keeps it one onset."""
    sim, _ = _place_and_step(make_sim, "ghost", "agent_in_carried_box")
    sim.step(20)
    assert sim.contacts.counts["agent_box"] == 1
    assert sim.contacts.time_s["agent_box"] == pytest.approx(25 * sim.dt)
    box = sim.task.bodies[0]
    assert pytest.approx(sim.world.body_pose(box)[0], abs=0.01) == sim.state.positions[1]


def test_a_released_box_has_its_contacts_again_and_is_no_ghost(make_sim):
    sim = _sim(make_sim, "ghost")
    _carry(sim, 0, 0, MIDFIELD)
    _carry(sim, 1, 1, MIDFIELD + [0.5, 0.0, 0.0])
    box0, box1 = sim.task.bodies[0], sim.task.bodies[1]
    agents = sim.world.agent_bodies
    pairs = sim.world.ghost_pairs
    assert (min(box0, box1), max(box0, box1)) in pairs
    assert (min(agents[0], box0), max(agents[0], box0)) not in pairs  # the grip is not counted
    assert all((min(a, box0), max(a, box0)) in pairs for a in agents[1:])
    sim.task.release(0, agents[0], sim.time)
    assert not any(box0 in p for p in sim.world.ghost_pairs)
    assert (min(agents[2], box1), max(agents[2], box1)) in sim.world.ghost_pairs


def test_a_ghost_run_counts_what_a_brute_force_check_of_every_ghost_pair_counts(monkeypatch):
    """30 s of stigmergy without avoidance in ghost mode (agents and loads cross often): the same contact
    events as with Bullet's exact query run on every registered pair every physics step."""
    from pybullet_swarm.experiment.simulation import Simulation
    from pybullet_swarm.world.world import World

    def run():
        sc = load_scenario("construction", {"task.time_limit_s": 30.0})
        with Simulation(sc, planner="stigmergy", avoidance="none", seed=0, record=False) as sim:
            sim.run()
            return dict(sim.contacts.counts), [(e.time_s, e.kind, e.a, e.b) for e in sim.events]

    counts, events = run()
    monkeypatch.setattr(World, "ghost_overlaps", lambda w: [p for p in w.ghost_pairs if w.overlapping(*p)])
    assert run() == (counts, events)
    assert counts["agent_agent"] > 0 and counts["agent_box"] > 0
