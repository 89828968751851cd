"""The default study of a flock: vasarhelyi's eleven parameters, flock.fitness maximised, no penalty."""

from __future__ import annotations

from pybullet_swarm.cli.tune import _task_objective
from pybullet_swarm.experiment.scenario import field_info, load_scenario
from pybullet_swarm.tuning.space import check_ranges, planner_search_space

ELEVEN = [
    "r0_rep",
    "p_rep",
    "r0_frict",
    "C_frict",
    "v_frict",
    "p_frict",
    "a_frict",
    "r0_shill",
    "v_shill",
    "p_shill",
    "a_shill",
]


def test_vasarhelyi_declares_its_eleven_parameters_within_their_ranges() -> None:
    space = planner_search_space("vasarhelyi")
    assert [p.key.removeprefix("planner.params.") for p in space] == ELEVEN
    sc = load_scenario("flocking_confined")
    check_ranges(space, lambda k: field_info(sc, k))  # raises for a range the model refuses
    assert planner_search_space("reynolds") == []


def test_a_flock_is_tuned_on_its_fitness() -> None:
    assert _task_objective("flocking_confined") == ("flock.fitness", "maximize", 0.0)
    assert _task_objective("construction") is None


def test_the_defaults_are_the_first_trial() -> None:
    from pybullet_swarm.cli.tune import _defaults

    base = _defaults("vasarhelyi", planner_search_space("vasarhelyi"))
    assert base["planner.params.r0_rep"] == 2.5 and len(base) == 11
