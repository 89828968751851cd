"""Absolute positioning (GPS outdoors, motion capture or a lighthouse system indoors).

A fix is the true position plus white Gaussian noise, taken every ``1 / rate_hz`` s; optionally
it also carries a heading (motion capture sees the whole pose). Fixes can be lost at random
(``dropout_probability`` per agent and fix) and during scheduled outages.

Default figures: 10 Hz and 1 cm per axis (about 1.7 cm in 3-D), the order of an indoor
lighthouse or ultra-wideband-plus-optical system and the GPS noise of the course report's
fusion exercise (sigma_x = sigma_y = 0.01 m); heading 0.01 rad (about 0.6 deg).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.sensing.attitude import wrap_angle, yaw_of


@dataclasses.dataclass(frozen=True)
class PositioningParams:
    """Positioning sensor (same fields as the scenario's ``sensing.positioning``).

    Attributes:
        rate_hz: Hz, fix rate.
        noise_std: m, per-axis standard deviation of a fix.
        heading_noise_std: rad, standard deviation of the heading of a fix (None: fixes carry no heading).
        dropout_probability: probability that an agent's fix is lost, independently per fix.
        outages: ``[start_s, end_s]`` intervals during which no agent gets a fix.
    """

    rate_hz: int = 10
    noise_std: float = 0.01
    heading_noise_std: float | None = 0.01
    dropout_probability: float = 0.0
    outages: Sequence[Sequence[float]] = ()


@dataclasses.dataclass(frozen=True)
class Fix:
    """The fixes of one positioning instant.

    Attributes:
        time_s: s, when the fixes were taken.
        valid: (n,) bool, which agents got a fix.
        positions: (n, 3) m (meaningless where not valid).
        headings: (n,) rad, or None when the sensor gives no heading.
    """

    time_s: float
    valid: NDArray[np.bool_]
    positions: NDArray[np.float64]
    headings: NDArray[np.float64] | None


class PositioningSensor:
    """The positioning receivers of ``n`` agents.

    Args:
        n: number of agents.
        params: rate, noise, dropouts.
        rng: the generator of this sensor's noise and dropouts.
    """

    def __init__(self, n: int, params: PositioningParams, *, rng: np.random.Generator) -> None:
        self.n = n
        self.params = params
        self.rng = rng
        self.outages = np.asarray(params.outages, dtype=float).reshape(-1, 2)
        self.fixes = 0  # agent-fixes delivered
        self.dropped = 0  # agent-fixes lost

    def in_outage(self, t: float) -> bool:
        """True when ``t`` s lies in a scheduled outage."""
        o = self.outages
        return bool(np.any((o[:, 0] <= t) & (t < o[:, 1]))) if o.size else False

    def measure(self, t: float, positions: NDArray[np.float64], quaternions: NDArray[np.float64]) -> Fix:
        """Take the fixes of time ``t`` s from true positions (n, 3) m and attitudes (n, 4)."""
        p = self.params
        # every draw is made whatever happens, so the streams do not depend on the outcomes
        noise = self.rng.normal(0.0, 1.0, size=(self.n, 4))
        lost = self.rng.random(self.n) < p.dropout_probability
        valid = ~lost & (not self.in_outage(t))
        pos = positions + p.noise_std * noise[:, :3]
        heading = None
        if p.heading_noise_std is not None:
            heading = wrap_angle(yaw_of(quaternions) + p.heading_noise_std * noise[:, 3])
        k = int(np.count_nonzero(valid))
        self.fixes += k
        self.dropped += self.n - k
        return Fix(t, valid, pos, heading)

    def neighbour_noise(self, rng: np.random.Generator, count: int) -> NDArray[np.float64]:
        """Noise (count, 3) m of ``count`` sensed neighbour positions (same standard deviation as a fix)."""
        return self.params.noise_std * rng.normal(0.0, 1.0, size=(count, 3))
