"""Warm start of sweep workers: what every run needs, loaded once by the process workers are forked from.

The local executor's forkserver imports this module (``executors.PRELOAD``) while the sweep is
still being planned: it imports the simulation stack with every planner, avoidance layer and
task, and loads the compiled kernels (position and attitude loops, reference shaping, ORCA, the
stigmergy planners' zone tests) from numba's cache, by calling each once on a two-agent problem.
A worker forked from it then starts its first run with none of this to do. Bullet is not touched
(a child forked from a process that ran it is not safe). Measured by ``scripts/sweep_speedup.py``.
"""

from __future__ import annotations

import numpy as np

from pybullet_swarm.experiment import runner, sweep  # noqa: F401 - imported to be inherited by workers


def warm_up() -> None:
    """Import every plug-in and call each compiled kernel once (loaded from numba's cache when it has them)."""
    from pybullet_swarm.control.cascade import CascadeController
    from pybullet_swarm.control.reference import ReferenceShaper
    from pybullet_swarm.planning import stigmergy
    from pybullet_swarm.planning.orca import layer as orca_layer
    from pybullet_swarm.planning.registry import avoidance_layers, planners
    from pybullet_swarm.tasks import task_runtimes
    from pybullet_swarm.vehicle import load_vehicle

    planners(), avoidance_layers(), task_runtimes()
    state = np.zeros((2, 13))
    state[:, 2], state[:, 6] = 1.0, 1.0  # 1 m up, level
    for limits in (np.full(3, 0.5), None):  # shaped references, and raw set-points
        ctrl = CascadeController(load_vehicle("quad150"), 2, prefilter=limits is not None)
        shaper = ReferenceShaper(2, limits, np.full(3, 1.0), ctrl.control_dt)
        shaper.reset(state[:, :3])
        ctrl.position_update(state, shaper.step())
        ctrl.physics_update(state)
    orca_layer._warm_up()
    lo, hi = np.zeros((1, 2)), np.ones((1, 2))
    stigmergy._zone_entry(lo, hi, -1.0, 0.5, 2.0, 0.5)
    stigmergy._zone_contains(lo, hi, 0.5, 0.5)


try:
    warm_up()
except Exception:  # noqa: BLE001 - a warm start is an optimisation: a worker then warms up in its first run
    pass
