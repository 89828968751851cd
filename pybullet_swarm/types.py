"""Values that cross layers: swarm state, references, exit status, events."""

from __future__ import annotations

import dataclasses
import enum
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray


class ExitStatus(str, enum.Enum):
    """How a simulation ended."""

    RUNNING = "running"
    COMPLETED = "completed"  # the task's completion condition held
    TIMEOUT = "timeout"  # the time limit was reached first
    CRASHED = "crashed"  # an agent flipped over or hit the ground hard
    DIVERGED = "diverged"  # a state became non-finite or left the world
    STALLED = "stalled"  # the task made no progress for its stall time


@dataclasses.dataclass(frozen=True)
class SwarmState:
    """Kinematic state of all agents (world frame, SI units).

    Attributes:
        positions: (n, 3) m, centre of mass.
        quaternions: (n, 4) unit quaternions, scalar last (x, y, z, w) as in Bullet.
        velocities: (n, 3) m/s.
        body_rates: (n, 3) rad/s, angular velocity in the body frame.
    """

    positions: NDArray[np.float64]
    quaternions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    body_rates: NDArray[np.float64]

    @property
    def n(self) -> int:
        """Number of agents."""
        return int(self.positions.shape[0])


@dataclasses.dataclass(frozen=True)
class Event:
    """Something that happened at one instant of a run (a contact onset, a grasp, a crash).

    Attributes:
        time_s: simulated time, s.
        kind: short machine-readable kind, e.g. ``agent_agent`` or ``crash``.
        a: first participant (agent id, or body name).
        b: second participant, '' when there is none.
        detail: free text for humans.
    """

    time_s: float
    kind: str
    a: str
    b: str = ""
    detail: str = ""


@dataclasses.dataclass(frozen=True)
class TimeSeries:
    """Recorded time series of a run (float32 to keep runs small).

    Attributes:
        t: (m,) s.
        positions: (m, n, 3) m.
        quaternions: (m, n, 4) (x, y, z, w).
        velocities: (m, n, 3) m/s.
        rotor_speeds: (m, n, 4) rad/s.
        ref_positions: (m, n, 3) m.
        ref_velocities: (m, n, 3) m/s.
    """

    t: NDArray[np.float32]
    positions: NDArray[np.float32]
    quaternions: NDArray[np.float32]
    velocities: NDArray[np.float32]
    rotor_speeds: NDArray[np.float32]
    ref_positions: NDArray[np.float32]
    ref_velocities: NDArray[np.float32]
    extra: dict[str, NDArray[np.float32]] = dataclasses.field(default_factory=dict)

    def save(self, path: Path) -> None:
        """Write to an ``.npz`` file (arrays by name; ``extra`` arrays prefixed with ``extra_``)."""
        with open(path, "wb") as fh:
            self.save_to(fh)

    def save_to(self, fh: Any) -> None:
        """Write the ``.npz`` content to an open binary file."""
        arrays = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "extra"}
        arrays.update({f"extra_{k}": v for k, v in self.extra.items()})
        np.savez_compressed(fh, **arrays)

    @classmethod
    def load(cls, path: Path) -> TimeSeries:
        """Read a file written by ``save``."""
        with np.load(path) as z:
            names = [f.name for f in dataclasses.fields(cls) if f.name != "extra"]
            extra = {k[6:]: z[k] for k in z.files if k.startswith("extra_")}
            return cls(**{k: z[k] for k in names}, extra=extra)


@dataclasses.dataclass(frozen=True)
class Perception:
    """What every agent perceives at one planner tick: one snapshot for the whole swarm.

    Built once per planner tick by ``pybullet_swarm.sensing.perception.PerceptionStage`` and
    shared by planners, avoidance layers and the learning environments' observation builders.
    Row ``i`` is what agent ``i`` knows; nothing here is another agent's private state.

    Attributes:
        time_s: simulated time, s.
        positions: (n, 3) m, each agent's own position (the estimate when flying on it).
        velocities: (n, 3) m/s, own velocity, likewise.
        quaternions: (n, 4) own attitude (x, y, z, w).
        yaws: (n,) rad, own heading.
        position_std: m, per-axis standard deviation an agent can expect of its own position
            (0 on true state).
        nb_start: (n + 1,) offsets into the neighbour arrays: agent i's neighbours are rows
            ``nb_start[i]:nb_start[i + 1]`` (CSR layout), in increasing agent index.
        nb_ids: (m,) neighbour agent ids (within the sensing radius of the agent, from one spatial
            query over the swarm).
        nb_positions: (m, 3) m, the neighbours' positions as the agent senses them.
        nb_velocities: (m, 3) m/s, their velocities as sensed.
        nb_distances: (m,) m, true centre distances (what decides who is in range).
        ranges: (n, r) m, range readings of this tick (r = 0 without range sensors).
        carrying: (n,) id of the object each agent holds, or -1.
    """

    time_s: float
    positions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    quaternions: NDArray[np.float64]
    yaws: NDArray[np.float64]
    position_std: float
    nb_start: NDArray[np.int64]
    nb_ids: NDArray[np.int64]
    nb_positions: NDArray[np.float64]
    nb_velocities: NDArray[np.float64]
    nb_distances: NDArray[np.float64]
    ranges: NDArray[np.float64]
    carrying: NDArray[np.int64]

    @property
    def n(self) -> int:
        """Number of agents."""
        return int(self.positions.shape[0])

    def neighbours(self, i: int) -> slice:
        """Rows of agent ``i``'s neighbours in the ``nb_*`` arrays."""
        return slice(int(self.nb_start[i]), int(self.nb_start[i + 1]))

    def nearest_table(self, k: int) -> NDArray[np.int64]:
        """(n, min(k, n - 1) + 1) ids of up to ``k`` nearest neighbours of each agent (within the sensing
        radius), nearest first, padded with -1 (one spare column, so that a table is never empty)."""
        n = self.n
        k = max(min(int(k), n - 1), 0)
        out = np.full((n, k + 1), -1, dtype=np.int64)
        counts = np.diff(self.nb_start)
        if self.nb_ids.size == 0 or k < 1:
            return out
        owner = np.repeat(np.arange(n), counts)
        order = np.lexsort((self.nb_ids, self.nb_distances, owner))  # by agent, then distance
        rank = np.arange(order.size) - np.repeat(self.nb_start[:-1], counts)
        keep = rank < k
        out[owner[keep], rank[keep]] = self.nb_ids[order][keep]
        return out
