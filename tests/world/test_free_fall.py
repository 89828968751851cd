"""Free fall of an unpowered airframe against z = z0 - g t^2 / 2."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import physics_scenario


@pytest.mark.parametrize("vehicle", ["quad150", "cf2x"])
def test_free_fall_matches_closed_form(make_sim, vehicle):
    sim = make_sim(physics_scenario(start_z=20.0, vehicle=vehicle))
    sim.set_open_loop(np.zeros((1, 4)), motor_state=True)
    z0 = sim.state.positions[0, 2]
    sim.step(sim.physics_hz)            # 1 s
    g = sim.scenario.sim.gravity
    drop = z0 - sim.state.positions[0, 2]
    expected = 0.5 * g * 1.0**2
    assert drop == pytest.approx(expected, rel=0.005)
    # velocity after 1 s is g t, horizontal motion and rotation stay zero
    assert sim.state.velocities[0, 2] == pytest.approx(-g, rel=1e-3)
    assert np.abs(sim.state.positions[0, :2] - [1.5, 1.5]).max() < 1e-9
    assert np.abs(sim.state.body_rates).max() < 1e-9


def test_gravity_setting_is_used(make_sim):
    sim = make_sim(physics_scenario(start_z=20.0, **{"sim.gravity": 3.7}))
    sim.set_open_loop(np.zeros((1, 4)), motor_state=True)
    sim.step(sim.physics_hz)
    assert sim.state.velocities[0, 2] == pytest.approx(-3.7, rel=1e-3)
