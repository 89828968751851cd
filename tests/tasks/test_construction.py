"""The construction task: grasp and release physics, slot order, validation, completion, full runs."""

from __future__ import annotations

import numpy as np
import pytest

import pybullet_swarm
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.tasks.construction import CARRIED, FREE, PLACED
from pybullet_swarm.types import ExitStatus


def _hover_to(sim, target, seconds):
    sim.set_targets(np.asarray(target, dtype=float).reshape(sim.n, 3))
    sim.step(int(seconds * sim.physics_hz))


def _fly_down_and_grasp(sim, box, point):
    """Agent 0 flies over ``point`` at 0.45 m, down to it, grasps ``box`` and takes on its load."""
    c = sim.task
    _hover_to(sim, [point[0], point[1], 0.45], 12)
    _hover_to(sim, point, 6)
    assert c.grasp(0, sim.world.agent_bodies[0], sim.state.positions[0], sim.time) == box
    sim.controller.set_payload(0, c.spec.box_mass + sim.own_wake_load(c.spec.box_mass))


def test_carried_box_follows_and_released_box_settles_in_its_slot(make_sim):
    sim = make_sim(load_scenario("construction_single", {"agents.start_jitter": 0.0}))
    c = sim.task
    box = 4
    grasp = c.grasp_points()[box]
    _fly_down_and_grasp(sim, box, grasp)
    assert np.linalg.norm(sim.state.positions[0] - grasp) < c.spec.attach_threshold
    assert c.state[box] == CARRIED
    _hover_to(sim, [grasp[0], grasp[1], 0.45], 5)
    c.read()
    lifted = c.positions[box] - sim.state.positions[0]
    assert c.positions[box, 2] > 0.3  # it came up with the agent
    assert np.allclose(lifted, [0.0, 0.0, -c.grasp_height], atol=0.01)
    slot = c.slots[0]
    above = slot + [0.0, 0.0, 0.45 - slot[2]]
    _hover_to(sim, above, 20)
    drop = slot + [0.0, 0.0, 0.004] - lifted
    _hover_to(sim, drop, 6)
    assert c.release(0, sim.world.agent_bodies[0], sim.time) == box
    sim.controller.set_payload(0, 0.0)
    _hover_to(sim, above, 3)
    c.update(sim.time)
    assert c.state[box] == PLACED
    assert c.slot_box[0] == box
    assert np.linalg.norm(c.positions[box] - slot) < c.spec.place_tolerance_m
    assert [e.kind for e in c.events] == ["grasp", "release", "guided", "placed"]


def test_grasp_refused_beyond_attach_threshold(make_sim):
    sim = make_sim(load_scenario("construction_single", {"agents.start_jitter": 0.0}))
    c = sim.task
    far = c.grasp_points()[0] + [0.0, 0.0, c.spec.attach_threshold * 1.5]
    assert c.grasp(0, sim.world.agent_bodies[0], far, 0.0) == -1
    assert np.all(c.state == FREE)


def test_slots_open_bottom_layer_first(make_sim):
    sim = make_sim(load_scenario("construction_single"))
    c = sim.task
    bottom = np.isclose(c.slots[:, 2], 0.05)
    assert np.array_equal(c.slot_open, bottom)
    c.slot_box[:] = -1
    c.slot_box[0] = 0  # slot 0 at (2.7, 0.2, 0.05) holds a box
    above0 = np.nonzero(np.isclose(c.slots[:, 1], 0.2) & np.isclose(c.slots[:, 2], 0.15))[0][0]
    assert c.slot_open[above0]
    top0 = np.nonzero(np.isclose(c.slots[:, 1], 0.2) & np.isclose(c.slots[:, 2], 0.25))[0][0]
    assert not c.slot_open[top0]
    assert not c.slot_open[0]  # filled


@pytest.mark.parametrize(
    ("override", "field", "text"),
    [
        (
            {"task.boxes": [[3.5, 0.5, 0.05]], "task.structure": [[2.7, 0.2, 0.05]]},
            "task.boxes[0]",
            "outside the arena",
        ),
        (
            {"task.boxes": [[0.4, 0.3, 0.05], [0.45, 0.3, 0.05]], "task.structure": [[2.7, 0.2, 0.05]]},
            "task.boxes[1]",
            "overlap",
        ),
        ({"task.boxes": [[0.4, 0.3, 0.05]]}, "task.structure", "at most as many slots as boxes"),
        ({"task.structure": [[2.7, 0.2, 0.05], [2.7, 0.6, 0.15]]}, "task.structure[1]", "nothing under it"),
        ({"task.structure": [[2.7, 0.2, 0.02]]}, "task.structure[0]", "above the ground"),
    ],
)
def test_bad_construction_layouts_are_refused(override, field, text):
    with pytest.raises(ConfigError) as err:
        load_scenario("construction", override)
    assert err.value.field == field
    assert text in str(err.value)
    assert "\n" not in str(err.value)
    assert str(err.value).startswith("construction.yaml: ")


def test_completion_needs_every_slot_and_a_still_structure(make_sim):
    sc = load_scenario(
        "construction_single",
        {"task.boxes": [[0.4, 0.5, 0.05]], "task.structure": [[2.7, 0.5, 0.05]], "task.settle_s": 1.0},
    )
    sim = make_sim(sc)
    c = sim.task
    assert not c.update(0.0)
    sim.world.reset_body(c.bodies[0], [2.7, 0.5, 0.05])
    assert not c.update(1.0)  # filled, but the structure must stand still for 1 s first
    assert c.update(2.05)
    assert c.completed_at == pytest.approx(2.05)


@pytest.mark.slow
def test_shortest_path_completes_construction_single():
    r = pybullet_swarm.run("construction_single", planner="shortest_path")
    assert r.exit_status is ExitStatus.COMPLETED
    m = r.metrics
    assert m["boxes_placed"] == m["boxes_total"] == 9
    assert m["task_lower_bound_s"] < m["completion_time_s"] < 500
    assert 0 < m["efficiency"] < 1
    kinds = [e.kind for e in r.events]
    assert kinds.count("grasp") == kinds.count("placed") == 9


@pytest.mark.slow
def test_shortest_path_completes_construction_with_five_agents():
    r = pybullet_swarm.run("construction", planner="shortest_path", seed=0)
    assert r.exit_status is ExitStatus.COMPLETED
    assert r.metrics["boxes_placed"] == 9
    assert r.metrics["completion_time_s"] < 200


def test_placed_box_stays_placed_within_the_hysteresis_band(make_sim):
    sc = load_scenario("construction_single", {"task.boxes": [[0.4, 0.5, 0.05]], "task.structure": [[2.7, 0.5, 0.05]]})
    sim = make_sim(sc)
    c = sim.task
    tol = c.spec.place_tolerance_m
    wide = (1.0 + c.spec.place_hysteresis) * tol
    c.update(0.0)
    sim.world.reset_body(c.bodies[0], [2.7 + 1.2 * tol, 0.5, 0.05])  # lands just outside: not placed
    c.update(0.1)
    assert c.slot_box[0] == -1 and c.state[0] == FREE
    sim.world.reset_body(c.bodies[0], [2.7 + 0.9 * tol, 0.5, 0.05])  # inside: placed
    c.update(0.2)
    assert c.slot_box[0] == 0 and c.state[0] == PLACED
    sim.world.reset_body(c.bodies[0], [2.7 + 1.2 * tol, 0.5, 0.05])  # nudged past the tolerance: still placed
    c.update(0.3)
    assert c.slot_box[0] == 0 and c.state[0] == PLACED
    sim.world.reset_body(c.bodies[0], [2.7 + wide + 0.002, 0.5, 0.05])  # clearly out: displaced
    c.update(0.4)
    assert c.slot_box[0] == -1 and c.state[0] == FREE
    kinds = [e.kind for e in c.events]
    assert kinds == ["placed", "unplaced"]


@pytest.mark.parametrize(("norm", "seen"), [("chebyshev", True), ("euclidean", False)])
def test_view_radius_is_measured_in_the_task_norm(make_sim, norm, seen):
    sc = load_scenario(
        "construction_single",
        {"task.boxes": [[0.4, 0.5, 0.05]], "task.structure": [[2.7, 0.5, 0.05]], "task.view_norm": norm},
    )
    c = make_sim(sc).task
    reach = c.view_radius + c.grasp_height
    grasp = c.grasp_points()[0]
    diagonal = grasp + 0.95 * reach * np.array([1.0, 1.0, 0.0])  # inside the cube, outside the ball
    free, _ = c.visible(diagonal)
    assert (0 in free) is seen
    along = grasp + 0.95 * reach * np.array([0.0, 1.0, 0.0])  # inside both
    assert 0 in c.visible(along)[0]
    beyond = grasp + 1.05 * reach * np.array([0.0, 0.0, 1.0])  # outside both
    assert 0 not in c.visible(beyond)[0]


@pytest.mark.parametrize("square", [True, False])
def test_grip_squares_a_box_knocked_askew(make_sim, square):
    from pybullet_swarm.tasks.construction import _box_tilt_and_yaw_error

    sc = load_scenario("construction_single", {"agents.start_jitter": 0.0, "task.square_grip": square})
    sim = make_sim(sc)
    c = sim.task
    box = 4
    yaw = np.radians(14.0)  # beyond the 10 deg place tolerance
    sim.world.reset_body(c.bodies[box], c.positions[box], [0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)])
    c.read()
    grasp = c.grasp_points()[box]
    _fly_down_and_grasp(sim, box, grasp)
    _hover_to(sim, [grasp[0], grasp[1], 0.45], 4)
    c.read()
    _, box_yaw = _box_tilt_and_yaw_error(c.quaternions[box : box + 1])
    _, agent_yaw = _box_tilt_and_yaw_error(sim.state.quaternions[0:1])
    if square:  # turned square with the airframe, which holds its heading
        assert abs(np.degrees(box_yaw[0]) - np.degrees(agent_yaw[0])) < 1.0
        assert np.degrees(box_yaw[0]) < c.spec.place_tolerance_deg
    else:
        assert np.degrees(box_yaw[0]) == pytest.approx(14.0, abs=1.0)


def _lift_off_centre(make_sim, square):
    """Agent 0 grasps box 4 1.5 cm off its grasp point and lifts it to 0.45 m; returns the box's
    distance from the airframe's vertical axis (m) and the most the airframe tilted (deg)."""
    from pybullet_swarm.control.rotations import quat_to_matrix

    sc = load_scenario("construction_single", {"agents.start_jitter": 0.0, "task.square_grip": square})
    sim = make_sim(sc)
    c = sim.task
    box = 4
    off = c.grasp_points()[box] + np.array([0.0, 0.015, 0.0])
    _fly_down_and_grasp(sim, box, off)
    sim.step(int(0.5 * sim.physics_hz))  # the grip slides the box under the airframe
    sim.set_targets(np.array([[off[0], off[1], 0.45]]))
    tilt = 0.0  # deg, the most the airframe tilts while it lifts the box
    for _ in range(40):
        sim.step(int(0.05 * sim.physics_hz))
        tilt = max(tilt, float(np.degrees(np.arccos(quat_to_matrix(sim.state.quaternions[0])[2, 2]))))
    c.read()
    rot = quat_to_matrix(sim.state.quaternions[0])
    rel = rot.T @ (c.positions[box] - sim.state.positions[0])  # the box's centre in the airframe's frame
    return float(np.hypot(rel[0], rel[1])), tilt


def test_grip_centres_a_box_grasped_off_centre(make_sim):
    """Grasped 1.5 cm off its grasp point (inside the 2 cm threshold), a box is held on the
    airframe's vertical axis by the square grip (a self-centring jaw), and where it was without it.
    Off the axis the load (0.67 N at hover: its weight, 0.1 N, and its carrier's wake on it) twists the
    airframe until the attitude loop's integral answers: measured, up to 20 deg of tilt while
    lifting, against 1 deg centred."""
    off_c, tilt_c = _lift_off_centre(make_sim, True)
    off_o, tilt_o = _lift_off_centre(make_sim, False)
    print(f"centred: {100 * off_c:.2f} cm, {tilt_c:.2f} deg; as grasped: {100 * off_o:.2f} cm, {tilt_o:.2f} deg")
    assert off_c < 0.002
    assert off_o == pytest.approx(0.015, abs=0.003)
    assert tilt_c < 3.0
    assert tilt_o > 5.0 * tilt_c


def _carry(sim, box, point, seconds=2.0):
    """Agent 0 grasps ``box`` and holds it with its centre at ``point`` (teleported there, then flown)."""
    c = sim.task
    body = sim.world.agent_bodies[0]
    grasp = c.grasp_points()[box]
    sim.world.reset_agent(0, grasp)
    sim.world.read_agent_states(sim.state_array)
    c.read()
    assert c.grasp(0, body, sim.state.positions[0], sim.time) == box
    sim.controller.set_payload(0, c.spec.box_mass + sim.own_wake_load(c.spec.box_mass))
    point = np.asarray(point, dtype=float)
    sim.world.reset_agent(0, point)
    sim.world.reset_body(c.bodies[box], point - [0.0, 0.0, c.grasp_height])
    sim.world.read_agent_states(sim.state_array)
    sim.shaper.reset(sim.state_array[:, :3])
    _hover_to(sim, point, seconds)
    assert np.linalg.norm(sim.state.positions[0] - point) < 0.003


def _drop(sim, seconds=3.0):
    c = sim.task
    p = sim.state.positions[0].copy()
    assert c.release(0, sim.world.agent_bodies[0], sim.time) >= 0
    sim.controller.set_payload(0, 0.0)
    _hover_to(sim, p + [0.0, 0.0, 0.3], seconds)
    c.update(sim.time)


SOLID_WALL_BOX = 0.1  # m, the box size of ``_solid_wall_with_one_placed``


def _solid_wall_with_one_placed(make_sim, **task):
    """A solid wall of two slots (pitch = box size) with box 0 placed in the first by agent 0 (``task``:
    more task fields); the simulation."""
    size = SOLID_WALL_BOX
    sc = load_scenario(
        "construction_single",
        {
            "agents.start_jitter": 0.0,
            "task.boxes": [[0.4, 0.3, 0.05], [0.4, 0.7, 0.05]],
            "task.structure": [[2.0, 0.5, 0.05], [2.0, 0.5 + size, 0.05]],
            **{f"task.{k}": v for k, v in task.items()},
        },
    )
    sim = make_sim(sc)
    c = sim.task
    _carry(sim, 0, c.slots[0] + [0.0, 0.0, c.grasp_height + 0.004])
    _drop(sim)
    assert c.slot_box[0] == 0
    return sim


@pytest.mark.parametrize("placement", ["guided", "free"])
def test_a_box_released_beside_a_placed_one_never_pushes_it(make_sim, placement):
    # a solid wall: pitch = box size; the second box comes down 8 mm off its slot, towards the first
    size = SOLID_WALL_BOX
    sim = _solid_wall_with_one_placed(make_sim, placement=placement)
    c = sim.task
    gh = c.grasp_height
    first = c.positions[0].copy()
    release_at = c.slots[1] + [0.0, -0.008, gh + 0.004]  # 8 mm towards the first box: the boxes rub on the way
    _carry(sim, 1, release_at + [0.0, 0.0, size])
    _hover_to(sim, release_at, 4.0)
    _drop(sim)
    moved = np.linalg.norm(c.positions[0] - first)
    if placement == "guided":
        assert c.slot_box.tolist() == [0, 1]
        assert moved < 1e-3
        assert np.linalg.norm(c.positions[1] - c.slots[1]) < 1e-3
        assert [e.kind for e in c.events].count("guided") == 2
    else:  # the boxes push each other: the first moves
        assert moved > 1e-3
        assert "guided" not in [e.kind for e in c.events]


@pytest.mark.parametrize("guide_carried", [True, False])
def test_a_carried_box_lowered_off_its_slot_slides_past_its_neighbour(make_sim, guide_carried):
    """guide_carried: a box held 8 mm off a solid wall's slot comes down beside the placed box without
    touching it (the chamfers take it while still held); without, it meets the placed box's edge."""
    size = SOLID_WALL_BOX
    sim = _solid_wall_with_one_placed(make_sim, guide_carried=guide_carried)
    c = sim.task
    gh = c.grasp_height
    first = c.positions[0].copy()
    box_at = c.slots[1] + [0.0, -0.008, 0.004]  # the held box's centre at the release point
    _carry(sim, 1, box_at + [0.0, 0.0, gh + size])
    import pybullet as pb

    touched = 0
    sim.set_targets((box_at + [0.0, 0.0, gh]).reshape(1, 3))
    for _ in range(40):  # 4 s, the contact looked at every 0.1 s
        sim.step(int(0.1 * sim.physics_hz))
        touched += bool(pb.getContactPoints(c.bodies[0], c.bodies[1], physicsClientId=sim.world._cid))
    c.read()
    assert c.state[1] == CARRIED
    if guide_carried:
        assert touched == 0
        assert np.linalg.norm(c.positions[1] - box_at) < 3e-3  # down at the release point, beside the first
        assert np.linalg.norm(c.positions[0] - first) < 1e-4
        # out of the guide's reach it meets the first box again: set down on top of it, it rests there
        _hover_to(sim, box_at + [0.0, 0.0, gh + 2.0 * size], 3.0)
        _hover_to(sim, c.slots[0] + [0.0, 0.0, gh + 2.0 * size], 3.0)
        _hover_to(sim, c.slots[0] + [0.0, 0.0, gh + size - 0.01], 3.0)  # 1 cm into the first box
        c.read()
        assert pb.getContactPoints(c.bodies[0], c.bodies[1], physicsClientId=sim.world._cid)
        assert c.positions[1, 2] > c.slots[0, 2] + size - 0.003
    else:
        assert touched > 0


def test_a_bonded_box_springs_back_into_its_slot_after_a_shove(make_sim):
    sc = load_scenario(
        "construction_single",
        {"agents.start_jitter": 0.0, "task.boxes": [[0.4, 0.3, 0.05]], "task.structure": [[2.0, 0.5, 0.05]]},
    )
    sim = make_sim(sc)
    c = sim.task
    _carry(sim, 0, c.slots[0] + [0.0, 0.0, c.grasp_height + 0.004])
    _drop(sim)
    assert c.slot_box[0] == 0
    # a sideways shove of 10 N for 0.1 s (an agent's full thrust is about 3 N): the interlock gives and pulls back
    import pybullet as pb

    for _ in range(int(0.1 * sim.physics_hz)):
        pb.applyExternalForce(
            c.bodies[0], -1, [10.0, 0.0, 0.0], c.slots[0].tolist(), pb.WORLD_FRAME, physicsClientId=sim.world._cid
        )
        sim.world.step()
    sim.step(int(1.0 * sim.physics_hz))
    c.update(sim.time)
    assert c.slot_box[0] == 0
    assert np.linalg.norm(c.positions[0] - c.slots[0]) < 1e-3


def _judge_slot_by_slot(c, tilt, yaw):
    """The slot rule written out one slot at a time (the reference for the vectorised judgement)."""
    tol_a = np.radians(c.spec.place_tolerance_deg)
    wide = 1.0 + c.spec.place_hysteresis
    loose = c.state != CARRIED
    aligned = (tilt <= tol_a) & (yaw <= tol_a)
    kept = loose & (tilt <= wide * tol_a) & (yaw <= wide * tol_a)
    d = np.linalg.norm(c.positions[None, :, :] - c.slots[:, None, :], axis=2)
    out = np.full(c.S, -1)
    for s in range(c.S):
        b = c.slot_box[s]
        if b >= 0 and kept[b] and d[s, b] <= wide * c.spec.place_tolerance_m:
            out[s] = b
            continue
        cand = np.nonzero((d[s] <= c.spec.place_tolerance_m) & aligned & loose)[0]
        if cand.size:
            out[s] = cand[np.argmin(d[s, cand])]
    return out


def test_slots_judged_at_once_as_slot_by_slot(make_sim):
    """Boxes scattered near the slots (inside, on and beyond the tolerances, some tilted, some carried,
    some slots already holding a box): the judgement of every slot at once matches the rule slot by slot."""
    from pybullet_swarm.rng import named_rng
    from pybullet_swarm.tasks.construction import _box_tilt_and_yaw_error

    c = make_sim(load_scenario("construction")).task
    rng = named_rng(0, "test/judge_slots")
    tol = c.spec.place_tolerance_m
    changed = 0
    for _ in range(300):
        near = rng.integers(0, c.S, size=c.B)
        c._states[:, :3] = c.slots[near] + rng.normal(0.0, tol, size=(c.B, 3))
        c._states[:, 3:7] = np.array([0.0, 0.0, 0.0, 1.0]) + rng.normal(0.0, 0.1, size=(c.B, 4)) * (
            rng.random((c.B, 1)) < 0.3
        )
        c._states[:, 3:7] /= np.linalg.norm(c._states[:, 3:7], axis=1, keepdims=True)
        c.positions[:], c.quaternions[:] = c._states[:, :3], c._states[:, 3:7]
        c.state = np.where(rng.random(c.B) < 0.2, CARRIED, np.where(c.state == CARRIED, FREE, c.state))
        before = c.slot_box.copy()
        expected = _judge_slot_by_slot(c, *_box_tilt_and_yaw_error(c.quaternions))
        c._judge_slots(0.0)
        assert np.array_equal(c.slot_box, expected)
        changed += int(np.any(c.slot_box != before))
    assert changed > 50


def test_boxes_are_read_once_per_state_of_the_world(make_sim, monkeypatch):
    # without wakes: the wake model reads the boxes' poses itself every physics step
    sim = make_sim(load_scenario("construction_single", {"agents.start_jitter": 0.0, "sim.downwash": False}))
    c, world = sim.task, sim.world
    reads = []
    read = world.read_body_poses
    monkeypatch.setattr(world, "read_body_poses", lambda bodies, out: (reads.append(1), read(bodies, out)))
    c.read()
    c.sample()
    c.update(sim.time)
    assert len(reads) == 1  # one state, one read
    world.reset_body(c.bodies[0], c.slots[0])  # a teleport is a new state
    c.update(sim.time)
    assert len(reads) == 2 and c.slot_box[0] == 0
    sim.step(1)  # so is a step
    c.sample()
    assert len(reads) == 3


@pytest.mark.parametrize("downwash", [True, False])
def test_a_carried_box_is_pushed_down_by_its_carriers_wake(make_sim, downwash):
    """Hovering with its box, the carrier's rotors hold its weight, the box's and the drag of its own wake on the
    box's top face (``vehicle/downwash.py``), at the separation it holds the box at."""
    sim = make_sim(load_scenario("construction_single", {"agents.start_jitter": 0.0, "sim.downwash": downwash}))
    c = sim.task
    _carry(sim, 0, [1.5, 0.5, 0.45], seconds=8.0)
    p = sim.params
    thrust = p.kf * float(np.sum(sim.controller.rotor_speeds[0] ** 2))
    c.read()
    top = c.positions[0, 2] + 0.5 * c.size
    drag = p.downwash_params.force_on_box(sim.state.positions[0, 2] - top, c.size, thrust=thrust)
    weight = (p.mass + c.spec.box_mass) * sim.scenario.sim.gravity
    assert drag > 0.2 * weight  # a sizeable force: the carrier's own wake on a box right under it
    assert thrust == pytest.approx(weight + (drag if downwash else 0.0), rel=2e-3)


def test_a_carried_box_touching_the_ground_is_a_contact_of_its_own_unless_set_into_its_slot(make_sim):
    sim = make_sim(load_scenario("construction_single", {"agents.start_jitter": 0.0}))
    c = sim.task
    _carry(sim, 0, [1.5, 0.5, 0.45])
    low = [1.5, 0.5, c.grasp_height + 0.5 * c.size - 0.01]  # the box 1 cm into the ground, far from any slot
    _hover_to(sim, low, 3.0)
    m = sim.metrics()
    assert m["collisions"]["load_ground"] == 1 and m["incidents"] == 1
    assert sum(m["collisions"].values()) == 1
    slot = c.slots[0]  # an open slot on the ground: a box set down into it is placed, no contact
    assert c.slot_open[0] and slot[2] == pytest.approx(0.5 * c.size)
    _hover_to(sim, slot + [0.0, 0.0, c.grasp_height + 0.1], 8.0)
    _hover_to(sim, slot + [0.0, 0.0, c.grasp_height - 0.005], 3.0)
    m = sim.metrics()
    assert m["collisions"]["load_ground"] == 1 and m["incidents"] == 1
