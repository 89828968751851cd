"""Whole runs: determinism, exit statuses, recorder budget, run directories, the Python API."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from conftest import physics_scenario

import pybullet_swarm
from pybullet_swarm.experiment.recorder import Recorder, TimeSeries
from pybullet_swarm.types import ExitStatus

TIMING_KEYS = {"wall_time_s", "real_time_factor"}


def _strip(metrics):
    return {k: v for k, v in metrics.items() if k not in TIMING_KEYS and not k.endswith("_ms")}


def test_hover_scenario_completes_and_tracks():
    r = pybullet_swarm.run("hover")
    assert r.exit_status is ExitStatus.COMPLETED
    m = r.metrics
    assert m["completion_time_s"] == pytest.approx(m["sim_time_s"])
    assert 20.0 < m["completion_time_s"] < 30.0
    assert m["tracking_rmse_m"] < 0.03
    assert sum(m["collisions"].values()) == 0
    final = r.timeseries.positions[-1, 0].astype(float)
    start = r.timeseries.positions[0, 0].astype(float)
    assert np.allclose(final - start, [0.5, 0.5, 1.5], atol=0.03)


def test_same_seed_gives_identical_metrics_and_series():
    sc = pybullet_swarm.load_scenario(
        "hover_swarm",
        overrides={"agents.count": 4, "task.time_limit_s": 6.0, "task.waypoints": [{"t_s": 0, "position": [0, 0, 1]}]},
    )
    a = pybullet_swarm.run(sc, seed=3)
    b = pybullet_swarm.run(sc, seed=3)
    assert _strip(a.metrics) == _strip(b.metrics)
    for name in ("t", "positions", "quaternions", "velocities", "rotor_speeds", "ref_positions"):
        assert np.array_equal(getattr(a.timeseries, name), getattr(b.timeseries, name)), name
    assert a.metrics["seed"] == 3


def test_timeout_when_task_cannot_finish():
    sc = physics_scenario(start_z=0.02, **{"task.time_limit_s": 2.0})
    r = pybullet_swarm.run(sc)
    assert r.exit_status is ExitStatus.TIMEOUT
    assert r.metrics["sim_time_s"] == pytest.approx(2.0, abs=0.11)
    assert r.metrics["completion_time_s"] is None


def test_crash_when_agent_flips(make_sim):
    sim = make_sim(physics_scenario(start_z=3.0))
    # a 90 deg roll rate kick with rotors off: the airframe tumbles and is reported crashed
    sim.set_open_loop(np.zeros((1, 4)), motor_state=True)
    sim.world.reset_agent(0, [1.5, 1.5, 3.0], angular_velocity=[20.0, 0.0, 0.0])
    sim.step(sim.physics_hz)
    assert sim.exit_status is ExitStatus.CRASHED
    assert sim.crashed_agent == 0
    crash = [e for e in sim.events if e.kind == "crashed"]
    assert crash and "no agent-agent contact" in crash[0].detail  # alone: neither a contact nor a wake
    assert sim.crash_cause == "other" and sim.metrics()["crash_cause"] == "other"


@pytest.mark.parametrize("contact_hz", [None, 48], ids=["every_step", "every_control_tick"])
def test_hard_ground_impact_is_a_crash(make_sim, contact_hz):
    # read at the control rate, the impact's speed is the lowest vertical velocity since the last read
    sim = make_sim(physics_scenario(start_z=2.0, **{"sim.contact_hz": contact_hz}))
    sim.set_open_loop(np.zeros((1, 4)), motor_state=True)
    sim.world.reset_agent(0, [1.5, 1.5, 2.0], velocity=[0.0, 0.0, -4.0])
    sim.step(2 * sim.physics_hz)
    assert sim.exit_status is ExitStatus.CRASHED
    assert "ground" in sim.events[-1].detail


def test_non_finite_state_is_diverged(make_sim):
    sim = make_sim(physics_scenario(start_z=1.0))
    sim.world.reset_agent(0, [1.5, 1.5, 1.0], velocity=[0.0, 0.0, 1e6])  # Bullet clamps to 100 m/s
    sim.step(10)
    assert sim.exit_status is ExitStatus.DIVERGED
    sim2 = make_sim(physics_scenario(start_z=1.0))
    sim2.world.reset_agent(0, [1.5, 1.5, float("nan")])
    sim2.step(10)
    assert sim2.exit_status is ExitStatus.DIVERGED
    assert np.isfinite(sim2.controller.forces).all()


def test_recorder_budget_one_megabyte_per_agent_per_ten_minutes():
    sc = pybullet_swarm.load_scenario("hover")
    samples = int(600 * sc.sim.record_hz)
    rec = Recorder(1, samples)
    assert rec.nbytes <= 1_000_000 * 1.0486  # 1 MiB
    rec2 = Recorder(4, 3)
    z = np.zeros((4, 13))
    for k in range(10):  # grows past its capacity without losing samples
        rec2.record(float(k), z[:, :7], z[:, 7:], np.zeros((4, 4)), np.zeros((4, 3)), np.zeros((4, 3)))
    assert rec2.series().t.tolist() == [float(k) for k in range(10)]


def test_run_directory_contents(tmp_path):
    out = tmp_path / "run"
    r = pybullet_swarm.run(
        "hover",
        out=out,
        overrides={"task.time_limit_s": 3.0, "task.waypoints": [{"t_s": 0.0, "position": [0.0, 0.0, 0.5]}]},
    )
    assert r.run_dir == out
    metrics = json.loads((out / "metrics.json").read_text())
    for key in ("exit_status", "sim_time_s", "wall_time_s", "real_time_factor", "seed"):
        assert key in metrics
    scenario = yaml.safe_load((out / "scenario.yaml").read_text())
    assert scenario["task"]["time_limit_s"] == 3.0
    ts = TimeSeries.load(out / "timeseries.npz")
    assert np.array_equal(ts.positions, r.timeseries.positions)
    for name in ("position.png", "attitude.png", "rotor_speeds.png"):
        assert (out / "plots" / name).stat().st_size > 10_000
    assert not list(out.glob(".*tmp*"))
    # the resolved scenario of a run reproduces it
    r2 = pybullet_swarm.run(out / "scenario.yaml")
    assert _strip(r2.metrics) == _strip(r.metrics) | {"scenario": r2.metrics["scenario"]}
