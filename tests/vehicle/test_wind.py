"""Wind drag against closed forms, seeded Dryden gusts, and refused wind settings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.experiment.simulation import Simulation
from pybullet_swarm.vehicle import load_vehicle
from pybullet_swarm.vehicle.wind import AIR_DENSITY, BOX_DRAG_COEFFICIENT, Gusts, WindParams, form_drag, linear_drag


def test_drag_forces_are_the_closed_forms() -> None:
    f = linear_drag(np.array([0.1, 0.1, 0.2]), np.array([2.0, 0.0, 0.0]), np.array([[1.0, 1.0, -1.0]]))
    assert f[0].tolist() == pytest.approx([0.1, -0.1, 0.2])
    f = form_drag(np.array([0.01]), np.array([3.0, 0.0, 0.0]), np.array([[0.0, 4.0, 0.0]]))  # |u| = 5 m/s
    k = 0.5 * AIR_DENSITY * BOX_DRAG_COEFFICIENT * 0.01 * 5.0
    assert f[0].tolist() == pytest.approx([3.0 * k, -4.0 * k, 0.0])


def test_vehicle_drag_coefficients_are_read_from_the_vehicle_file() -> None:
    assert load_vehicle("quad150").drag_coefficients.tolist() == pytest.approx([0.0309, 0.0309, 0.0347])
    assert load_vehicle("cf2x").drag_coefficients.tolist() == pytest.approx([5.565e-3, 5.565e-3, 6.252e-3])


def test_gusts_are_seeded_and_have_the_given_spread() -> None:
    p = WindParams((2.0, 0.0, 0.0), 0.5, 8.0)
    a = Gusts(200, p, 1.0 / 240.0, np.random.default_rng(3))
    b = Gusts(200, p, 1.0 / 240.0, np.random.default_rng(3))
    for _ in range(240):
        ga, gb = a.step(), b.step()
    assert (ga == gb).all()
    assert float(np.std(ga)) == pytest.approx(0.5, rel=0.1)  # stationary: sigma at every instant
    assert p.correlation_time_s == pytest.approx(4.0)


def test_a_falling_vehicle_is_carried_by_the_wind_as_linear_drag_says() -> None:
    # rotors stopped: horizontally only drag acts, v_x(t) = w (1 - exp(-d t / m))
    sc = load_scenario(
        "hover", ["agents.start=[[1.5, 1.5, 40.0]]", "wind.velocity=[1.0, 0.0, 0.0]", "task.time_limit_s=40"]
    )
    with Simulation(sc) as sim:
        sim.set_open_loop(np.zeros((1, 4)), motor_state=True)
        sim.step(480)  # 2 s
        vx = float(sim.state.velocities[0, 0])
    v = load_vehicle(sc.agents.vehicle)
    expected = 1.0 * (1.0 - math.exp(-v.drag_coefficients[0] * 2.0 / v.mass))
    assert vx == pytest.approx(expected, rel=0.02)


@pytest.mark.parametrize(
    ("override", "field"),
    [
        (["wind.velocity=[1.0, 0.0]"], "wind.velocity"),
        (["wind.turbulence=-1"], "wind.turbulence"),
        (["wind.velocity=[1.0, 0.0, 0.0]", "sim.drag_coefficient=0.1"], "sim.drag_coefficient"),
    ],
)
def test_bad_wind_is_refused(override: list[str], field: str) -> None:
    with pytest.raises(ConfigError, match=field.replace(".", r"\.")):
        load_scenario("hover", override)
