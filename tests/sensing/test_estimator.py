"""Onboard estimation inside the simulation: flying on the estimate, baselines, determinism, config."""

from __future__ import annotations

import numpy as np
import pytest

import pybullet_swarm
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.plotting.run_plots import plot_run

SHORT = {
    "task.time_limit_s": 12.0,
    "task.waypoints": [{"t_s": 0, "position": [0.0, 0.0, 1.0]}, {"t_s": 2.5, "position": [0.4, -0.3, 1.0]}],
}
NO_NOISE = {
    "sensing.imu.accel_noise_density": 0.0,
    "sensing.imu.gyro_noise_density": 0.0,
    "sensing.imu.accel_bias_std": 0.0,
    "sensing.imu.gyro_bias_std": 0.0,
    "sensing.positioning.noise_std": 0.0,
    "sensing.positioning.heading_noise_std": 0.0,
}


def _strip(m):
    return {k: v for k, v in m.items() if k not in ("wall_time_s", "real_time_factor") and not k.endswith("_ms")}


def test_flying_on_the_estimate_beats_the_fixes_and_dead_reckoning_drifts():
    r = pybullet_swarm.run(load_scenario("hover", {**SHORT, "sensing.state": "estimated"}), seed=1)
    e = r.metrics["estimation"]
    assert r.metrics["tracking_rmse_m"] < 0.05
    assert e["state"] == "estimated"
    assert e["kalman"]["rmse_m"] < 0.75 * e["gps"]["rmse_m"]
    assert e["gps"]["rmse_m"] == pytest.approx(np.sqrt(3) * 0.01, rel=0.25)  # the fixes' own noise
    assert e["imu"]["rmse_m"] > 5 * e["kalman"]["rmse_m"]  # dead reckoning drifts
    assert e["calibration"]["accel_bias_error_m_s2"] < 0.1 * e["calibration"]["accel_bias_m_s2"]
    assert 1.0 < e["kalman"]["position_nees"] < 6.0
    ts = r.timeseries
    assert ts.extra["est_kalman_position"].shape == ts.positions.shape
    assert ts.extra["est_kalman_variance"].shape[-2:] == (3, 3)


def test_zero_noise_estimate_equals_the_truth(make_sim):
    sim = make_sim(load_scenario("hover", {**SHORT, **NO_NOISE, "sensing.state": "estimated"}), seed=0)
    sim.step(8 * sim.physics_hz)
    sim.step(1)  # the estimator runs at the start of a control tick: now it has caught up with the truth
    kalman = sim.metrics()["estimation"]["kalman"]
    # what is left is the IMU's mean acceleration against Bullet's own integration between fixes
    assert kalman["max_error_m"] < 2e-3 and kalman["heading_error_rad"] < 1e-3
    np.testing.assert_allclose(sim.sensed_state_array[:, :3], sim.state_array[:, :3], atol=2e-3)
    np.testing.assert_allclose(sim.estimation.state_array[:, 7:10], sim.state_array[:, 7:10], atol=0.02)
    assert abs(float(np.sum(sim.estimation.attitude.q * sim.state_array[:, 3:7]))) == pytest.approx(1.0, abs=1e-6)


def test_same_seed_same_estimates_and_other_seed_differs():
    sc = load_scenario("hover", {**SHORT, "task.time_limit_s": 4.0, "sensing.state": "estimated"})
    a, b, c = (pybullet_swarm.run(sc, seed=s) for s in (5, 5, 6))
    assert _strip(a.metrics) == _strip(b.metrics)
    for name, arr in a.timeseries.extra.items():
        assert np.array_equal(arr, b.timeseries.extra[name]), name
    assert np.array_equal(a.timeseries.positions, b.timeseries.positions)
    assert a.metrics["estimation"]["kalman"]["rmse_m"] != c.metrics["estimation"]["kalman"]["rmse_m"]


def test_estimator_on_true_state_changes_nothing_else():
    base = pybullet_swarm.run(
        load_scenario("hover_swarm", {**SHORT, "agents.count": 3, "task.time_limit_s": 3.0}), seed=2
    )
    watched = pybullet_swarm.run(
        load_scenario(
            "hover_swarm", {**SHORT, "agents.count": 3, "task.time_limit_s": 3.0, "sensing.run_estimator": True}
        ),
        seed=2,
    )
    assert np.array_equal(base.timeseries.positions, watched.timeseries.positions)
    assert "estimation" not in base.metrics and watched.metrics["estimation"]["state"] == "true"


def test_observations_use_the_estimate_and_noisy_neighbours(make_sim):
    sc = load_scenario(
        "hover_swarm",
        {
            **SHORT,
            "agents.count": 3,
            "agents.spacing": 0.4,
            "task.time_limit_s": 5.0,
            "sensing.state": "estimated",
            "sensing.positioning.noise_std": 0.05,
        },
    )
    sim = make_sim(sc, seed=0)
    sim.step(48)
    est, true = sim.estimation.state_array, sim.state_array
    offsets = []
    for _ in range(40):
        obs = sim.observations()
        for o in obs:
            assert np.array_equal(o.position, est[o.agent_id, :3])
            offsets.append(o.neighbour_positions - true[o.neighbour_ids, :3])
    off = np.concatenate(offsets)
    assert off.std() == pytest.approx(0.05, rel=0.2)
    np.testing.assert_allclose(sim.world_view().positions, est[:, :3])


def test_dropouts_and_outages_are_counted_and_coasted_through():
    r = pybullet_swarm.run(
        load_scenario(
            "hover",
            {
                **SHORT,
                "sensing.state": "estimated",
                "sensing.positioning.dropout_probability": 0.3,
                "sensing.positioning.outages": [[3.0, 5.0]],
            },
        ),
        seed=3,
    )
    e = r.metrics["estimation"]
    total = e["fixes"] + e["fixes_dropped"]
    assert total == pytest.approx(10 * r.metrics["sim_time_s"], abs=1.5)
    assert e["fixes_dropped"] >= 20 + 0.15 * (total - 20)
    assert e["kalman"]["rmse_m"] < 0.03
    assert r.metrics["tracking_rmse_m"] < 0.06


@pytest.mark.parametrize(
    "override, field",
    [
        ("sensing.state=false", "sensing.state"),
        ("sensing.state=estimate", "sensing.state"),
        ("sensing.positioning.rate_hz=7", "sensing.positioning.rate_hz"),
        ("sensing.positioning.rate_hz=120", "sensing.positioning.rate_hz"),
        ("sensing.positioning.outages=[[5, 1]]", "sensing.positioning.outages[0]"),
        ("sensing.imu.gyro_bias=[0.1]", "sensing.imu.gyro_bias"),
        ("sensing.estimator.calibration_s=-1", "sensing.estimator.calibration_s"),
    ],
)
def test_bad_sensing_configuration_is_one_line(override, field):
    with pytest.raises(ConfigError) as info:
        load_scenario("hover", [override])
    msg = str(info.value)
    assert msg.startswith(f"hover.yaml: {field}: ") and "\n" not in msg


def test_state_spellings_are_normalised():
    for value in (True, "true"):
        assert load_scenario("hover", {"sensing.state": value}).data["sensing"]["state"] == "true"
    assert load_scenario("hover", ["sensing.state=estimated"]).data["sensing"]["state"] == "estimated"


def test_estimation_figures_are_drawn(tmp_path):
    r = pybullet_swarm.run(load_scenario("hover", {**SHORT, "task.time_limit_s": 3.0, "sensing.state": "estimated"}))
    files = plot_run(r.timeseries, tmp_path, r.metrics, scenario=r.scenario.data, events=r.events)
    names = {f.name for f in files}
    assert {"estimation_axes.png", "estimation_error.png", "estimation_variance.png"} <= names
    assert all((tmp_path / n).stat().st_size > 10_000 for n in names if n.startswith("estimation"))
