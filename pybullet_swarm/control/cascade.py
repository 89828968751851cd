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

from pybullet_swarm.control.design import ControllerDesign, ReferenceStep, design_controller
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
        design: a precomputed design (default: designed now for these rates and this gravity).
        reference_step: the largest reference step of the run (a scenario's is
            ``ReferenceStep.from_limits(scenario.velocity_limits(), scenario.acceleration_limits())``);
            refused with a ``ConfigError`` when following it would saturate a rotor
            (``ControllerDesign.check_step``). The design itself is made for ``ReferenceStep()``.
        prefilter: follow shaped references as the inner loops can (two-degree-of-freedom): the
            position and velocity references are passed through the design's model of the
            acceleration path (``ControllerDesign.acceleration_path``) while the acceleration
            reference is fed forward unfiltered, so a feasible trajectory is tracked without the
            position loop fighting the attitude loop's lag (without it, a 0.15 m/s velocity step
            of quad150 overshoots by 69 % on x and 10 % on z; with it by the acceleration path's
            own 28 % on x and none on z). Off for raw steps, whose response is the designed
            closed loop.
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
        prefilter: bool = False,
        reference_step: ReferenceStep | None = None,
    ) -> None:
        self.params = params
        self.design = design or design_controller(
            params, physics_hz=physics_hz, position_hz=control_hz, gravity=gravity
        )
        if reference_step is not None:
            self.design.check_step(reference_step)
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
        self.prefilter = _ReferencePrefilter(self.design, self.control_dt) if prefilter else None
        self.reset(n)

    def reset(self, n: int, rotor_speed: float = 0.0) -> None:
        """Clear integrators and motor states for ``n`` agents; rotors start at ``rotor_speed`` rad/s."""
        K = kernels
        self.n = n
        # One per-agent array shared by the compiled kernels; the attributes below are views of it.
        self.ctrl = np.zeros((n, K.CTRL_COLS))
        self.R_des = self.ctrl[:, K.C_RDES : K.C_RDES + 9].reshape(n, 3, 3)  # desired attitude
        self.R_des[:] = np.eye(3)
        self.thrust_acc = self.ctrl[:, K.C_THRUST]  # m/s^2, specific thrust command
        self.yaw_rate = self.ctrl[:, K.C_YAWRATE]  # rad/s, yaw-rate reference
        self.att_integral = self.ctrl[:, K.C_INTEG : K.C_INTEG + 3]  # rad s
        self.rotor_speeds = self.ctrl[:, K.C_W : K.C_W + 4]  # rad/s, motor state
        self.rotor_commands = self.ctrl[:, K.C_WCMD : K.C_WCMD + 4]  # rad/s
        self.body_rates = self.ctrl[:, K.C_RATES : K.C_RATES + 3]  # rad/s
        self.mass = self.ctrl[:, K.C_MASS]  # kg, airframe + known payload
        self.mass[:] = self.params.mass
        self.rotor_speeds[:] = rotor_speed
        self.rotor_commands[:] = rotor_speed
        self.pos_integral = np.zeros((n, 3))  # m s
        self.forces = np.zeros((n, 3))  # N, world frame
        self.torques = np.zeros((n, 3))  # N m, world frame
        self.status = np.zeros(n, dtype=np.int64)
        c = np.zeros(K.CONST_LEN)
        c[K.K_GAINS : K.K_GAINS + 9] = self.att_gains.ravel()
        c[K.K_INTMAX : K.K_INTMAX + 3] = self.ATTITUDE_INTEGRAL_LIMIT
        c[K.K_INERTIA : K.K_INERTIA + 3] = self.inertia
        c[K.K_MIXER : K.K_MIXER + 16] = self.mixer.ravel()
        c[K.K_MIXINV : K.K_MIXINV + 16] = self.mixer_inv.ravel()
        c[K.K_WMAX] = self.params.max_rotor_speed
        c[K.K_ALPHA] = self.motor_alpha
        c[K.K_DT] = self.physics_dt
        c[K.K_DRAG] = self.drag
        c[K.K_GROUND_R] = self.ground_radius
        c[K.K_CLOSED] = 1.0
        self.const = c
        self.pos_scal = np.array([self.control_dt, self.gravity, self.max_tilt_tan, self.max_acc])
        self._pos_key: tuple[int, int] | None = None
        self._pos_args: tuple = ()
        if self.prefilter is not None:
            self.prefilter.reset(n)

    @property
    def wrench(self) -> NDArray[np.float64]:
        """World-frame force N (3) and torque N m (3) per agent, (n, 6) (a copy)."""
        return np.concatenate([self.forces, self.torques], axis=1)

    def set_payload(self, agent: int, mass: float) -> None:
        """Tell the controller that ``agent`` carries ``mass`` kg (thrust feed-forward; 0 when empty)."""
        self.mass[agent] = self.params.mass + float(mass)

    def set_closed_loop(self, closed: bool) -> None:
        """Run the attitude loop (True) or hold ``rotor_commands`` as set from outside (False)."""
        self.const[kernels.K_CLOSED] = 1.0 if closed else 0.0
        if closed and self.prefilter is not None:
            self.prefilter.primed = False  # start again from the references of the next update

    def position_update(self, state: NDArray[np.float64], ref: Reference) -> None:
        """Run the position loop once: state (n, 13) and references -> desired attitude and thrust."""
        key = (id(state), id(ref))
        pf = self.prefilter
        if key != self._pos_key:  # bind the argument tuple once per (state, reference) pair
            self._pos_key = key
            p_ref, v_ref = (ref.positions, ref.velocities) if pf is None else (pf.p, pf.v)
            self._pos_args = (
                state,
                p_ref,
                v_ref,
                ref.accelerations,
                ref.yaw,
                ref.yaw_rate,
                self.pos_gains,
                self.pos_integral,
                self.POSITION_INTEGRAL_LIMIT,
                self.pos_scal,
                self.ctrl,
            )
        if pf is not None:
            pf.update(ref.positions, ref.velocities)
        kernels.position_tick(*self._pos_args)

    def physics_args(self, state: NDArray[np.float64]) -> tuple:
        """Arguments of ``kernels.physics_tick`` for ``state`` (n, 13); the arrays are updated in place,
        so the tuple stays valid for the life of the run (hot loops bind it once)."""
        return (state, self.ctrl, self.forces, self.torques, self.status, self.const)

    def physics_update(self, state: NDArray[np.float64]) -> int:
        """Attitude loop, mixer, motors and wrench for one physics step (fills ``forces``, ``torques``).

        Returns the worst agent status (see ``kernels.STATUS_*``).
        """
        return kernels.physics_tick(state, self.ctrl, self.forces, self.torques, self.status, self.const)

    def __call__(self, state: SwarmState, ref: Reference, dt: float) -> NDArray[np.float64]:
        """Controller protocol: one position and one attitude update; returns rotor commands (n, 4) rad/s.

        The simulation calls ``position_update`` and ``physics_update`` at their own rates; this
        entry point serves scripted use on plain arrays.
        """
        from pybullet_swarm.control.rotations import quat_to_matrix

        omega_world = np.einsum("nij,nj->ni", quat_to_matrix(state.quaternions), state.body_rates)
        packed = np.ascontiguousarray(
            np.concatenate([state.positions, state.quaternions, state.velocities, omega_world], axis=1)
        )
        self.position_update(packed, ref)
        self.physics_update(packed)
        return self.rotor_commands.copy()


class _ReferencePrefilter:
    """The acceleration path of each position loop (the design's sampled-data model at the control
    period), run on the position and velocity references of all agents at once (one compiled call).

    The shaper hands each tick the references for the end of the coming period with the
    acceleration for the period; the position loop acts at its start. So the filter runs on the
    references of the start of the period (those handed over the tick before): then a feasible
    trajectory gives zero error in the linear model and the command is the acceleration reference
    alone (fed the end-of-period references, the loop chased a reference one period ahead: about
    14 times the velocity error from the model, 6 % overshoot on z where the path has none).

    Starts (and restarts after ``primed = False``) in steady state at the references it is given.
    """

    def __init__(self, design: ControllerDesign, dt: float) -> None:
        import control

        systems = [control.ss(design.acceleration_path(loop)) for loop in ("x", "y", "z")]
        for sys in systems:
            if not math.isclose(float(sys.dt), dt, rel_tol=1e-9):
                raise ValueError(f"prefilter: the design's position period {sys.dt} s is not the control period {dt} s")
        m = max(sys.nstates for sys in systems)  # axes with fewer states are padded with zeros
        self.At, self.B = np.zeros((3, m, m)), np.zeros((3, m))
        self.C, self.D, self.x_unit = np.zeros((3, m)), np.zeros(3), np.zeros((3, m))
        for k, sys in enumerate(systems):
            A, B = np.asarray(sys.A, dtype=float), np.asarray(sys.B, dtype=float)[:, 0]
            r = A.shape[0]
            self.At[k, :r, :r] = A.T
            self.B[k, :r] = B
            self.C[k, :r] = np.asarray(sys.C, dtype=float)[0]
            self.D[k] = float(np.asarray(sys.D)[0, 0])
            self.x_unit[k, :r] = np.linalg.solve(np.eye(r) - A, B)  # steady state for a unit input
        self.primed = False

    def reset(self, n: int) -> None:
        """Size for ``n`` agents; the next update primes the filter."""
        self.n = n
        self.p = np.zeros((n, 3))  # m, filtered position references
        self.v = np.zeros((n, 3))  # m/s, filtered velocity references
        self.x = np.zeros((2, n, 3, self.B.shape[1]))  # filter states: positions, velocities
        self.p_start = np.zeros((n, 3))  # m, position references at the start of the period
        self.v_start = np.zeros((n, 3))  # m/s, velocity references at the start of the period
        self.primed = False

    def update(self, p_ref: NDArray[np.float64], v_ref: NDArray[np.float64]) -> None:
        """Take this tick's end-of-period references (n, 3) m and m/s; filter those of the start of
        the period into ``p`` and ``v``."""
        if not self.primed:
            self.p_start[:] = p_ref
            self.v_start[:] = v_ref
        kernels.prefilter_references(
            self.p_start,
            self.v_start,
            self.At,
            self.B,
            self.C,
            self.D,
            self.x_unit,
            self.x,
            self.primed,
            self.p,
            self.v,
        )
        self.p_start[:] = p_ref
        self.v_start[:] = v_ref
        self.primed = True
