"""Radio range, delay, loss and GPS-like fixes of the comm flight condition."""

from __future__ import annotations

import numpy as np
import pytest

from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.experiment.simulation import Simulation
from pybullet_swarm.sensing.comm import CommParams, Radio

LINE = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [3.0, 0.0, 1.0]])


def _radio(seed: int = 0, **kw: float) -> Radio:
    return Radio(
        3,
        CommParams(**kw),  # type: ignore[arg-type]
        sensing_radius=10.0,
        planner_dt=0.1,
        loss_rng=np.random.default_rng(seed),
        gps_rng=np.random.default_rng(seed + 1),
    )


def test_only_agents_within_radio_range_are_heard() -> None:
    r = _radio(radio_range_m=1.5)
    r.send(0.0, LINE, np.zeros((3, 3)))
    i, j, d, p, _ = r.receive()
    assert list(zip(i.tolist(), j.tolist())) == [(0, 1), (1, 0)]
    assert d.tolist() == [1.0, 1.0] and p.tolist() == [LINE[1].tolist(), LINE[0].tolist()]


def test_messages_arrive_after_the_delay() -> None:
    r = _radio(delay_s=0.2)  # two planner periods
    for k in range(4):
        r.send(0.1 * k, LINE + [k, 0.0, 0.0], np.zeros((3, 3)))
        _, j, _, p, _ = r.receive()
        sent = max(k - 2, 0)  # at the start the oldest message stands in
        assert p[j == 0, 0].tolist() == [float(sent)] * 2  # agent 0 as agents 1 and 2 hear it


def test_packet_loss_drops_that_share_of_messages_reproducibly() -> None:
    kept = []
    for seed in (0, 0, 1):
        r = _radio(seed, packet_loss=0.3)
        n = 0
        for k in range(500):
            r.send(0.1 * k, LINE, np.zeros((3, 3)))
            n += r.receive()[0].size
        kept.append(n)
    assert kept[0] == kept[1] != kept[2]
    assert kept[0] / (500 * 6) == pytest.approx(0.7, abs=0.03)


def test_gps_fixes_come_at_their_rate_with_their_noise() -> None:
    r = _radio(gps_rate_hz=5.0, gps_noise_std_m=0.1)
    r.send(0.0, LINE, np.zeros((3, 3)))
    first = r.receive()[3].copy()
    r.send(0.1, LINE + 1.0, np.zeros((3, 3)))  # no fix due: the old one is sent again
    assert (r.receive()[3] == first).all()
    r.send(0.2, LINE + 1.0, np.zeros((3, 3)))
    now = r.receive()[3]
    assert np.abs(now - (LINE + 1.0)[[1, 2, 0, 2, 0, 1]]).max() < 0.5 and not (now == first).all()


SMALL = ["agents.count=6", "task.time_limit_s=6", "task.warmup_s=2", "arena.size=[8.0, 8.0]", "agents.spacing=1.0"]


def test_runs_with_loss_and_gusts_are_deterministic() -> None:
    cond = SMALL + ["comm.packet_loss=0.3", "comm.delay_s=0.2", "wind.turbulence=0.3", "wind.velocity=[0.2, 0.0, 0.0]"]
    runs = []
    for overrides in (cond, cond, SMALL):
        with Simulation(load_scenario("flocking_confined", overrides)) as sim:
            runs.append(sim.run().timeseries.positions)
    assert (runs[0] == runs[1]).all()
    assert not (runs[0] == runs[2]).all()


@pytest.mark.parametrize(
    ("override", "field"),
    [
        ("comm.packet_loss=1.0", "comm.packet_loss"),
        ("comm.delay_s=-0.1", "comm.delay_s"),
        ("comm.radio_range_m=0", "comm.radio_range_m"),
        ("comm.gps_rate_hz=50", "comm.gps_rate_hz"),
        ("comm.radio=1", "comm.radio"),
    ],
)
def test_bad_comm_is_refused(override: str, field: str) -> None:
    with pytest.raises(ConfigError, match=field.replace(".", r"\.")):
        load_scenario("flocking_confined", [override])
