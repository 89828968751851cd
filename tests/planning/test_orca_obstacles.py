"""ORCA's static obstacles (the paper's, no switch): the obstacle planes, the target's own obstacles
left out, the arena's and the task's obstacles reaching the layer as data, runs past pillars and placed boxes."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest

import pybullet_swarm
from pybullet_swarm.experiment.simulation import Simulation
from pybullet_swarm.planning.base import Command, CommandKind, Obstacles, TaskInfo, WorldView
from pybullet_swarm.planning.orca import (
    FLAG_BIASED,
    FLAG_FREE,
    FLAG_OBSTACLE,
    OrcaLayer,
    OrcaParams,
    bounding_boxes,
    commanded_velocities,
    orca_plane,
    orca_velocities,
    preferred_velocities,
    shape_parts,
    solve_velocity,
)
from pybullet_swarm.planning.params import Params as PlannerParams
from pybullet_swarm.planning.registry import register_planner
from pybullet_swarm.types import ExitStatus

HALF = np.array([0.075, 0.075, 0.01])  # m, quad150 half extents (level)
VM = np.full(3, 0.15)  # m/s, construction.yaml's per-axis limits
CUBE = np.full(3, 0.05)  # m, half extents of a 10 cm box


def _one_agent(
    params: OrcaParams,
    pos: list[float],
    vel: list[float],
    command: Command,
    obstacles: tuple[np.ndarray, np.ndarray] | None,
    carrying: bool = False,
) -> tuple[np.ndarray, int]:
    """One level quad150 (carrying a 10 cm box 6.5 cm below, or not) under ``command`` among static
    ``obstacles``: (velocity (3,) m/s, flags)."""
    parts = shape_parts(np.array([[0.0, 0.0, 0.0, 1.0]]), HALF, np.array([carrying]), 0.1, 0.065)
    centre, half = bounding_boxes(np.array([[0.0, 0.0, 0.0, 1.0]]), HALF, np.array([carrying]), 0.1, 0.065)
    p, v = np.array([pos], dtype=float), np.array([vel], dtype=float)
    kinds = np.array([int(command.kind)])
    vectors = command.vector[None, :]
    pref = preferred_velocities(kinds, vectors, p, arrive_time=params.arrive_time, v_max=VM)
    has_goal = kinds != int(CommandKind.VELOCITY)
    out, flags = orca_velocities(
        p,
        v,
        pref,
        params=params,
        sensing_radius=1.0,
        v_max=VM,
        boxes=(centre, half),
        goals=np.where(has_goal[:, None], vectors, p),
        has_goal=has_goal,
        commanded=commanded_velocities(kinds, vectors, p, v_max=VM, a_max=np.ones(3), dt=1.0 / 48.0),
        obstacles=obstacles,
        parts=parts,
    )
    return out[0], int(flags[0])


# ----------------------------------------------------------------------------- the planes
def test_an_obstacle_plane_is_the_papers_with_the_whole_u_and_its_own_horizon():
    # every other rule off: the LP's velocity over the one plane of orca_plane with responsibility 1
    # (the obstacle does not move) and the obstacle horizon, not the agents' time horizon
    params = OrcaParams(preset="paper", obstacle_horizon=2.0)  # the paper keeps static obstacles
    pos, vel = np.array([1.0, 0.5, 0.3]), np.array([0.15, 0.0, 0.0])
    oc, oh = np.array([[1.3, 0.52, 0.3]]), CUBE[None, :]
    v, flags = _one_agent(params, pos.tolist(), vel.tolist(), Command.velocity(vel), (oc, oh))
    n, point = orca_plane(
        oc[0] - pos,
        vel,
        vel,
        time_horizon=2.0,
        recovery_time=params.recovery_time,
        half_extents=HALF + CUBE + params.margin,
        responsibility=1.0,
    )
    expected, feasible = solve_velocity(n[None, :], point[None, :], vel, v_max=VM)
    assert feasible and flags & FLAG_OBSTACLE
    assert np.allclose(v, expected, atol=1e-12)
    assert np.linalg.norm(v - vel) > 0.02  # 0.16 m of gap ahead: within the 2 s horizon at 0.15 m/s
    half_share, _ = solve_velocity(n[None, :], (vel + 0.5 * (point - vel))[None, :], vel, v_max=VM)
    assert np.linalg.norm(v - half_share) > 0.01  # not the reciprocal half of an agent pair
    # without the obstacle the command passes as it is
    v_off, flags_off = _one_agent(params, pos.tolist(), vel.tolist(), Command.velocity(vel), None)
    assert np.array_equal(v_off, vel) and not flags_off & FLAG_OBSTACLE


def test_obstacles_out_of_reach_within_the_horizon_give_no_plane():
    params = OrcaParams(obstacle_horizon=1.0)
    far = (np.array([[2.0, 0.5, 0.3]]), CUBE[None, :])  # 0.87 m of gap; the speed sphere reaches 0.26 m in 1 s
    v, flags = _one_agent(params, [1.0, 0.5, 0.3], [0.15, 0.0, 0.0], Command.velocity([0.15, 0.0, 0.0]), far)
    assert not flags & FLAG_OBSTACLE and flags & FLAG_FREE


def test_the_obstacle_the_target_touches_is_left_out():
    # An agent 5 cm above the grasp point of a box (construction.yaml: grasp height 6.5 cm), descending:
    # flying to its grasp point it descends freely (the box is its target's own), while a plain
    # velocity command downwards is held up by the same box.
    box = (np.array([[0.4, 0.5, 0.05]]), CUBE[None, :])
    grasp = np.array([0.4, 0.5, 0.115])
    params = OrcaParams()
    v, flags = _one_agent(params, (grasp + [0, 0, 0.05]).tolist(), [0.0, 0.0, -0.1], Command.goto(grasp), box)
    assert not flags & FLAG_OBSTACLE and flags & FLAG_FREE
    v, flags = _one_agent(
        params, (grasp + [0, 0, 0.05]).tolist(), [0.0, 0.0, -0.1], Command.velocity([0, 0, -0.1]), box
    )
    assert flags & FLAG_OBSTACLE and v[2] > -0.06
    # a neighbour of the box at the depot's 20 cm pitch is not touched at the grasp point: still avoided
    beside = (np.array([[0.4, 0.5, 0.05], [0.6, 0.5, 0.05]]), np.tile(CUBE, (2, 1)))
    _, flags = _one_agent(params, [0.55, 0.5, 0.16], [0.0, 0.0, -0.1], Command.goto(grasp), beside)
    assert flags & FLAG_OBSTACLE


def test_a_carrier_places_between_neighbours_but_is_held_above_a_taller_one():
    # A solid wall (pitch = box size): the load at its drop point (4 mm over the slot) touches the
    # placed boxes on either side and the ground under it; all three are the target's own and the
    # carrier descends freely. A box one layer up beside the slot would stand where the 15 cm
    # airframe must be at the drop point: that target is inside an obstacle, which stays avoided.
    params = OrcaParams()
    drop = [2.7, 0.2, 0.05 + 0.004 + 0.065]
    level = (np.array([[2.7, 0.1, 0.05], [2.7, 0.3, 0.05]]), np.tile(CUBE, (2, 1)))
    down = [0.0, 0.0, -0.15]
    v, flags = _one_agent(params, [2.7, 0.2, 0.45], down, Command.goto(drop), level, carrying=True)
    assert flags & FLAG_FREE and not flags & FLAG_OBSTACLE
    taller = (np.vstack([level[0], [[2.7, 0.3, 0.15]]]), np.tile(CUBE, (3, 1)))
    v, flags = _one_agent(params, [2.7, 0.2, 0.45], down, Command.goto(drop), taller, carrying=True)
    assert flags & FLAG_OBSTACLE and v[2] > -0.12  # avoided: slowed from the commanded -0.15 m/s


def test_a_stall_in_front_of_a_pillar_steps_aside():
    params = OrcaParams()
    pillar = (np.array([[1.5, 1.5, 1.0]]), np.array([[0.15, 0.15, 1.0]]))  # a 2 m pillar, r = 15 cm
    # at rest 2 cm short of the pillar (margin included), target straight behind it
    pos = [1.5 - 0.15 - 0.075 - params.margin - 0.02, 1.5, 1.0]
    v, flags = _one_agent(params, pos, [0.0, 0.0, 0.0], Command.goto([2.5, 1.5, 1.0]), pillar)
    assert flags & FLAG_BIASED and abs(v[1]) > 0.05 and abs(v[2]) < 1e-9  # around it, not over it
    v, flags = _one_agent(
        params.model_copy(update={"deadlock_resolution": False}),
        pos,
        [0.0, 0.0, 0.0],
        Command.goto([2.5, 1.5, 1.0]),
        pillar,
    )
    assert not flags & FLAG_BIASED and abs(v[1]) < 1e-9  # the paper's ORCA waits in front of it


# ----------------------------------------------------------------------------- obstacles as data
def test_obstacles_refuse_mismatched_arrays_and_add_up():
    a = Obstacles(np.zeros((2, 3)), np.ones((2, 3)), np.array([0, 1]))
    b = Obstacles(np.ones((1, 3)), np.ones((1, 3)), np.array([-1]))
    both = a + b
    assert len(both) == 3 and both.objects.tolist() == [0, 1, -1]
    assert (a + Obstacles()) is a and (Obstacles() + b) is b
    with pytest.raises(ValueError, match="half_extents"):
        Obstacles(np.zeros((2, 3)), np.ones((1, 3)), np.array([0, 1]))


def test_the_arena_gives_its_walls_and_obstacles_as_world_axis_boxes():
    sc = pybullet_swarm.load_scenario(
        "hover",
        {
            "arena.walls": True,
            "arena.wall_height": 1.5,
            "arena.obstacles": [
                {"shape": "cylinder", "size": [0.15, 2.0], "position": [1.0, 1.0]},
                {"shape": "box", "size": [0.4, 0.2, 1.0], "position": [2.0, 2.0, 1.0], "yaw_deg": 90},
            ],
        },
    )
    ob = sc.arena.obstacle_boxes()
    assert len(ob) == 6 and np.all(ob.objects == -1)
    lx, ly = sc.arena.size
    walls_lo, walls_hi = ob.centres[:4] - ob.half_extents[:4], ob.centres[:4] + ob.half_extents[:4]
    assert np.allclose(walls_lo.min(axis=0), [-0.02, -0.02, 0.0]) and np.allclose(
        walls_hi.max(axis=0), [lx + 0.02, ly + 0.02, 1.5]
    )
    assert np.allclose(ob.centres[4], [1.0, 1.0, 1.0]) and np.allclose(ob.half_extents[4], [0.15, 0.15, 1.0])
    assert np.allclose(ob.centres[5], [2.0, 2.0, 1.0]) and np.allclose(ob.half_extents[5], [0.1, 0.2, 0.5])


def test_the_construction_view_shows_boxes_that_stand_still_and_the_layer_gets_the_arenas():
    sc = pybullet_swarm.load_scenario(
        "construction",
        {"arena.obstacles": [{"shape": "cylinder", "size": [0.1, 1.0], "position": [1.5, 0.5]}]},
        avoidance="orca",
    )
    sim = Simulation(sc)
    try:
        view = sim.task.view(sim.time)
        assert view.obstacles.objects.tolist() == list(range(len(view.state.objects)))  # all free at the start
        assert np.allclose(view.obstacles.centres, view.state.objects)
        assert np.allclose(view.obstacles.half_extents, 0.05, atol=1e-6)
        layer = sim.avoidance_layer
        assert isinstance(layer, OrcaLayer) and len(layer.arena_obstacles) == 1
        # a box carried by agent 2 is no obstacle
        sim.task.state[4] = 1
        sim.task.carried_by[4] = 2
        assert 4 not in sim.task.view(sim.time).obstacles.objects.tolist()
    finally:
        sim.close()


# ----------------------------------------------------------------------------- runs
class _GoTo:
    """Test planner: every agent flies to its own fixed target (centralised, for scenario set-up only)."""

    name: ClassVar[str] = "test_orca_obstacles_goto"
    centralized: ClassVar[bool] = True

    class Params(PlannerParams):
        targets: list[list[float]] = []

    def __init__(self, params: Params) -> None:
        self.targets = np.asarray(params.targets, dtype=float)

    def reset(self, n: int, rng: np.random.Generator, info: TaskInfo) -> None:
        assert n == len(self.targets)

    def plan_all(self, view: WorldView) -> list[Command]:
        return [Command.goto(t) for t in self.targets]


register_planner(_GoTo.name, _GoTo, "test only: fixed targets", ("waypoints", "construction"))


def _goto(start: list[float], goal: list[float], on: bool, **extra: Any) -> dict[str, Any]:
    """A scenario of one agent flying to ``goal``, with ORCA (``on``) or without avoidance."""
    return {
        "agents.count": 1,
        "agents.start": [start],
        "collisions": "physical",
        "planner": {"name": _GoTo.name, "params": {"targets": [goal]}},
        "avoidance": "orca" if on else "none",
        **extra,
    }


@pytest.mark.parametrize("on", [True, False])
def test_an_agent_flies_around_a_pillar_only_with_orca(on: bool):
    goal = [2.2, 1.5, 1.0]
    sc = pybullet_swarm.load_scenario(
        "hover",
        _goto(
            [0.8, 1.5, 1.0],
            goal,
            on,
            **{
                "arena.obstacles": [{"shape": "cylinder", "size": [0.15, 2.0], "position": [1.5, 1.5]}],
                "task.time_limit_s": 20.0,
                "task.waypoints": [{"t_s": 0.0, "position": [0.0, 0.0, 500.0]}],  # never completes by itself
            },
        ),
    )
    r = pybullet_swarm.run(sc, plots=False)
    final = r.timeseries.positions[-1, 0].astype(float)
    if on:
        assert r.metrics["collisions"]["agent_obstacle"] == 0
        assert sum(r.metrics["collisions"].values()) == 0
        assert np.linalg.norm(final - goal) < 0.03
        assert r.metrics["orca_obstacle_agent_ticks"] > 0
    else:
        assert r.metrics["collisions"]["agent_obstacle"] > 0
        assert r.metrics.get("orca_obstacle_agent_ticks", 0) == 0


@pytest.mark.parametrize("planner", ["stigmergy", "shortest_path"])
def test_construction_with_orca_grasps_and_places_among_static_obstacles(planner: str):
    # the default physics: rotor wakes act (the layer keeps the wake column clear)
    r = pybullet_swarm.run("construction", planner=planner, avoidance="orca", seed=3, plots=False)
    assert r.exit_status is ExitStatus.COMPLETED
    c = r.metrics["collisions"]
    assert c["agent_agent"] == c["agent_structure"] == c["agent_box"] == 0
    assert r.metrics["orca_obstacle_agent_ticks"] > 0
