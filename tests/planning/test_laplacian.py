"""Laplacian formation: graphs, and convergence at the rate of the algebraic connectivity."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.planning.base import Observation, TaskInfo
from pybullet_swarm.planning.views.route import RouteLayout
from pybullet_swarm.planning.laplacian import (
    LaplacianParams,
    LaplacianPlanner,
    adjacency,
    algebraic_connectivity,
    formation_error,
    laplacian,
)
from pybullet_swarm.tasks.route import SEED_FORMATION


def _obs(i: int, pos: np.ndarray) -> Observation:
    others = np.array([j for j in range(len(pos)) if j != i], dtype=np.int64)
    return Observation(
        i,
        0.0,
        pos[i].copy(),
        np.zeros(3),
        0.0,
        -1,
        others,
        pos[others].copy(),
        np.zeros((len(others), 3)),
        None,  # a route has no objects to see
    )


def test_named_graphs_and_connectivity() -> None:
    assert algebraic_connectivity(laplacian(adjacency("star", 5))) == pytest.approx(1.0)
    assert algebraic_connectivity(laplacian(adjacency("complete", 5))) == pytest.approx(5.0)
    assert algebraic_connectivity(laplacian(adjacency("ring", 5))) == pytest.approx(2 - 2 * np.cos(2 * np.pi / 5))
    # the course report's star Laplacian
    L = laplacian(adjacency("star", 5))
    assert L[0, 0] == 4 and np.all(L[0, 1:] == -1) and np.all(np.diag(L)[1:] == 1)


@pytest.mark.parametrize(
    "bad", [[[0, 1], [1, 0]], [[0, 1, 0], [0, 0, 1], [0, 1, 0]], "wheel", [[0, 1, 0], [1, 0, 0], [0, 0, 0]]]
)
def test_bad_graphs_refused(bad: object) -> None:
    with pytest.raises(ValueError, match="planner.params.graph"):
        adjacency(bad, 3)


@pytest.mark.parametrize("graph", ["star", "ring", "complete"])
def test_kinematic_convergence_rate_matches_algebraic_connectivity(graph: str) -> None:
    n, gain, dt = 5, 0.7, 0.002
    slots = np.column_stack([2.0 * SEED_FORMATION, np.zeros(n)])
    slots -= slots.mean(axis=0)
    info = TaskInfo(
        arena_size=np.array([10.0, 10.0]),
        n_agents=n,
        agent_radius=0.1,
        v_max=np.full(3, np.inf),
        layout=RouteLayout(np.array([[5.0, 5.0, 1.0]]), pass_radius=0.3, formation_slots=slots),
    )
    planners = []
    rng = np.random.default_rng(7)
    for i in range(n):
        pl = LaplacianPlanner(
            LaplacianParams(graph=graph, gain=gain, migration_speed=0.0, w_separation=0.0, altitude=1.0)
        )
        pl.reset(i, rng, info)
        planners.append(pl)
    x = np.column_stack([rng.uniform(3, 7, size=(n, 2)), np.ones(n)])  # random start, at the altitude
    times, errs = [], []
    for k in range(int(4.0 / dt)):
        e = np.linalg.norm(formation_error(x, slots))
        times.append(k * dt)
        errs.append(e)
        v = np.array([pl.velocity(_obs(i, x)) for i, pl in enumerate(planners)])
        x = x + dt * v
    errs = np.asarray(errs)
    assert errs[-1] < 0.1 * errs[0]  # it converges
    times = np.asarray(times)
    late = (times > 1.5) & (errs > 1e-9)
    rate = -np.polyfit(times[late], np.log(errs[late]), 1)[0]
    expected = gain * algebraic_connectivity(laplacian(adjacency(graph, n)))
    assert rate == pytest.approx(expected, rel=0.10)
