"""Values that cross layers: swarm state, references, exit status, events."""
from __future__ import annotations

import dataclasses
import enum

import numpy as np
from numpy.typing import NDArray


class ExitStatus(str, enum.Enum):
    """How a simulation ended."""

    RUNNING = "running"
    COMPLETED = "completed"   # the task's completion condition held
    TIMEOUT = "timeout"       # the time limit was reached first
    CRASHED = "crashed"       # an agent flipped over or hit the ground hard
    DIVERGED = "diverged"     # a state became non-finite or left the world


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
