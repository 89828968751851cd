"""The simulation loop: one clock for physics, control, planner and recording ticks.

The loop can be stepped from outside (``reset``, ``step``, ``state``), which is what learning
environments wrap, or run to the end with ``run``.
"""
from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.control.cascade import CascadeController
from pybullet_swarm.control.kernels import STATUS_FLIPPED, STATUS_NONFINITE, physics_tick
from pybullet_swarm.control.reference import ReferenceShaper
from pybullet_swarm.control.rotations import quat_to_matrix
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.recorder import Recorder, TimeSeries
from pybullet_swarm.experiment.scenario import Scenario, WaypointsTask
from pybullet_swarm.metrics.flight import flight_metrics
from pybullet_swarm.metrics.collisions import COLLISION_CLASSES, CollisionClass, ContactTracker
from pybullet_swarm.tasks.waypoints import WaypointsRuntime
from pybullet_swarm.types import Event, ExitStatus, SwarmState
from pybullet_swarm.vehicle import VehicleParams, load_vehicle
from pybullet_swarm.world import BodyKind, World


@dataclasses.dataclass(frozen=True)
class RunResult:
    """Outcome of a run.

    Attributes:
        exit_status: how it ended.
        metrics: the metrics written to ``metrics.json`` (plain JSON data).
        events: contact onsets, crashes and task events, in time order.
        timeseries: recorded samples.
        scenario: the resolved scenario.
        run_dir: directory the run was written to, if any.
    """

    exit_status: ExitStatus
    metrics: dict[str, Any]
    events: list[Event]
    timeseries: TimeSeries
    scenario: Scenario
    run_dir: Any = None


class Simulation:
    """One run of a scenario: World, controller, reference shaper, task, recorder and clock.

    Args:
        scenario: a validated scenario.
        seed: seed of the run's random generator (default: the scenario's).
        planner: planner name (None: the task's own set-points).
        avoidance: avoidance layer name ('none').
        gui: watch in the Bullet GUI.
        record: keep time series.
    """

    def __init__(self, scenario: Scenario, *, seed: int | None = None, planner: str | None = None,
                 avoidance: str | None = None, gui: bool = False, record: bool = True) -> None:
        self.scenario = scenario
        self.seed = scenario.seed if seed is None else int(seed)
        self.rng = np.random.default_rng(self.seed)
        planner = planner if planner is not None else scenario.planner.name
        avoidance = avoidance if avoidance is not None else scenario.avoidance
        if planner not in (None, "waypoints"):
            raise ConfigError(f"planner {planner!r} is not available yet; available: waypoints",
                              source=scenario.source, field="planner.name")
        if avoidance not in ("none",):
            raise ConfigError(f"avoidance {avoidance!r} is not available yet; available: none",
                              source=scenario.source, field="avoidance")
        self.planner_name = planner or "waypoints"
        self.avoidance_name = avoidance
        s = scenario.sim
        self.physics_hz = s.physics_hz
        self.dt = 1.0 / s.physics_hz
        self.control_every = s.physics_hz // s.control_hz
        self.planner_every = s.physics_hz // s.planner_hz
        self.record_every = s.physics_hz // s.record_hz
        self.params: VehicleParams = load_vehicle(scenario.agents.vehicle)
        self.n = scenario.agents.count
        self.gui = gui
        self.record_enabled = record
        self._build()

    # ------------------------------------------------------------------ set-up
    def _build(self) -> None:
        sc, s, p, n = self.scenario, self.scenario.sim, self.params, self.n
        self.world = World(physics_hz=s.physics_hz, gravity=s.gravity, gui=self.gui)
        self.world.add_ground()
        if sc.arena.walls:
            self.world.add_walls(sc.arena.size, sc.arena.wall_height)
        self.rest_height = 0.5 * p.collision_size[2] + 1e-3
        self.starts = sc.start_positions(self.rest_height)
        self.world.add_agents(p.urdf_path, self.starts, mass=p.mass, inertia=p.inertia)
        if sc.collisions == "ghost":
            self.world.set_agent_collisions(False)
        self.agent_index = {b: i for i, b in enumerate(self.world.agent_bodies)}
        self.controller = CascadeController(p, n, physics_hz=s.physics_hz, control_hz=s.control_hz, gravity=s.gravity,
                                            max_tilt_deg=s.max_tilt_deg, drag=s.drag_coefficient,
                                            ground_effect=s.ground_effect)
        self.shaper = ReferenceShaper(n, sc.velocity_limits(), sc.acceleration_limits(), 1.0 / s.control_hz)
        self.state_array = np.zeros((n, 13))   # position, quaternion, velocity, angular velocity (world)
        self.world.read_agent_states(self.state_array)
        self.shaper.reset(self.state_array[:, :3])
        self.time_limit = float(sc.task.time_limit_s)
        cap = int(math.ceil(self.time_limit * s.record_hz)) + 2
        self.recorder = Recorder(n, cap) if self.record_enabled else None
        self.task = WaypointsRuntime(sc.task, self.starts) if isinstance(sc.task, WaypointsTask) else None
        self.max_height = self.starts[:, 2].copy()   # m, highest recorded altitude per agent
        self.contacts = ContactTracker(self._classify, self.dt, debounce_s=0.1)
        self.events: list[Event] = []
        self.step_count = 0
        self.exit_status = ExitStatus.RUNNING
        self.crashed_agent: int | None = None
        self.open_loop = False
        self._external = False
        self._wall_time = 0.0

    def _classify(self, a: int, b: int) -> CollisionClass | None:
        ka, kb = self.world.body_kind(a), self.world.body_kind(b)
        if ka is not BodyKind.AGENT:
            a, b, ka, kb = b, a, kb, ka
        if ka is not BodyKind.AGENT:
            return None
        if kb is BodyKind.AGENT:
            return CollisionClass.AGENT_AGENT
        if kb is BodyKind.GROUND:
            i = self.agent_index[a]
            airborne = max(self.max_height[i], self.state_array[i, 2]) > self.rest_height + 0.05
            return CollisionClass.AGENT_GROUND if airborne else None
        if kb is BodyKind.BOX:
            return CollisionClass.AGENT_BOX
        return CollisionClass.AGENT_OBSTACLE

    # ----------------------------------------------------------------- access
    @property
    def time(self) -> float:
        """Simulated time, s."""
        return self.step_count * self.dt

    @property
    def state(self) -> SwarmState:
        """True state of the swarm now (copies)."""
        a = self.state_array
        return SwarmState(a[:, :3].copy(), a[:, 3:7].copy(), a[:, 7:10].copy(), self.controller.body_rates.copy())

    def set_open_loop(self, rotor_speeds: NDArray[np.float64] | None, *, motor_state: bool = False) -> None:
        """Bypass the controller and command rotor speeds (n, 4) rad/s directly (None: closed loop again).

        With ``motor_state`` the motors also start at these speeds (no lag transient).
        """
        if rotor_speeds is None:
            self.open_loop = False
            self.controller.set_closed_loop(True)
            return
        self.open_loop = True
        self.controller.set_closed_loop(False)
        self.controller.rotor_commands[:] = rotor_speeds
        if motor_state:
            self.controller.rotor_speeds[:] = rotor_speeds

    def set_targets(self, positions: NDArray[np.float64] | None, yaw: NDArray[np.float64] | None = None,
                    *, velocities: bool = False) -> None:
        """Command the agents from outside: positions (n, 3) m (or velocities m/s with ``velocities``).

        From then on the task's own set-points are ignored (the task still judges completion);
        ``None`` hands control back to the task.
        """
        if positions is None:
            self._external = False
            return
        self._external = True
        arr = np.asarray(positions, dtype=float).reshape(self.n, 3)
        if velocities:
            self.shaper.set_velocity_targets(arr)
        else:
            self.shaper.set_position_targets(arr)
        if yaw is not None:
            self.shaper.yaw[:] = yaw

    # ------------------------------------------------------------------- loop
    def _planner_tick(self) -> None:
        t = self.time
        if self.task is not None and not self._external:
            targets, yaws = self.task.targets(t)
            self.shaper.set_position_targets(targets)
            self.shaper.yaw[:] = yaws
        if self.task is not None:
            if self.task.update(t, self.state_array[:, :3]):
                self._finish(ExitStatus.COMPLETED)
                return
        if t >= self.time_limit - 1e-9:
            self._finish(ExitStatus.TIMEOUT)

    def _finish(self, status: ExitStatus, agent: int | None = None, detail: str = "") -> None:
        if self.exit_status is ExitStatus.RUNNING:
            self.exit_status = status
            if agent is not None:
                self.crashed_agent = agent
            if status in (ExitStatus.CRASHED, ExitStatus.DIVERGED):
                self.events.append(Event(self.time, status.value, f"agent{agent}" if agent is not None else "", "", detail))

    def _on_contacts(self, pairs: set[tuple[int, int]]) -> None:
        t = self.time
        for cls, a, b in self.contacts.update(pairs, t):
            wa, wb = self.world.body_name(a), self.world.body_name(b)
            self.events.append(Event(t, cls.value, wa, wb))
            if cls is CollisionClass.AGENT_GROUND:
                body = a if self.world.body_kind(a) is BodyKind.AGENT else b
                i = self.agent_index[body]
                vz = self.state_array[i, 9]
                if -vz > self.scenario.sim.crash_speed:
                    self._finish(ExitStatus.CRASHED, i, f"hit the ground at {-vz:.2f} m/s")

    def _on_status(self, worst: int) -> None:
        status = self.controller.status
        if worst == STATUS_NONFINITE:
            i = int(np.argmax(status == STATUS_NONFINITE))
            self._finish(ExitStatus.DIVERGED, i, "non-finite or runaway state")
        elif worst == STATUS_FLIPPED:
            i = int(np.argmax(status == STATUS_FLIPPED))
            self._finish(ExitStatus.CRASHED, i, "flipped over")

    def step(self, n_physics: int | None = None) -> ExitStatus:
        """Advance by ``n_physics`` physics steps (default: one control period); returns the status."""
        steps = self.control_every if n_physics is None else int(n_physics)
        t0 = time.perf_counter()
        world, ctrl, shaper, contacts = self.world, self.controller, self.shaper, self.contacts
        state = self.state_array
        tick = physics_tick
        args = ctrl.physics_args(state)
        forces, torques = ctrl.forces, ctrl.torques
        apply, advance, read, contact_pairs = (world.apply_agent_wrenches, world.step, world.read_agent_states,
                                               world.contact_pairs)
        ce, pe, re = self.control_every, self.planner_every, self.record_every
        running = ExitStatus.RUNNING
        closed = not self.open_loop
        k = self.step_count
        end = k + steps
        while k < end and self.exit_status is running:
            if k % pe == 0:
                self._planner_tick()
                if self.exit_status is not running:
                    break
            if closed and k % ce == 0:
                ctrl.position_update(state, shaper.step())
            worst = tick(*args)
            apply(forces, torques)
            advance()
            k += 1
            self.step_count = k
            read(state)
            pairs = contact_pairs()
            if pairs or contacts._prev:
                self._on_contacts(pairs)
            if worst:
                self._on_status(worst)
            if k % re == 0:
                self._sample()
        self._wall_time += time.perf_counter() - t0
        return self.exit_status

    def _sample(self) -> None:
        """Work done at the recording rate: the recorder and the altitude high-water mark."""
        np.maximum(self.max_height, self.state_array[:, 2], out=self.max_height)
        if self.recorder is not None:
            s = self.state_array
            self.recorder.record(self.time, s[:, :7], s[:, 7:], self.controller.rotor_speeds, self.shaper.p,
                                 self.shaper.v)

    def run(self) -> RunResult:
        """Run until the task completes, the time limit passes, or an agent crashes."""
        chunk = self.planner_every
        while self.exit_status is ExitStatus.RUNNING:
            self.step(chunk)
        return self.result()

    # ---------------------------------------------------------------- results
    def metrics(self) -> dict[str, Any]:
        """Metrics of the run so far (plain JSON data)."""
        ts = self.recorder.series() if self.recorder is not None else None
        sim_t = self.time
        m: dict[str, Any] = {
            "exit_status": self.exit_status.value,
            "sim_time_s": round(sim_t, 9),
            "wall_time_s": self._wall_time,
            "real_time_factor": sim_t / self._wall_time if self._wall_time > 0 else None,
            "seed": self.seed,
            "scenario": self.scenario.name,
            "planner": self.planner_name,
            "avoidance": self.avoidance_name,
            "agents": self.n,
            "vehicle": self.params.name,
            "crashed_agent": self.crashed_agent,
            "completion_time_s": self.task.completed_at if self.task is not None else None,
            "collisions": {c: self.contacts.counts[c] for c in COLLISION_CLASSES},
            "collision_time_s": {c: round(self.contacts.time_s[c], 9) for c in COLLISION_CLASSES},
        }
        if ts is not None and ts.t.size:
            m.update(flight_metrics(ts, self.params.km))
        return m

    def result(self) -> RunResult:
        """The run's result now."""
        empty = Recorder(self.n, 1).series()
        ts = self.recorder.series() if self.recorder is not None else empty
        return RunResult(self.exit_status, self.metrics(), list(self.events), ts, self.scenario)

    def close(self) -> None:
        """Release the Bullet client."""
        self.world.close()

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
