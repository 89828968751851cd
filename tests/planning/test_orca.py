"""ORCA layer: velocity obstacles, the LP, kinematic swaps, full simulations, determinism."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pydantic
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog, minimize

import pybullet_swarm
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.simulation import Simulation
from pybullet_swarm.planning.base import Action, Command, CommandKind, TaskInfo, WorldView
from pybullet_swarm.planning.orca import (
    FLAG_FREE,
    FLAG_INFEASIBLE,
    OrcaParams,
    Shape,
    commanded_velocities,
    orca_plane,
    orca_velocities,
    preferred_velocities,
    solve_velocity,
)
from pybullet_swarm.planning.params import Params as PlannerParams
from pybullet_swarm.planning.registry import avoidance_layers, register_planner
from pybullet_swarm.types import ExitStatus

V_MAX = np.full(3, 0.5)  # m/s per axis
R_AGENT = 0.106  # m, quad150 enclosing radius
HALF = np.array([0.075, 0.075, 0.01])  # m, quad150 half extents (level)


# ----------------------------------------------------------------------------- half-spaces
def _ray_hits_box(c: np.ndarray, H: np.ndarray, v: np.ndarray, tau: float) -> bool:
    """Brute force: does t v enter [c - H, c + H] for some 0 <= t <= tau?"""
    lo, hi = 0.0, tau
    for k in range(3):
        if abs(v[k]) < 1e-15:
            if not (c[k] - H[k] <= 0.0 <= c[k] + H[k]):
                return False
            continue
        a, b = sorted(((c[k] - H[k]) / v[k], (c[k] + H[k]) / v[k]))
        lo, hi = max(lo, a), min(hi, b)
    return lo <= hi


@settings(max_examples=300, deadline=None)
@given(
    c=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    H=st.lists(st.floats(0.03, 0.3), min_size=3, max_size=3),
    v=st.lists(st.floats(-0.6, 0.6), min_size=3, max_size=3),
)
def test_box_velocity_obstacle_is_exact(c, H, v):
    """Inside the computed VO exactly when the relative motion hits the Minkowski box within the horizon,
    and v + u lies on the VO's boundary."""
    c, H, v = np.array(c), np.array(H), np.array(v)
    if np.all(np.abs(c) <= H):
        return  # touching or overlapping now: the recovery rule applies
    tau = 2.0
    n, u = orca_plane(c, v, np.zeros(3), time_horizon=tau, recovery_time=0.5, half_extents=H, responsibility=1.0)
    depth = float(u @ n)  # > 0: v inside the VO, by that much
    if abs(depth) > 1e-9:
        assert (depth > 0) == _ray_hits_box(c, H, v, tau)
    if depth > 1e-6:  # just inside / just outside the boundary point
        w = v + u
        assert _ray_hits_box(c, H, w - 1e-7 * n, tau) and not _ray_hits_box(c, H, w + 1e-7 * n, tau)


def test_sphere_head_on_keeps_right_and_is_antisymmetric():
    p = np.array([1.0, 0.0, 0.0])  # neighbour straight ahead (+x)
    v = np.array([0.6, 0.0, 0.0])  # closing head-on
    n_a, _ = orca_plane(p, v, np.array([0.3, 0, 0]), time_horizon=4.0, recovery_time=0.5, combined_radius=0.3)
    n_b, _ = orca_plane(-p, -v, np.array([-0.3, 0, 0]), time_horizon=4.0, recovery_time=0.5, combined_radius=0.3)
    assert n_a[1] < -0.5  # agent a (heading +x) turns to its right: -y
    assert np.allclose(n_b, -n_a)  # b turns to its own right: +y


# ----------------------------------------------------------------------------- the LP
def _planes(rng_data: list[tuple[list[float], list[float]]], shape: str, v_self: np.ndarray):
    normals, points = [], []
    for rel_p, rel_v in rng_data:
        rel_p, rel_v = np.array(rel_p), np.array(rel_v)
        if shape == "sphere":
            if np.linalg.norm(rel_p) < 0.3:
                rel_p = rel_p / max(np.linalg.norm(rel_p), 1e-9) * 0.3
            n, pt = orca_plane(rel_p, rel_v, v_self, time_horizon=2.0, recovery_time=0.5, combined_radius=0.25)
        else:
            n, pt = orca_plane(
                rel_p,
                rel_v,
                v_self,
                time_horizon=2.0,
                recovery_time=0.5,
                half_extents=2 * HALF + 0.03,
            )
        normals.append(n)
        points.append(pt)
    return np.array(normals).reshape(-1, 3), np.array(points).reshape(-1, 3)


vec = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3)
neighbour = st.tuples(vec, st.lists(st.floats(-0.8, 0.8), min_size=3, max_size=3))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    nbrs=st.lists(neighbour, min_size=1, max_size=8),
    shape=st.sampled_from(["sphere", "box"]),
    pref=st.lists(st.floats(-0.6, 0.6), min_size=3, max_size=3),
    v_self=st.lists(st.floats(-0.4, 0.4), min_size=3, max_size=3),
)
def test_lp_result_satisfies_every_halfspace_when_feasible(nbrs, shape, pref, v_self):
    v_self, pref = np.array(v_self), np.array(pref)
    N, P = _planes(nbrs, shape, v_self)
    v, feasible = solve_velocity(N, P, pref, v_max=V_MAX)
    assert np.all(np.abs(v) <= V_MAX + 1e-9)  # the per-axis limits hold in every case
    # independent feasibility check: the largest common slack t of all planes inside the box
    A = np.hstack([-N, np.ones((len(N), 1))])  # -n.v + t <= -n.p
    res = linprog(
        c=[0, 0, 0, -1],
        A_ub=A,
        b_ub=-np.einsum("ij,ij->i", N, P),
        bounds=[(-V_MAX[0], V_MAX[0]), (-V_MAX[1], V_MAX[1]), (-V_MAX[2], V_MAX[2]), (None, 1.0)],
        method="highs",
    )
    slack = -res.fun
    if slack > 1e-7:
        assert feasible
        assert np.all(np.einsum("ij,ij->i", N, v - P) >= -1e-6)
        # optimal: no feasible velocity of a generic solver is closer to the preferred one
        cons = [{"type": "ineq", "fun": lambda x, N=N, P=P: np.einsum("ij,ij->i", N, x - P)}]
        x0 = res.x[:3]
        qp = minimize(
            lambda x: np.sum((x - pref) ** 2),
            x0,
            constraints=cons,
            method="SLSQP",
            bounds=[(-0.5, 0.5)] * 3,
            options={"ftol": 1e-12, "maxiter": 200},
        )
        if qp.success and np.all(np.einsum("ij,ij->i", N, qp.x - P) >= -1e-9):
            assert np.linalg.norm(v - pref) <= np.linalg.norm(qp.x - pref) + 1e-6
    elif slack < -1e-7:
        assert not feasible


def test_infeasible_lp_gives_least_violating_velocity_within_limits():
    N = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    P = np.array([[0.3, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.2, 0.0]])  # v_x >= 0.3 and v_x <= 0.1
    v, feasible = solve_velocity(N, P, np.array([0.0, 0.0, 0.1]), v_max=np.full(3, 0.25))
    assert not feasible
    assert v[0] == pytest.approx(0.2, abs=1e-8)  # both x planes violated by 0.1, the least possible
    # every plane is now allowed that violation, and within it the velocity is the closest to the
    # preferred one: the y plane is met up to 0.1, z is free
    assert v[1] == pytest.approx(0.1, abs=1e-8)
    assert v[2] == pytest.approx(0.1, abs=1e-8)
    assert np.all(np.abs(v) <= 0.25 + 1e-12)


@pytest.mark.parametrize("seed", range(40))
def test_the_weighted_fallback_minimises_the_largest_weighted_violation(seed: int):
    """With ``weights`` an infeasible LP gives a velocity whose largest weighted violation is the least there is
    (scipy's linprog on the same crowd: min t with w_i n_i.(p_i - v) <= t inside the box); unweighted, the paper's;
    a half-space weighed 4 times as much is violated a quarter as much at the optimum."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(3, 9))
    N = rng.normal(size=(m, 3))
    N /= np.linalg.norm(N, axis=1)[:, None]
    P = N * rng.uniform(0.05, 0.3, size=(m, 1))  # every half-space excludes the origin
    N[1], P[1] = -N[0], -N[0] * 0.1  # two that contradict each other: infeasible
    w = rng.uniform(1.0, 30.0, size=m)
    vm = np.full(3, 0.25)
    for weights in (w, None):
        v, feasible = solve_velocity(N, P, np.zeros(3), v_max=vm, weights=weights)
        assert not feasible and np.all(np.abs(v) <= vm + 1e-9)
        ww = np.ones(m) if weights is None else weights
        res = linprog(
            c=[0, 0, 0, 1],
            A_ub=np.hstack([-ww[:, None] * N, -np.ones((m, 1))]),  # w (n.p - n.v) - t <= 0
            b_ub=-ww * np.einsum("ij,ij->i", N, P),
            bounds=[(-vm[0], vm[0]), (-vm[1], vm[1]), (-vm[2], vm[2]), (None, None)],
            method="highs",
        )
        worst = float(np.max(ww * np.einsum("ij,ij->i", N, P - v)))
        assert worst == pytest.approx(res.fun, abs=1e-7)
    # the same pair of contradicting half-spaces, one weighed 4 times: it gives way a quarter as much
    N2, P2 = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]), np.array([[0.1, 0.0, 0.0], [-0.1, 0.0, 0.0]])
    v, _ = solve_velocity(N2, P2, np.zeros(3), v_max=vm, weights=np.array([4.0, 1.0]))
    assert v[0] == pytest.approx(0.1 - 0.2 / 5.0)  # violations 0.04 and 0.16
    with pytest.raises(ValueError, match="weights"):
        solve_velocity(N2, P2, np.zeros(3), v_max=vm, weights=np.array([1.0, 0.0]))


def _refused_field(**values: Any) -> Any:
    with pytest.raises(pydantic.ValidationError) as err:
        OrcaParams.model_validate(values)
    return err.value.errors()[0]["loc"][0]


def test_params_refuse_bad_values_naming_the_field():
    assert _refused_field(time_horizon=-1.0) == "time_horizon"
    assert _refused_field(shape="blob") == "shape"
    assert _refused_field(horizon=2.0) == "horizon"
    assert _refused_field(max_neighbours=1000) == "max_neighbours"  # bounds the neighbour table
    assert _refused_field(max_neighbours=2.5) == "max_neighbours"
    assert _refused_field(stuck_fraction=1.0) == "stuck_fraction"
    assert OrcaParams.model_validate({"shape": "sphere"}).shape is Shape.SPHERE


# ----------------------------------------------------------------------------- kinematic swaps
def _kinematic(
    starts: np.ndarray,
    goals: np.ndarray,
    *,
    params: OrcaParams,
    T: float,
    v_max: float = 0.5,
    a_max: float = 1.0,
    lag: float = 0.1,
) -> dict[str, Any]:
    """Point agents under the layer as the simulation runs it: 10 Hz ticks; a command left alone stays
    a position target, a changed one becomes a velocity target; the reference shaper of the
    controller at 48 Hz; each airframe trails its reference position with a first-order lag.
    Returns the final positions, the closest approach, the smallest airframe gap and the fastest
    commanded axis."""
    from pybullet_swarm.control.reference import ReferenceShaper

    n = len(starts)
    dt = 1.0 / 48.0
    vm = np.full(3, v_max)
    shaper = ReferenceShaper(n, vm, np.full(3, a_max), dt)
    shaper.reset(starts)
    pos, vel = starts.astype(float).copy(), np.zeros((n, 3))
    kinds = np.full(n, int(CommandKind.POSITION))
    closest, fastest, gap = np.inf, 0.0, np.inf
    for k in range(int(T / dt)):
        if k % 5 == 0:  # ~10 Hz
            pref = preferred_velocities(kinds, goals, pos, arrive_time=params.arrive_time, v_max=vm)
            vcmd = commanded_velocities(kinds, goals, pos, v_max=vm, a_max=np.full(3, a_max), dt=dt)
            cmd, flags = orca_velocities(
                pos,
                np.clip(vel, -vm, vm),
                pref,
                params=params,
                sensing_radius=3.0,
                v_max=vm,
                radii=np.full(n, R_AGENT),
                boxes=(np.zeros((n, 3)), np.tile(HALF, (n, 1))),
                goals=goals,
                has_goal=np.ones(n, dtype=bool),
                commanded=vcmd,
            )
            free = (flags & FLAG_FREE) != 0
            shaper.set_position_targets(goals, free)
            shaper.set_velocity_targets(cmd, ~free)
            fastest = max(fastest, float(np.abs(cmd).max()))
        ref = shaper.step()
        new = pos + (ref.positions - pos) * (dt / lag)
        vel = (new - pos) / dt
        pos = new
        d = pos[:, None, :] - pos[None, :, :]
        closest = min(closest, float((np.linalg.norm(d, axis=2) + np.eye(n) * 1e9).min()))
        # true airframe clearance: the largest per-axis gap between two level 15 x 15 x 2 cm boxes
        gap = min(gap, float((np.max(np.abs(d) - 2 * HALF, axis=2) + np.eye(n) * 1e9).min()))
    return {"pos": pos, "closest": closest, "fastest": fastest, "gap": gap}


def _circle(n: int, radius: float, z: float = 1.0) -> np.ndarray:
    a = 2 * np.pi * np.arange(n) / n
    return np.column_stack([radius * np.cos(a), radius * np.sin(a), np.full(n, z)])


@pytest.mark.parametrize("shape", ["sphere", "box"])
def test_eight_agents_swap_antipodes_on_a_circle(shape):
    starts = _circle(8, 1.0)
    goals = starts * [-1, -1, 1]
    params = OrcaParams(shape=shape)
    out = _kinematic(starts, goals, params=params, T=40.0)
    assert np.max(np.linalg.norm(out["pos"] - goals, axis=1)) < 0.02
    if shape == "sphere":
        assert out["closest"] > 2 * R_AGENT  # spheres never touched, so neither did the airframes
    assert out["gap"] > 0.0  # airframes never overlapped
    assert out["fastest"] <= 0.5 + 1e-9  # velocity limits hold


def test_agents_swap_antipodes_on_a_sphere():
    m = 12
    i = np.arange(m) + 0.5
    th, ph = np.arccos(1 - 2 * i / m), np.pi * (1 + 5**0.5) * i
    starts = 1.0 * np.column_stack([np.cos(ph) * np.sin(th), np.sin(ph) * np.sin(th), np.cos(th)]) + [0, 0, 2.0]
    goals = 2 * np.array([0, 0, 2.0]) - starts
    out = _kinematic(starts, goals, params=OrcaParams(shape=Shape.SPHERE), T=40.0)
    assert np.max(np.linalg.norm(out["pos"] - goals, axis=1)) < 0.02
    assert out["closest"] > 2 * R_AGENT
    assert out["fastest"] <= 0.5 + 1e-9


def test_layer_math_is_deterministic():
    starts = _circle(8, 1.0)
    a = _kinematic(starts, starts * [-1, -1, 1], params=OrcaParams(), T=6.0)
    b = _kinematic(starts, starts * [-1, -1, 1], params=OrcaParams(), T=6.0)
    assert np.array_equal(a["pos"], b["pos"])


def test_free_agents_keep_their_commands_untouched():
    pos = np.array([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0]])
    goals = pos + [0.5, 0.0, 0.0]
    kinds = np.full(2, int(CommandKind.POSITION))
    vm = np.full(3, 0.5)
    pref = preferred_velocities(kinds, goals, pos, arrive_time=0.5, v_max=vm)
    v, flags = orca_velocities(
        pos,
        np.zeros((2, 3)),
        pref,
        params=OrcaParams(shape=Shape.SPHERE),
        sensing_radius=1.0,
        v_max=vm,
        radii=np.full(2, R_AGENT),
    )
    assert np.all(flags & FLAG_FREE) and not np.any(flags & FLAG_INFEASIBLE)
    assert np.array_equal(v, pref)


# ----------------------------------------------------------------------------- full simulations
class _GoTo:
    """Test planner: every agent flies to its own fixed target (centralised, for scenario set-up only)."""

    name: ClassVar[str] = "test_orca_goto"
    centralized: ClassVar[bool] = True

    class Params(PlannerParams):
        targets: list[list[float]] = []

    def __init__(self, params: Params) -> None:
        self.targets = np.asarray(params.targets, dtype=float)

    def reset(self, n: int, rng: np.random.Generator, info: TaskInfo) -> None:
        assert n == len(self.targets)

    def plan_all(self, view: WorldView) -> list[Command]:
        return [Command.goto(t, Action.NONE) for t in self.targets]


register_planner(_GoTo.name, _GoTo, "test only: fixed targets", ("waypoints",))


def _swap_scenario(starts: np.ndarray, goals: np.ndarray, time_limit: float, **extra: Any):
    overrides = {
        "agents.count": len(starts),
        "agents.start": starts.tolist(),
        "collisions": "physical",
        "task.time_limit_s": time_limit,
        "task.waypoints": [{"t_s": 0.0, "position": [0.0, 0.0, 500.0]}],  # never completes by itself
        "planner": {"name": _GoTo.name, "params": {"targets": goals.tolist()}},
        "avoidance": "orca",
    }
    overrides.update(extra)
    return pybullet_swarm.load_scenario("hover", overrides)


def _min_airframe_gap(positions: np.ndarray) -> float:
    """Smallest clearance (m) between two level airframes over a run: per pair and sample, the largest
    per-axis gap of their 15 x 15 x 2 cm boxes (positive: apart)."""
    p = positions.astype(float)
    d = np.abs(p[:, :, None, :] - p[:, None, :, :]) - 2 * HALF
    g = np.max(d, axis=3)
    n = p.shape[1]
    g[:, np.arange(n), np.arange(n)] = np.inf
    return float(g.min())


def test_orca_is_registered():
    assert "orca" in avoidance_layers()


def test_two_agents_head_on_reach_their_goals_without_contact():
    starts = np.array([[1.0, 1.5, 1.0], [2.2, 1.5, 1.0]])
    goals = starts[::-1].copy()  # exact head-on swap at one altitude
    r = pybullet_swarm.run(_swap_scenario(starts, goals, 16.0))
    assert r.exit_status is ExitStatus.TIMEOUT  # the scenario runs to its time limit
    assert r.metrics["collisions"]["agent_agent"] == 0
    assert sum(r.metrics["collisions"].values()) == 0
    final = r.timeseries.positions[-1].astype(float)
    assert np.max(np.linalg.norm(final - goals, axis=1)) < 0.03
    assert _min_airframe_gap(r.timeseries.positions) > 0.005
    assert r.metrics["orca_ticks"] > 0


def test_same_seed_same_run_with_orca():
    starts = np.array([[1.0, 1.5, 1.0], [2.2, 1.5, 1.0]])
    sc = _swap_scenario(starts, starts[::-1].copy(), 4.0)
    a, b = pybullet_swarm.run(sc, seed=1), pybullet_swarm.run(sc, seed=1)

    def strip(m: dict) -> dict:
        return {k: v for k, v in m.items() if k not in ("wall_time_s", "real_time_factor") and not k.endswith("_ms")}

    assert strip(a.metrics) == strip(b.metrics)
    assert np.array_equal(a.timeseries.positions, b.timeseries.positions)


def test_layer_keeps_action_and_refuses_bad_params():
    starts = np.array([[1.0, 1.5, 1.0], [1.25, 1.5, 1.0]])
    sc = _swap_scenario(starts, starts, 1.0)
    sim = Simulation(sc)
    try:
        # both aim at the other's place: the layer must change the commands, keeping the action
        cmds = [Command.goto(starts[1], Action.GRASP), Command.goto(starts[0], Action.RELEASE)]
        out = sim.avoidance_layer.filter(cmds, sim.perceive(), sim.task.view(sim.time))
        assert [c.action for c in out] == [Action.GRASP, Action.RELEASE]
        assert all(c.kind is CommandKind.VELOCITY for c in out)
        assert np.all(np.abs(np.array([c.vector for c in out])) <= 0.5 + 1e-9)
    finally:
        sim.close()
    with pytest.raises((ValueError, ConfigError), match="time_horizon"):
        Simulation(_swap_scenario(starts, starts, 1.0, **{"avoidance_params": {"time_horizon": 0}})).close()


@pytest.mark.slow
def test_eight_agents_swap_on_a_circle_with_physics():
    starts = _circle(8, 1.0, z=1.0) + [1.5, 1.5, 0.0]
    goals = (starts - [1.5, 1.5, 0.0]) * [-1, -1, 1] + [1.5, 1.5, 0.0]
    r = pybullet_swarm.run(_swap_scenario(starts, goals, 25.0))
    assert r.metrics["collisions"]["agent_agent"] == 0
    assert sum(r.metrics["collisions"].values()) == 0
    final = r.timeseries.positions[-1].astype(float)
    assert np.max(np.linalg.norm(final - goals, axis=1)) < 0.05
    assert _min_airframe_gap(r.timeseries.positions) > 0.005


def test_line_of_stalled_agents_is_broken_sideways():
    # Three agents at rest in a line along their 2:1 headings (per-axis limits), two one way and one
    # the other, airframe boxes face to face along x: the right bias alone cancels the preferred
    # velocity along the free y axis, so each asks for the sideways step alone and moves (a
    # deadlock of 10 s traced in stigmergy + orca on construction.yaml, seed 5).
    pos = np.array([[1.735, 0.401, 0.215], [1.554, 0.319, 0.215], [1.374, 0.163, 0.215]])
    pref = np.array([[-0.15, -0.075, 0.0], [-0.15, -0.075, 0.0], [0.15, 0.075, 0.0]])
    vm = np.full(3, 0.15)
    params = OrcaParams()
    v, flags = orca_velocities(
        pos,
        np.zeros((3, 3)),
        pref,
        params=params,
        sensing_radius=1.0,
        v_max=vm,
        radii=np.full(3, R_AGENT),
        boxes=(np.zeros((3, 3)), np.tile(HALF, (3, 1))),
        goals=pos + 10.0 * pref,
        has_goal=np.ones(3, dtype=bool),
    )
    speed = np.linalg.norm(v, axis=1)
    assert np.all(speed >= params.stuck_fraction * np.linalg.norm(pref, axis=1))
    assert abs(v[1, 1]) > 0.05  # the middle one steps aside along the free axis
    assert np.all(np.abs(v) <= vm + 1e-9)
