"""Neighbour information by radio: limited range, delay, packet loss and GPS-like position fixes.

With a ``comm`` section in the scenario, what an agent learns of its neighbours in the perception
snapshot is what reached it by radio, instead of what it would perceive directly:

* every planner tick each agent broadcasts its last position fix and its velocity; fixes come
  from a GPS-like source at ``gps_rate_hz`` (None: at every tick) with Gaussian noise
  ``gps_noise_std_m`` per axis (velocity noise ``gps_velocity_noise_std``, drawn with each fix);
* a message reaches the agents within ``radio_range_m`` (and ``agents.sensing_radius``) of the
  sender, judged on true positions when it is sent;
* it is received ``delay_s`` later: at time t an agent holds the messages of the last tick at or
  before t - delay_s (the delay is counted in whole planner periods, rounded down; at the start of
  a run the oldest messages stand in);
* each message to each neighbour is lost with probability ``packet_loss``, independently: a
  neighbour whose message was lost is not heard this tick (no memory of older messages).

The fixes' noise and the losses come from the run's ``comm/gps`` and ``comm/loss`` random streams.
"""

from __future__ import annotations

import collections
import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.sensing.perception import neighbour_pairs


@dataclasses.dataclass(frozen=True)
class CommParams:
    """The radio and the position source (the scenario's ``comm`` section).

    Attributes:
        radio_range_m: m, reach of a message (None: unlimited).
        delay_s: s, from sending to receiving.
        packet_loss: probability that one message to one neighbour is lost.
        gps_rate_hz: Hz, position fixes per second (None: one every planner tick).
        gps_noise_std_m: m per axis.
        gps_velocity_noise_std: m/s per axis.
    """

    radio_range_m: float | None = None
    delay_s: float = 0.0
    packet_loss: float = 0.0
    gps_rate_hz: float | None = None
    gps_noise_std_m: float = 0.0
    gps_velocity_noise_std: float = 0.0


@dataclasses.dataclass(frozen=True)
class _Broadcast:
    t: float
    true_positions: NDArray[np.float64]  # (n, 3) m, who hears it is judged on these
    positions: NDArray[np.float64]  # (n, 3) m, the fixes sent
    velocities: NDArray[np.float64]  # (n, 3) m/s


class Radio:
    """Broadcasts, delays and loses the agents' messages (one ``receive`` per planner tick).

    Args:
        n: number of agents.
        params: the radio and the position source.
        sensing_radius: m, agents farther apart never hear each other.
        planner_dt: s, the planner period.
        loss_rng: the run's ``comm/loss`` stream.
        gps_rng: the run's ``comm/gps`` stream.
    """

    def __init__(
        self,
        n: int,
        params: CommParams,
        *,
        sensing_radius: float,
        planner_dt: float,
        loss_rng: np.random.Generator,
        gps_rng: np.random.Generator,
    ) -> None:
        self.n = int(n)
        self.params = params
        r = params.radio_range_m
        self.radius = float(sensing_radius) if r is None else min(float(r), float(sensing_radius))
        self.delay_ticks = int(math.floor(params.delay_s / planner_dt + 1e-9))
        self.fix_period = 0.0 if params.gps_rate_hz is None else 1.0 / params.gps_rate_hz
        self.loss_rng = loss_rng
        self.gps_rng = gps_rng
        self.history: collections.deque[_Broadcast] = collections.deque(maxlen=self.delay_ticks + 1)
        self._fix_t = -math.inf
        self._fix_p = np.zeros((self.n, 3))
        self._fix_v = np.zeros((self.n, 3))

    def _fix(self, t: float, positions: NDArray[np.float64], velocities: NDArray[np.float64]) -> None:
        """A new position fix (n, 3) m when one is due at time t s."""
        if t - self._fix_t < self.fix_period - 1e-9:
            return
        p = self.params
        self._fix_t = t
        self._fix_p = positions + (
            p.gps_noise_std_m * self.gps_rng.standard_normal((self.n, 3)) if p.gps_noise_std_m > 0 else 0.0
        )
        self._fix_v = velocities + (
            p.gps_velocity_noise_std * self.gps_rng.standard_normal((self.n, 3))
            if p.gps_velocity_noise_std > 0
            else 0.0
        )

    def send(self, t: float, true_positions: NDArray[np.float64], velocities: NDArray[np.float64]) -> None:
        """Every agent broadcasts at time t s (once per tick: a second call at the same instant is ignored)."""
        if self.history and t <= self.history[-1].t + 1e-12:
            return
        self._fix(t, np.asarray(true_positions, dtype=float), np.asarray(velocities, dtype=float))
        self.history.append(
            _Broadcast(t, np.array(true_positions, dtype=float), self._fix_p.copy(), self._fix_v.copy())
        )

    def receive(
        self,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The messages received now: ``(i, j, d, positions, velocities)``, receiver ids ascending (m,), sender
        ids ascending within a receiver (m,), distances when sent (m,) m, sent fixes (m, 3) m, velocities (m, 3) m/s."""
        msg = self.history[0]  # the deque holds delay_ticks + 1 broadcasts: the oldest is the one due now
        i, j, d = neighbour_pairs(msg.true_positions, self.radius)
        if self.params.packet_loss > 0.0 and i.size:
            keep = self.loss_rng.random(i.size) >= self.params.packet_loss
            i, j, d = i[keep], j[keep], d[keep]
        return i, j, d, msg.positions[j], msg.velocities[j]
