"""Action spaces: velocity set-points, waypoints or rotor speeds, normalised or in SI units.

One row per agent. The first columns are the command (3 for velocity and waypoint actions, 4
for rotor speeds); tasks with boxes add a last ``gripper`` column in [-1, 1]: above +0.5 asks
to GRASP, below -0.5 to RELEASE, anything between does nothing.

| action type | normalised (float32, [-1, 1]) | SI units (float64) |
|---|---|---|
| ``velocity`` | v = a * v_max per axis (the scenario's velocity limit, else ``velocity_scale``) | m/s in [-v_max, v_max] |
| ``waypoint`` | p = low + (a + 1) / 2 * (high - low) over the arena [0, Lx] x [0, Ly] x [0, ceiling] | m in that box |
| ``rotor_speed`` | w = w_hover * (1 + rotor_span * a), within [0, w_max] | rad/s in [0, w_max] |

Actions outside the space are clipped to it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.envs.config import ActionType, EnvConfig
from pybullet_swarm.planning.base import Action
from pybullet_swarm.planning.views.construction import ConstructionLayout

GRIP_THRESHOLD = 0.5  # |gripper| above this asks for GRASP (+) or RELEASE (-)
DEFAULT_CEILING = 2.0  # m, top of the waypoint range when the arena has no height


class ActionMapper:
    """Maps action rows (n, dim) onto physical commands for one scenario.

    Args:
        sim: the simulation (scenario limits, arena, vehicle, task).
        config: the environment options.
    """

    def __init__(self, sim: Any, config: EnvConfig) -> None:
        sc = sim.scenario
        self.type = ActionType(config.action_type)
        self.normalized = bool(config.normalize_actions)
        layout = sim.info.layout  # the task has objects to grasp and release: a construction layout with boxes
        self.gripper = isinstance(layout, ConstructionLayout) and len(layout.depot) > 0
        self.span = float(config.rotor_span)
        self.hover_speed = sim.params.hover_rotor_speed(sc.sim.gravity)  # rad/s
        self.max_speed = float(sim.params.max_rotor_speed)  # rad/s
        if self.type is ActionType.VELOCITY:
            v = sc.velocity_limits()
            vmax = np.full(3, config.velocity_scale) if v is None else v
            lo, hi = -vmax, vmax
        elif self.type is ActionType.WAYPOINT:
            lx, ly = (float(x) for x in sc.arena.size)
            ceiling = config.waypoint_ceiling
            if ceiling is None:
                ceiling = float(sc.arena.height) if sc.arena.height is not None else DEFAULT_CEILING
            lo, hi = np.zeros(3), np.array([lx, ly, float(ceiling)])
        else:
            lo, hi = np.zeros(4), np.full(4, self.max_speed)
        self.core = lo.shape[0]
        self.phys_low = np.asarray(lo, dtype=float)  # SI bounds of the command columns
        self.phys_high = np.asarray(hi, dtype=float)
        self.dim = self.core + (1 if self.gripper else 0)
        if self.normalized:
            self.low = -np.ones(self.dim, dtype=np.float32)
            self.high = np.ones(self.dim, dtype=np.float32)
            self.dtype: type = np.float32
        else:
            self.low = np.concatenate([self.phys_low, [-1.0] * (self.dim - self.core)])
            self.high = np.concatenate([self.phys_high, [1.0] * (self.dim - self.core)])
            self.dtype = np.float64
        self._low64 = self.low.astype(np.float64)
        self._high64 = self.high.astype(np.float64)

    def to_physical(self, actions: NDArray[Any]) -> tuple[NDArray[np.float64], NDArray[np.int64] | None]:
        """Commands (n, core) in SI units and task actions (n,) ``Action`` values (None without a gripper)."""
        a = np.minimum(np.maximum(np.asarray(actions, dtype=np.float64), self._low64), self._high64)
        cmd = a[:, : self.core]
        if self.normalized:
            if self.type is ActionType.VELOCITY:
                cmd = cmd * self.phys_high
            elif self.type is ActionType.WAYPOINT:
                cmd = self.phys_low + 0.5 * (cmd + 1.0) * (self.phys_high - self.phys_low)
            else:
                cmd = np.clip(self.hover_speed * (1.0 + self.span * cmd), 0.0, self.max_speed)
        if not self.gripper:
            return cmd, None
        g = a[:, self.core]
        grip = np.where(
            g > GRIP_THRESHOLD, int(Action.GRASP), np.where(g < -GRIP_THRESHOLD, int(Action.RELEASE), int(Action.NONE))
        )
        return cmd, grip.astype(np.int64)

    def hover_action(self, sim: Any) -> NDArray[Any]:
        """The action rows (n, dim) that hold every agent where it is (a neutral action)."""
        n = sim.n
        if self.type is ActionType.VELOCITY:
            cmd = np.zeros((n, 3))
        elif self.type is ActionType.WAYPOINT:
            p = np.clip(sim.state_array[:, :3], self.phys_low, self.phys_high)
            cmd = (2.0 * (p - self.phys_low) / (self.phys_high - self.phys_low) - 1.0) if self.normalized else p
        else:
            cmd = np.zeros((n, 4)) if self.normalized else np.full((n, 4), self.hover_speed)
        out = np.zeros((n, self.dim))
        out[:, : self.core] = cmd
        return np.clip(out, self._low64, self._high64).astype(self.dtype)
