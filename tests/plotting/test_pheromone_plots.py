"""Pheromone figures drawn from saved arrays."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.planning.pheromone_grid import DepositRule, LayerSpec, PheromoneGrid
from pybullet_swarm.plotting.pheromone_plots import plot_pheromone_activity, plot_pheromone_map, plot_pheromones


def _is_png(path) -> bool:
    return path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_map_and_activity_figures_are_written(tmp_path):
    v = np.zeros((30, 10))
    v[4:8, 3:7] = 1.0
    v[27, 2:8] = -1.0
    m = plot_pheromone_map(v, 0.1, tmp_path / "map.png", title="task", extent=[3.0, 1.0])
    a = plot_pheromone_activity([0.0, 1.0, 2.0], {"task": [0, 3, 5], "presence": [1, 2, 1]}, tmp_path / "act.png")
    assert _is_png(m) and _is_png(a)
    assert plot_pheromone_map(np.zeros((3, 2)), 0.5, tmp_path / "empty.png", title="nothing yet").exists()
    with pytest.raises(ValueError, match="values_xy"):
        plot_pheromone_map(np.zeros(5), 0.1, tmp_path / "bad.png", title="bad")
    with pytest.raises(ValueError, match="marked"):
        plot_pheromone_activity([0.0, 1.0], {"task": [1, 2, 3]}, tmp_path / "bad.png")


def test_a_medium_draws_its_layers_into_the_run_directory(tmp_path):
    g = PheromoneGrid([3.0, 1.0], [LayerSpec("task"), LayerSpec("presence", fatigue=2.0)], snapshot_s=0.2)
    g.deposit("task", [0.6, 0.5, 0.1], 1.0, rule=DepositRule.SET)
    g.deposit("task", [2.7, 0.5, 0.1], -1.0, rule=DepositRule.SET)
    for k in range(8):
        g.deposit("presence", [0.5 + 0.1 * k, 0.5, 0.25], 2.0, rule=DepositRule.SET, source=0)
        g.step(0.1)
    from pybullet_swarm.experiment.runner import write_artefacts
    from pybullet_swarm.plotting.run_plots import plot_saved_artifacts

    files = write_artefacts(tmp_path, g.artefacts()) + plot_saved_artifacts(tmp_path, tmp_path / "plots")
    names = sorted(f.name for f in files)
    assert names == [
        "pheromone_activity.png",
        "pheromone_mass.png",
        "pheromone_presence.png",
        "pheromone_presence_series.png",
        "pheromone_task.png",
        "pheromones.npz",
    ]
    assert all(_is_png(f) for f in files if f.suffix == ".png")
    assert all(f.parent == tmp_path / "plots" for f in files if f.suffix == ".png")
    with np.load(tmp_path / "pheromones.npz") as z:  # the figures can be redrawn from the file alone
        again = plot_pheromones(dict(z), tmp_path / "again", persistent=["task"])
    assert len(again) == 5
