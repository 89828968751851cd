"""The runtime cascade, one object for the whole swarm.

position loop (control rate) -> desired acceleration -> collective thrust and desired attitude
-> attitude loop (physics rate) -> body torques -> mixer -> rotor speeds -> motor lag -> wrench.
Gains come from ``pybullet_swarm.control.design`` (never typed in by hand); they are in
acceleration units, multiplied here by the vehicle's mass and inertia.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.control.design import ControllerDesign, design_controller
from pybullet_swarm.control import kernels
from pybullet_swarm.control.reference import Reference
from pybullet_swarm.types import SwarmState
from pybullet_swarm.vehicle.dynamics import motor_alpha
from pybullet_swarm.vehicle.params import VehicleParams


class CascadeController:
    """Cascaded PID controller with anti-windup, vectorised over ``n`` agents.

    Args:
        params: the airframe.
        n: number of agents.
        physics_hz: attitude-loop (and physics) rate, Hz.
        control_hz: position-loop rate, Hz; must divide ``physics_hz``.
        gravity: m/s^2.
        max_tilt_deg: largest commanded tilt, deg.
        thrust_margin: fraction of the maximum thrust the position loop may command.
        drag: linear drag coefficient of the airframe model, N/(m/s) (0: none).
        ground_effect: model the thrust gain near the ground.
        design: a precomputed design (default: designed now for these rates).
    """

    #: bound on |ki * integral| of the position loop, m/s^2 (x, y, z): room for a 20 % payload.
    POSITION_INTEGRAL_LIMIT = np.array([2.0, 2.0, 4.0])
    #: bound on |ki * integral| of the attitude loop, rad/s^2 (roll, pitch, yaw).
    ATTITUDE_INTEGRAL_LIMIT = np.array([20.0, 20.0, 5.0])

    def __init__(
        self,
        params: VehicleParams,
        n: int,
        *,
        physics_hz: float = 240.0,
        control_hz: float = 48.0,
        gravity: float = 9.81,
        max_tilt_deg: float = 35.0,
        thrust_margin: float = 0.9,
        drag: float = 0.0,
        ground_effect: bool = False,
        design: ControllerDesign | None = None,
    ) -> None:
        self.params = params
        self.design = design or design_controller(params, physics_hz=physics_hz, position_hz=control_hz)
        self.physics_dt = 1.0 / physics_hz
        self.control_dt = 1.0 / control_hz
        self.gravity = float(gravity)
        self.max_tilt_tan = math.tan(math.radians(max_tilt_deg))
        self.max_acc = thrust_margin * 4.0 * params.kf * params.max_rotor_speed**2 / params.mass
        self.drag = float(drag)
        self.ground_radius = 0.6 * params.arm_length if ground_effect else 0.0
        self.att_gains = np.ascontiguousarray(self.design.attitude_gains, dtype=float)
        self.pos_gains = np.ascontiguousarray(self.design.position_gains, dtype=float)
        self.inertia = np.asarray(params.inertia, dtype=float)
        self.mixer = np.ascontiguousarray(params.mixer)
        self.mixer_inv = np.ascontiguousarray(params.mixer_inverse)
        self.motor_alpha = motor_alpha(self.physics_dt, params.motor_time_constant)
        self.reset(n)

    def reset(self, n: int, rotor_speed: float = 0.0) -> None:
        """Clear integrators and motor states for ``n`` agents; rotors start at ``rotor_speed`` rad/s."""
        self.n = n
        self.pos_integral = np.zeros((n, 3))    # m s
        self.att_integral = np.zeros((n, 3))    # rad s
        self.R_des = np.tile(np.eye(3), (n, 1, 1))
        self.thrust_acc = np.zeros(n)           # m/s^2, specific thrust command
        self.yaw_rate = np.zeros(n)             # rad/s, yaw-rate reference
        self.rotor_speeds = np.full((n, 4), float(rotor_speed))   # rad/s, motor state
        self.rotor_commands = np.full((n, 4), float(rotor_speed))  # rad/s
        self.wrench = np.zeros((n, 6))          # world force N (3) and torque N m (3)
        self.body_rates = np.zeros((n, 3))      # rad/s
        self.status = np.zeros(n, dtype=np.int64)
        self.scal = np.array([self.params.mass, self.params.max_rotor_speed, self.motor_alpha, self.physics_dt,
                              self.drag, self.ground_radius, 1.0])
        self.pos_scal = np.array([self.control_dt, self.gravity, self.max_tilt_tan, self.max_acc])

    @property
    def forces(self) -> NDArray[np.float64]:
        """World-frame forces (n, 3) N of the last physics update."""
        return self.wrench[:, :3]

    @property
    def torques(self) -> NDArray[np.float64]:
        """World-frame torques (n, 3) N m of the last physics update."""
        return self.wrench[:, 3:]

    def set_closed_loop(self, closed: bool) -> None:
        """Run the attitude loop (True) or hold ``rotor_commands`` as set from outside (False)."""
        self.scal[kernels.P_CLOSED_LOOP] = 1.0 if closed else 0.0

    def position_update(self, state: NDArray[np.float64], ref: Reference) -> None:
        """Run the position loop once: state (n, 13) and references -> desired attitude and thrust."""
        kernels.position_tick(state, ref.positions, ref.velocities, ref.accelerations, ref.yaw, self.pos_gains,
                              self.pos_integral, self.POSITION_INTEGRAL_LIMIT, self.pos_scal, self.R_des,
                              self.thrust_acc)
        self.yaw_rate[:] = ref.yaw_rate

    def physics_args(self, state: NDArray[np.float64]) -> tuple:
        """Arguments of ``kernels.physics_tick`` for ``state`` (n, 13); the arrays are updated in place,
        so the tuple stays valid for the life of the run (callers in hot loops bind it once)."""
        return (state, self.R_des, self.thrust_acc, self.yaw_rate, self.att_integral, self.rotor_speeds,
                self.rotor_commands, self.wrench, self.body_rates, self.status, self.att_gains,
                self.ATTITUDE_INTEGRAL_LIMIT, self.inertia, self.mixer, self.mixer_inv, self.scal)

    def physics_update(self, state: NDArray[np.float64]) -> int:
        """Attitude loop, mixer, motors and wrench for one physics step (fills ``wrench``).

        Returns the worst agent status (see ``kernels.STATUS_*``).
        """
        return kernels.physics_tick(*self.physics_args(state))

    def __call__(self, state: SwarmState, ref: Reference, dt: float) -> NDArray[np.float64]:
        """Controller protocol: one position and one attitude update; returns rotor commands (n, 4) rad/s.

        The simulation calls ``position_update`` and ``physics_update`` at their own rates; this
        entry point serves scripted use on plain arrays.
        """
        from pybullet_swarm.control.rotations import quat_to_matrix

        omega_world = np.einsum("nij,nj->ni", quat_to_matrix(state.quaternions), state.body_rates)
        packed = np.ascontiguousarray(np.concatenate(
            [state.positions, state.quaternions, state.velocities, omega_world], axis=1))
        self.position_update(packed, ref)
        self.physics_update(packed)
        return self.rotor_commands.copy()
