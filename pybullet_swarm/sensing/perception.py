"""The perception stage: one snapshot per planner tick of what every agent perceives.

Planners, avoidance layers and the learning environments' observation builders all read this
snapshot (``pybullet_swarm.types.Perception``); none of them sees the simulation. Who is a
neighbour is decided physically, from true positions within the sensing radius, by one spatial
query over the swarm; what an agent learns about a neighbour is its sensed position (with the
positioning noise when the swarm flies on estimates) and velocity.
"""

from __future__ import annotations

from typing import Callable, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from pybullet_swarm.control.rotations import quat_to_euler
from pybullet_swarm.types import Perception


class Radio(Protocol):
    """What carries neighbour information when it comes by radio (``pybullet_swarm.sensing.comm.Radio``)."""

    def send(self, t: float, true_positions: NDArray[np.float64], velocities: NDArray[np.float64]) -> None:
        """Every agent broadcasts at time t s."""

    def receive(
        self,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``(i, j, d, positions, velocities)`` of the messages received now."""


#: swarms up to this size are searched exhaustively (one vectorised distance matrix)
BRUTE_FORCE_MAX = 48


def neighbour_pairs(
    positions: NDArray[np.float64], radius: float
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """Every ordered pair of distinct agents within ``radius`` m of each other.

    Args:
        positions: (n, 3) m.
        radius: m, inclusive.

    Returns:
        ``(i, j, d)``: (m,) owner ids sorted ascending, (m,) neighbour ids ascending within an owner,
        and (m,) centre distances m.
    """
    n = positions.shape[0]
    if n < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
    if n <= BRUTE_FORCE_MAX:
        diff = positions[:, None, :] - positions[None, :, :]
        d = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
        mask = d <= radius
        np.fill_diagonal(mask, False)
        i, j = np.nonzero(mask)  # row-major: owners ascending, neighbours ascending
        return i.astype(np.int64), j.astype(np.int64), d[i, j]
    pairs = cKDTree(positions).query_pairs(radius, output_type="ndarray").astype(np.int64)  # (p, 2), a < b
    if pairs.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
    i = np.concatenate([pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([pairs[:, 1], pairs[:, 0]])
    order = np.lexsort((j, i))
    i, j = i[order], j[order]
    d = np.linalg.norm(positions[i] - positions[j], axis=1)
    return i, j, d


class PerceptionStage:
    """Builds the swarm's ``Perception`` snapshot once per planner tick.

    Args:
        n: number of agents.
        sensing_radius: m, neighbours within it are perceived.
        position_std: m, per-axis standard deviation of an agent's own position estimate (0 on true state).
        neighbour_noise: draws (k, 3) m of sensing noise for k neighbour measurements (the positioning
            noise, when the swarm flies on estimates), or None: neighbours are seen where they are.
        radio: neighbours are what reaches each agent by radio (``pybullet_swarm.sensing.comm``), or None:
            they are perceived directly.
    """

    def __init__(
        self,
        n: int,
        sensing_radius: float,
        *,
        position_std: float = 0.0,
        neighbour_noise: Callable[[int], NDArray[np.float64]] | None = None,
        radio: Radio | None = None,
    ) -> None:
        self.n = int(n)
        self.radio = radio
        self.radius = float(sensing_radius)
        self.position_std = float(position_std)
        self.neighbour_noise = neighbour_noise
        self._start = np.zeros(self.n + 1, dtype=np.int64)

    def snapshot(
        self,
        t: float,
        true_state: NDArray[np.float64],
        sensed_state: NDArray[np.float64],
        ranges: NDArray[np.float64],
        carrying: NDArray[np.int64],
        *,
        neighbours: bool = True,
    ) -> Perception:
        """The snapshot at time ``t`` s.

        Args:
            true_state: (n, 13) true rows (position, quaternion, velocity, angular velocity).
            sensed_state: (n, 13) what each agent knows of itself (the estimate, or the true rows).
            ranges: (n, r) m, range readings of this tick.
            carrying: (n,) id of the object each agent holds, or -1.
            neighbours: False when no consumer of this snapshot looks at neighbours (a centralised
                planner without an avoidance layer): the neighbour arrays are then empty.
        """
        true_pos = true_state[:, :3]
        if self.radio is not None:  # every tick, heard or not: the radio's messages are sent on time
            self.radio.send(float(t), true_pos, sensed_state[:, 7:10])
        if neighbours and self.radio is not None:
            i, j, d, nb_pos, nb_vel = self.radio.receive()
        elif neighbours:
            i, j, d = neighbour_pairs(true_pos, self.radius)
            nb_pos, nb_vel = true_pos[j], sensed_state[j, 7:10].copy()
            if self.neighbour_noise is not None and j.size:
                nb_pos = nb_pos + self.neighbour_noise(j.size)
        else:
            i, j, d = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
            nb_pos, nb_vel = np.zeros((0, 3)), np.zeros((0, 3))
        start = self._start.copy()
        np.cumsum(np.bincount(i, minlength=self.n), out=start[1:])
        return Perception(
            time_s=float(t),
            positions=sensed_state[:, :3].copy(),
            velocities=sensed_state[:, 7:10].copy(),
            quaternions=sensed_state[:, 3:7].copy(),
            yaws=quat_to_euler(sensed_state[:, 3:7])[:, 2],
            position_std=self.position_std,
            nb_start=start,
            nb_ids=j,
            nb_positions=nb_pos,
            nb_velocities=nb_vel,
            nb_distances=d,
            ranges=np.array(ranges, dtype=float),
            carrying=np.asarray(carrying, dtype=np.int64).copy(),
        )
