"""The pheromone grid: cells, queued deposits, fading against closed forms, strongest cell, files."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pybullet_swarm.planning.pheromone_grid import NO_SOURCE, DepositRule, LayerSpec, PheromoneGrid


def _grid(**layer_kw) -> PheromoneGrid:
    return PheromoneGrid([3.0, 1.0], [LayerSpec("task", **layer_kw)], cell=0.1, height=1.0)


def test_thesis_grid_is_30_by_10_by_10_and_clips_outside_points():
    g = _grid()
    assert g.shape == (30, 10, 10)
    assert g.index([0.0, 0.0, 0.0]).tolist() == [0, 0, 0]
    assert g.index([0.3, 0.25, 0.999]).tolist() == [3, 2, 9]  # 0.3 / 0.1 lands in cell 3, not 2
    assert g.index([-1.0, 5.0, 0.55]).tolist() == [0, 9, 5]  # outside: clipped into the border cells
    assert np.allclose(g.centre([3, 2, 9]), [0.35, 0.25, 0.95])


def test_deposits_take_effect_at_the_next_step_whatever_the_order_of_the_agents():
    g = _grid()
    p = [1.23, 0.45, 0.3]
    g.deposit("task", p, 0.2, rule=DepositRule.SET, source=0)
    g.deposit("task", p, 1.0, rule=DepositRule.SET, source=1)
    assert g.sample("task", p) == 0.0  # nobody sees a mark of this tick yet
    g.step(0.1)
    assert g.sample("task", p) == 1.0  # the stronger mark of the tick wins
    assert g.sources["task"][tuple(g.index(p))] == 1
    g.deposit("task", p, 0.5)  # ADD amplifies
    g.deposit("task", p, 0.25)
    g.step(0.1)
    assert g.sample("task", p) == pytest.approx(1.75)
    assert g.deposits["task"] == 4


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(0, 5), st.sampled_from([-1.0, 0.2, 1.0, 2.0]), st.integers(0, 4)), min_size=1, max_size=12
    ),
    st.randoms(use_true_random=False),
)
def test_set_marks_of_one_tick_resolve_independently_of_order(marks, rnd):
    """Per cell the mark of largest magnitude wins, whichever agent planned first (ties aside)."""
    unique = {}
    for cell, value, src in marks:  # keep one mark per (cell, |value|) so there are no ties
        unique.setdefault((cell, abs(value)), (cell, value, src))
    marks = list(unique.values())
    shuffled = list(marks)
    rnd.shuffle(shuffled)
    grids = []
    for order in (marks, shuffled):
        g = _grid()
        for cell, value, src in order:
            g.deposit("task", [0.05 + 0.1 * cell, 0.05, 0.05], value, rule=DepositRule.SET, source=src)
        g.step(0.1)
        grids.append(g)
    assert np.array_equal(grids[0].values["task"], grids[1].values["task"])
    assert np.array_equal(grids[0].sources["task"], grids[1].sources["task"])
    for cell in {c for c, _, _ in marks}:
        strongest = max((v for c, v, _ in marks if c == cell), key=abs)
        assert grids[0].values["task"][cell, 0, 0] == strongest


def test_fatigue_erases_a_presence_mark_in_one_second():
    """Thesis Table 6.1: value 2, fatigue 2/s -> 2 - 2 t, gone after 1 s; negative values fade towards 0 too."""
    g = PheromoneGrid([3.0, 1.0], [LayerSpec("presence", fatigue=2.0), LayerSpec("task", fatigue=0.5)])
    p, q = [0.5, 0.5, 0.25], [2.0, 0.5, 0.25]
    g.deposit("presence", p, 2.0, rule=DepositRule.SET, source=3)
    g.deposit("task", q, -1.0, rule=DepositRule.SET, source=3)
    g.step(0.1)
    seen = []
    for _ in range(12):
        seen.append(g.sample("presence", p))
        g.step(0.1)
    assert np.allclose(seen[:10], [2.0 - 0.2 * k for k in range(10)])
    assert seen[10] == seen[11] == 0.0
    assert g.sources["presence"][tuple(g.index(p))] == NO_SOURCE  # a faded mark belongs to nobody
    assert g.sample("task", q) == pytest.approx(-1.0 + 0.5 * 1.2)


def test_evaporation_is_exponential():
    g = _grid(evaporation=0.5)
    p = [1.0, 0.5, 0.5]
    g.deposit("task", p, 4.0)
    g.step(0.0)
    for _ in range(20):
        g.step(0.1)
    assert g.sample("task", p) == pytest.approx(4.0 * math.exp(-0.5 * 2.0), rel=1e-12)


def test_strongest_cell_by_sign_with_ties_to_the_nearest_and_optional_distance_effect():
    g = _grid()
    assert g.strongest("task", +1) is None
    for p, v in (
        ([0.45, 0.35, 0.1], 1.0),
        ([0.85, 0.55, 0.1], 1.0),
        ([2.75, 0.45, 0.1], -1.0),
        ([1.55, 0.45, 0.3], 0.2),
    ):
        g.deposit("task", p, v, rule=DepositRule.SET)
    g.step(0.1)
    assert np.allclose(g.strongest("task", -1), [2.75, 0.45, 0.15])
    assert np.allclose(g.strongest("task", +1, near=[0.0, 0.3, 0.3]), [0.45, 0.35, 0.15])
    assert np.allclose(g.strongest("task", +1, near=[1.0, 0.6, 0.3]), [0.85, 0.55, 0.15])
    # with a short distance scale the weak trail next to the agent beats the far boxes
    assert np.allclose(g.strongest("task", +1, near=[1.55, 0.45, 0.3], distance_scale=0.05), [1.55, 0.45, 0.35])
    with pytest.raises(ValueError, match="sign"):
        g.strongest("task", 0)
    # drawn at random, equally strong cells all get chosen (agents spread over every found box)
    rng = np.random.default_rng(0)
    picks = {tuple(np.round(g.strongest("task", +1, near=[0.0, 0.3, 0.3], rng=rng), 2)) for _ in range(40)}
    assert picks == {(0.45, 0.35, 0.15), (0.85, 0.55, 0.15)}
    # the first in a given axis order, whatever ``near`` is: y most significant, then z, then x
    assert np.allclose(g.strongest("task", +1, near=[0.9, 0.6, 0.1], first_by=(1, 2, 0)), [0.45, 0.35, 0.15])
    g.deposit("task", [0.15, 0.35, 0.5], 1.0, rule=DepositRule.SET)  # same y, higher: z decides before x
    g.step(0.1)
    assert np.allclose(g.strongest("task", +1, first_by=(1, 2, 0)), [0.45, 0.35, 0.15])
    assert np.allclose(g.strongest("task", +1, first_by=(0, 1, 2)), [0.15, 0.35, 0.55])


def test_a_column_marked_at_several_altitudes_is_drawn_as_often_as_one_marked_once():
    g = _grid()
    for z in (0.05, 0.15, 0.25):  # three boxes placed on top of each other
        g.deposit("task", [2.75, 0.25, z], -1.0, rule=DepositRule.SET)
    g.deposit("task", [2.75, 0.65, 0.05], -1.0, rule=DepositRule.SET)
    g.step(0.1)
    rng = np.random.default_rng(1)
    stacked = sum(g.strongest("task", -1, rng=rng, by_column=True)[1] < 0.5 for _ in range(2000))
    assert 0.45 < stacked / 2000 < 0.55
    rng = np.random.default_rng(1)
    stacked = sum(g.strongest("task", -1, rng=rng)[1] < 0.5 for _ in range(2000))
    assert 0.7 < stacked / 2000 < 0.8  # cell by cell the stacked column wins 3 draws in 4


def test_an_agent_can_ignore_its_own_marks():
    g = _grid()
    p, q = [1.0, 0.5, 0.25], [1.1, 0.5, 0.25]
    g.deposit("task", p, 2.0, rule=DepositRule.SET, source=4)
    g.deposit("task", q, 2.0, rule=DepositRule.SET, source=1)
    g.step(0.1)
    assert g.values_at("task", [p, q]).tolist() == [2.0, 2.0]
    assert g.values_at("task", [p, q], exclude_source=4).tolist() == [0.0, 2.0]


def test_projection_keeps_the_sign_of_the_largest_magnitude_in_each_column():
    g = _grid()
    g.deposit("task", [0.05, 0.05, 0.05], 0.2)
    g.deposit("task", [0.05, 0.05, 0.55], -1.0)
    g.deposit("task", [0.15, 0.05, 0.35], 1.0)
    g.step(0.1)
    top = g.projection("task")
    assert top.shape == (30, 10)
    assert top[0, 0] == -1.0 and top[1, 0] == 1.0 and top[2, 0] == 0.0


def test_metrics_are_json_and_write_saves_the_layers(tmp_path):
    g = PheromoneGrid([3.0, 1.0], [LayerSpec("task"), LayerSpec("presence", fatigue=2.0)], snapshot_s=0.5)
    g.deposit("task", [0.5, 0.5, 0.1], 1.0, rule=DepositRule.SET, source=2)
    g.tally("boxes_found")
    for _ in range(10):
        g.deposit("presence", [1.0, 0.5, 0.25], 2.0, rule=DepositRule.SET, source=0)
        g.step(0.1)
    m = g.metrics()
    json.dumps(m)
    assert m["pheromone"]["task"] == {"cells_marked": 1, "max": 1.0, "min": 0.0, "deposits": 1}
    assert m["pheromone"]["presence"]["deposits"] == 10
    assert m["pheromone"]["tallies"] == {"boxes_found": 1}
    from pybullet_swarm.experiment.runner import write_artefacts

    files = write_artefacts(tmp_path, g.artefacts())
    assert [f.name for f in files] == ["pheromones.npz"]
    with np.load(files[0]) as z:
        assert z["persistent"].tolist() == ["task"]
        assert np.array_equal(z["task"], g.values["task"])
        assert z["layers"].tolist() == ["task", "presence"]
        assert np.allclose(z["snapshot_t"], [0.1, 0.5, 1.0])  # first tick, then every 0.5 s
        assert z["presence_history"].shape == (3, 30, 10)
        assert z["presence_marked"].tolist() == [1, 1, 1]
    assert not list(tmp_path.glob(".*tmp*"))


def test_bad_configuration_is_refused():
    with pytest.raises(ValueError, match="cell"):
        PheromoneGrid([3.0, 1.0], [LayerSpec("a")], cell=0.0)
    with pytest.raises(ValueError, match="unique"):
        PheromoneGrid([3.0, 1.0], [LayerSpec("a"), LayerSpec("a")])
    with pytest.raises(ValueError, match="arena_size"):
        PheromoneGrid([3.0, -1.0], [LayerSpec("a")])
    with pytest.raises(ValueError, match="fatigue"):
        LayerSpec("a", fatigue=-1.0)
    g = _grid()
    with pytest.raises(KeyError, match="unknown pheromone layer 'presence'"):
        g.sample("presence", [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="amount"):
        g.deposit("task", [0.0, 0.0, 0.0], float("nan"))
