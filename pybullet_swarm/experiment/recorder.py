"""Decimated time series in preallocated arrays."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.types import TimeSeries

__all__ = ["Recorder", "TimeSeries"]


class Recorder:
    """Keeps decimated samples of the swarm in preallocated float32 arrays.

    20 float32 channels per agent at the default 20 Hz are 0.96 MB per agent per 10 simulated
    minutes. The arrays grow by doubling if a run outlives ``capacity``.

    Args:
        n: number of agents.
        capacity: expected number of samples.
    """

    def __init__(self, n: int, capacity: int) -> None:
        self.n = n
        self.k = 0
        cap = max(int(capacity), 16)
        self._t = np.zeros(cap, dtype=np.float32)
        self._pose = np.zeros((cap, n, 7), dtype=np.float32)
        self._vel = np.zeros((cap, n, 3), dtype=np.float32)
        self._rotor = np.zeros((cap, n, 4), dtype=np.float32)
        self._refp = np.zeros((cap, n, 3), dtype=np.float32)
        self._refv = np.zeros((cap, n, 3), dtype=np.float32)
        self._extra: dict[str, NDArray[np.float32]] = {}

    def _grow(self) -> None:
        for name in ("_t", "_pose", "_vel", "_rotor", "_refp", "_refv"):
            a = getattr(self, name)
            setattr(self, name, np.concatenate([a, np.zeros_like(a)]))
        for key, a in self._extra.items():
            self._extra[key] = np.concatenate([a, np.zeros_like(a)])

    def record(
        self,
        t: float,
        pose: NDArray[np.float64],
        twist: NDArray[np.float64],
        rotor: NDArray[np.float64],
        ref_p: NDArray[np.float64],
        ref_v: NDArray[np.float64],
    ) -> None:
        """Store one sample (state arrays of the whole swarm)."""
        k = self.k
        if k >= self._t.shape[0]:
            self._grow()
        self._t[k] = t
        self._pose[k] = pose
        self._vel[k] = twist[:, :3]
        self._rotor[k] = rotor
        self._refp[k] = ref_p
        self._refv[k] = ref_v
        self.k = k + 1

    def record_extra(self, name: str, value: NDArray[np.float64]) -> None:
        """Store a task-specific channel for the current sample (call after ``record``)."""
        k = self.k - 1
        arr = self._extra.get(name)
        if arr is None:
            arr = np.zeros((self._t.shape[0], *np.shape(value)), dtype=np.float32)
            self._extra[name] = arr
        arr[k] = value

    def series(self) -> TimeSeries:
        """The samples so far (copies)."""
        k = self.k
        return TimeSeries(
            t=self._t[:k].copy(),
            positions=self._pose[:k, :, :3].copy(),
            quaternions=self._pose[:k, :, 3:].copy(),
            velocities=self._vel[:k].copy(),
            rotor_speeds=self._rotor[:k].copy(),
            ref_positions=self._refp[:k].copy(),
            ref_velocities=self._refv[:k].copy(),
            extra={n: a[:k].copy() for n, a in self._extra.items()},
        )

    @property
    def nbytes(self) -> int:
        """Memory held by the buffers, bytes."""
        return sum(a.nbytes for a in (self._t, self._pose, self._vel, self._rotor, self._refp, self._refv))
