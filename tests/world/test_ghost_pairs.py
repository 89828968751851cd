"""Ghost pairs of the World: no contact response, overlaps reported as contacts, found by one broad phase.

The broad phase (bounding spheres, tested over all registered pairs at once or found by a k-d tree) must never
miss a pair that Bullet's exact closest-points query finds overlapping: every test here compares it
with that query run on every registered pair.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pybullet_swarm.rng import named_rng
from pybullet_swarm.vehicle import load_vehicle
from pybullet_swarm.world.world import BodyKind, World, _GhostIndex, sphere_pairs


def _crowd(n_agents: int, n_boxes: int) -> tuple[World, list[int], list[int]]:
    """A world with quad150 agents and 10 cm boxes (no gravity, nothing steps)."""
    p = load_vehicle("quad150")
    w = World(gravity=0.0)
    w.add_ground()
    starts = np.column_stack([np.arange(n_agents) * 0.5, np.zeros(n_agents), np.full(n_agents, 1.0)])
    w.add_agents(p.urdf_path, starts, mass=p.mass, inertia=p.inertia)
    boxes = [
        w.add_box([0.5 * k, 2.0, 1.0], [0.1] * 3, mass=0.01, kind=BodyKind.BOX, name=f"box{k}") for k in range(n_boxes)
    ]
    return w, list(w.agent_bodies), boxes


def _random_quaternions(rng: np.random.Generator, k: int) -> np.ndarray:
    q = rng.normal(size=(k, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _scatter(w: World, agents: list[int], boxes: list[int], rng: np.random.Generator, side: float) -> None:
    """Put every body at a random pose in a cube of edge ``side`` m (crowded: many overlaps)."""
    pos = rng.uniform(0.0, side, size=(len(agents) + len(boxes), 3)) + [0.0, 0.0, 1.0]
    quat = _random_quaternions(rng, len(pos))
    for i in range(len(agents)):
        w.reset_agent(i, pos[i], quat[i])
    for k, b in enumerate(boxes):
        w.reset_body(b, pos[len(agents) + k], quat[len(agents) + k])


def _brute_force(w: World) -> set[tuple[int, int]]:
    return {pair for pair in w.ghost_pairs if w.overlapping(*pair)}


@pytest.mark.parametrize("dense", [True, False], ids=["every_pair", "kdtree"])
def test_ghost_overlaps_are_exactly_the_registered_pairs_that_overlap(monkeypatch, dense):
    if not dense:
        monkeypatch.setattr(_GhostIndex, "DENSE_MAX_BODIES", 0)
    rng = named_rng(0, "test/ghost_pairs")
    w, agents, boxes = _crowd(8, 6)
    with w:
        w.set_agent_collisions(False)
        # some boxes are ghosts of some agents and of each other (loads), the last one of nothing
        for a, b in itertools.product(agents[:5], boxes[:3]):
            w.set_ghost_pair(a, b, True)
        w.set_ghost_pair(boxes[0], boxes[1], True)
        w.set_ghost_pair(boxes[3], agents[6], True)
        w.set_pair_collision(boxes[3], agents[7], False)  # a grip: contacts off, overlaps not counted
        found = 0
        for _ in range(60):
            _scatter(w, agents, boxes, rng, side=0.5)
            expected = _brute_force(w)
            assert set(w.ghost_overlaps()) == expected
            found += len(expected)
        assert found > 100  # crowded enough that the comparison means something


@pytest.mark.parametrize("dense", [True, False], ids=["every_pair", "kdtree"])
def test_grazing_overlaps_are_found(monkeypatch, dense):
    """Pairs turned at random and moved apart along a random direction until they barely touch (within
    0.5 mm): where a too-small bounding sphere would miss them first."""
    if not dense:
        monkeypatch.setattr(_GhostIndex, "DENSE_MAX_BODIES", 0)
    rng = named_rng(1, "test/ghost_grazing")
    w, agents, boxes = _crowd(2, 2)
    with w:
        w.set_agent_collisions(False)
        w.set_ghost_pair(agents[0], boxes[0], True)
        w.set_ghost_pair(boxes[0], boxes[1], True)
        home = np.array([1.0, 1.0, 1.0])
        for trial in range(90):
            a, b = [(agents[0], agents[1]), (agents[0], boxes[0]), (boxes[0], boxes[1])][trial % 3]
            qa, qb = _random_quaternions(rng, 2)
            u = rng.normal(size=3)
            u /= np.linalg.norm(u)
            place = {a: (home, qa)}
            lo, hi = 0.0, 0.5  # m: overlapping at lo, apart at hi
            while hi - lo > 5e-4:
                mid = 0.5 * (lo + hi)
                place[b] = (home + mid * u, qb)
                _put(w, agents, place)
                lo, hi = (mid, hi) if w.overlapping(a, b) else (lo, mid)
            place[b] = (home + lo * u, qb)
            _put(w, agents, place)
            assert (min(a, b), max(a, b)) in w.ghost_overlaps()


def _put(w: World, agents: list[int], poses: dict[int, tuple[np.ndarray, np.ndarray]]) -> None:
    for body, (p, q) in poses.items():
        if body in agents:
            w.reset_agent(agents.index(body), p.tolist(), q.tolist())
        else:
            w.reset_body(body, p.tolist(), q.tolist())


def test_a_ghost_pair_is_reported_as_a_contact_and_only_while_registered():
    w, agents, boxes = _crowd(2, 1)
    with w:
        a, b = agents
        w.reset_agent(1, [0.08, 0.0, 1.0])  # 15 cm airframes 8 cm apart: overlapping
        pair = (min(a, b), max(a, b))
        w.step()
        assert pair in w.contact_pairs()  # contacts on: Bullet's own contact
        w.set_ghost_pair(a, b, True)
        w.step()
        assert pair in w.contact_pairs()  # contacts off: the overlap is still reported
        assert w.ghost_pairs == {pair}
        w.set_pair_collision(a, b, False)  # off and not counted (a grip)
        w.step()
        assert pair not in w.contact_pairs()
        assert w.ghost_pairs == frozenset()
        w.set_ghost_pair(a, b, True)
        w.set_ghost_pair(a, b, False)  # contacts back on
        w.reset_agent(0, [0.0, 0.0, 1.0])
        w.reset_agent(1, [0.08, 0.0, 1.0])
        w.step()
        assert pair in w.contact_pairs()
        assert w.ghost_pairs == frozenset()


def test_ghost_bodies_apart_report_nothing():
    w, agents, boxes = _crowd(3, 2)
    with w:
        w.set_agent_collisions(False)
        for a in agents:
            w.set_ghost_pair(a, boxes[0], True)
        w.step()
        assert w.ghost_overlaps() == []
        assert not any(a in pair and b in pair for pair in w.contact_pairs() for a in agents for b in agents)


def _layout(kind: str, k: int, rng: np.random.Generator) -> np.ndarray:
    if kind == "uniform":
        return rng.uniform(-0.5, 0.7, size=(k, 3))
    if kind == "lattice":  # 10 cm, 20 cm and 30 cm apart along x, y, z, nudged: pairs along every axis and diagonal
        side = int(np.ceil(k ** (1 / 3)))
        ijk = np.array(list(itertools.product(range(side), repeat=3))[:k], dtype=float).reshape(-1, 3)
        return ijk * [0.1, 0.2, 0.3] + rng.normal(0.0, 0.01, size=(k, 3))
    return rng.normal(0.0, 0.05, size=(k, 3))  # "cluster": nearly all in one cell


@pytest.mark.parametrize("layout", ["uniform", "lattice", "cluster"])
@pytest.mark.parametrize("k", [0, 1, 2, 7, 300])
def test_sphere_pairs_finds_every_overlapping_pair_once(k, layout):
    rng = named_rng(k, f"test/sphere_pairs/{layout}")
    centres = _layout(layout, k, rng)
    radii = rng.uniform(0.02, 0.12, size=k)
    i, j = sphere_pairs(centres, radii, slack=0.01)
    got = {(min(a, b), max(a, b)) for a, b in zip(i.tolist(), j.tolist())}
    assert len(got) == len(i)  # each pair once
    expected = {
        (a, b)
        for a, b in itertools.combinations(range(k), 2)
        if np.linalg.norm(centres[a] - centres[b]) <= radii[a] + radii[b] + 0.01
    }
    assert got == expected
    if k == 300:
        assert len(expected) > 50


def _crossing(horizon: int, push: float = 0.0) -> tuple[World, list[list[tuple[int, int]]]]:
    """Six agents flying through each other and two boxes at 1-3 m/s (no gravity) for 0.5 s: the
    ghost overlaps found after every physics step with a broad phase every ``horizon`` steps. ``push`` N: a
    force on agent 0 from the 10th step on (an acceleration no vehicle has)."""
    p = load_vehicle("quad150")
    w = World(gravity=0.0, ghost_horizon=horizon)
    w.add_ground()
    rng = named_rng(0, "test/ghost_horizon")
    starts = np.column_stack([rng.uniform(0.0, 0.6, 6), rng.uniform(0.0, 0.6, 6), np.full(6, 1.0)])
    w.add_agents(p.urdf_path, starts, mass=p.mass, inertia=p.inertia)
    agents = list(w.agent_bodies)
    boxes = [w.add_box([0.3, 0.3 * k, 1.0], [0.1] * 3, mass=0.01, kind=BodyKind.BOX) for k in range(2)]
    w.set_agent_collisions(False)
    for a in agents[1:]:
        w.set_ghost_pair(a, boxes[0], True)
    w.set_ghost_pair(boxes[0], boxes[1], True)
    w.set_pair_collision(agents[0], boxes[0], False)
    # every agent heads for the middle of the group, so that pairs cross
    heading = [0.3, 0.3, 1.0] - starts
    heading /= np.linalg.norm(heading, axis=1, keepdims=True)
    for i in range(6):
        w.reset_agent(i, starts[i], velocity=(rng.uniform(1.0, 3.0) * heading[i]).tolist())
    states = np.zeros((6, 13))
    found = []
    for k in range(120):
        if push and k >= 10:
            w.apply_agent_wrenches(np.array([[push, 0.0, 0.0]] + [[0.0, 0.0, 0.0]] * 5), np.zeros((6, 3)))
        w.step()
        w.read_agent_states(states)
        found.append(sorted(w.ghost_overlaps()))
    return w, found


@pytest.mark.parametrize("sphere_test", [False, True], ids=["exact_query", "sphere_test_first"])
@pytest.mark.parametrize("push", [0.0, 60.0], ids=["flying", "pushed"])
def test_a_broad_phase_over_a_horizon_finds_what_one_every_step_finds(monkeypatch, push, sphere_test):
    """Bodies crossing each other: the same overlaps after every step whether the broad phase runs every
    step or once per 5 steps (its spheres grown by how far each body can move meanwhile; candidate pairs of
    two agents tested with their spheres every step, or not). A body pushed harder than
    ``GHOST_MAX_ACCELERATION`` allows is caught at the next broad phase, which then runs every step."""
    monkeypatch.setattr(World, "SPHERE_TEST_MIN_PAIRS", 1 if sphere_test else 10**6)
    monkeypatch.setattr(_GhostIndex, "DENSE_MAX_BODIES", 0)  # the horizon serves the k-d tree's broad phase
    every, expected = _crossing(1, push)
    horizon, got = _crossing(5, push)
    with every, horizon:
        assert sum(len(f) for f in expected) > 20  # the bodies do overlap
        if push:  # what the broad phase may have missed before it caught the push is not asserted
            assert horizon.ghost_bound_exceeded == 1 and horizon.ghost_horizon == 1
            assert got[20:] == expected[20:]
        else:
            assert horizon.ghost_bound_exceeded == 0 and horizon.ghost_horizon == 5
            assert got == expected


def test_a_teleport_ends_the_horizon(monkeypatch):
    monkeypatch.setattr(_GhostIndex, "DENSE_MAX_BODIES", 0)
    w, agents, boxes = _crowd(2, 0)
    with w:
        w.ghost_horizon = 5
        w.set_agent_collisions(False)
        states = np.zeros((2, 13))
        w.read_agent_states(states)
        assert w.ghost_overlaps() == []
        w.reset_agent(1, [0.08, 0.0, 1.0])  # onto agent 0, within the horizon
        w.read_agent_states(states)
        assert w.ghost_overlaps() == [(min(agents), max(agents))]


def test_few_ghost_bodies_get_a_broad_phase_every_step():
    w, agents, boxes = _crowd(3, 0)
    with w:
        w.ghost_horizon = 5
        w.set_agent_collisions(False)
        w.read_agent_states(np.zeros((3, 13)))
        assert w.ghost_overlaps() == [] and w._ghost_plan is None
