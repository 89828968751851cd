"""The simulation loop: one clock for physics, control, planner and recording ticks.

The loop can be stepped from outside (``reset``, ``step``, ``state``), which is what learning
environments wrap, or run to the end with ``run``.
"""
from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.control.cascade import CascadeController
from pybullet_swarm.control.kernels import STATUS_FLIPPED, STATUS_NONFINITE, physics_tick
from pybullet_swarm.control.reference import ReferenceShaper
from pybullet_swarm.control.rotations import quat_to_euler
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.recorder import Recorder, TimeSeries
from pybullet_swarm.experiment.scenario import Scenario, WaypointsTask
from pybullet_swarm.metrics.flight import flight_metrics
from pybullet_swarm.metrics.collisions import COLLISION_CLASSES, CollisionClass, ContactTracker
from pybullet_swarm.planning.base import Action, Command, CommandKind, Observation, TaskInfo, WorldView
from pybullet_swarm.tasks.construction import PLACED, ConstructionRuntime, ConstructionTask
from pybullet_swarm.tasks.waypoints import WaypointsRuntime
from pybullet_swarm.types import Event, ExitStatus, SwarmState
from pybullet_swarm.vehicle import VehicleParams, load_vehicle
from pybullet_swarm.world import BodyKind, World


@dataclasses.dataclass(frozen=True)
class RunResult:
    """Outcome of a run.

    Attributes:
        exit_status: how it ended.
        artifacts: objects that write extra files into a run directory (e.g. a pheromone medium).
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
    artifacts: dict[str, Any] = dataclasses.field(default_factory=dict)


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
                 avoidance: str | None = None, gui: bool = False, record: bool = True,
                 video: Path | None = None, video_quiet: bool = False) -> None:
        self.scenario = scenario
        self.seed = scenario.seed if seed is None else int(seed)
        self.rng = np.random.default_rng(self.seed)
        from pybullet_swarm.planning.registry import avoidance_layers, default_planner, planners

        PLANNERS = planners()
        kind = scenario.task.kind
        planner = planner if planner is not None else scenario.planner.name
        planner = planner or default_planner(kind)
        if planner not in PLANNERS:
            raise ConfigError(f"unknown planner {planner!r}; available: {', '.join(PLANNERS)}",
                              source=scenario.source, field="planner.name")
        if kind not in PLANNERS[planner][2]:
            raise ConfigError(f"planner {planner!r} does not solve {kind!r} tasks (it solves "
                              f"{', '.join(PLANNERS[planner][2])})", source=scenario.source, field="planner.name")
        avoidance = avoidance if avoidance is not None else scenario.avoidance
        if avoidance not in avoidance_layers():
            raise ConfigError(f"unknown avoidance {avoidance!r}; available: {', '.join(avoidance_layers())}",
                              source=scenario.source, field="avoidance")
        self.planner_name = planner
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
        self.video = None
        if video is not None:
            self._open_video(Path(video), video_quiet)

    # ------------------------------------------------------------------ set-up
    def _build(self) -> None:
        sc, s, p, n = self.scenario, self.scenario.sim, self.params, self.n
        self.world = World(physics_hz=s.physics_hz, gravity=s.gravity, gui=self.gui)
        self.world.add_ground()
        if sc.arena.walls:
            self.world.add_walls(sc.arena.size, sc.arena.wall_height)
        for k, ob in enumerate(sc.arena.obstacles):   # static pillars and boxes: contacts are agent_obstacle
            if ob.shape == "cylinder":
                self.world.add_cylinder(ob.center(), ob.size[0], ob.size[1], name=f"obstacle{k}")
            else:
                self.world.add_box(ob.center(), ob.size, yaw=math.radians(ob.yaw_deg), name=f"obstacle{k}")
        self.rest_height = 0.5 * p.collision_size[2] + 1e-3
        self.starts = sc.start_positions(self.rest_height)
        jitter = sc.agents.start_jitter
        if jitter > 0.0:   # hand placement is never exact; the seed decides how
            self.starts[:, :2] += self.rng.uniform(-jitter, jitter, size=(n, 2))
        self.world.add_agents(p.urdf_path, self.starts, mass=p.mass, inertia=p.inertia)
        if sc.collisions == "ghost":
            self.world.set_agent_collisions(False)
        self.agent_index = {b: i for i, b in enumerate(self.world.agent_bodies)}
        self.controller = CascadeController(p, n, physics_hz=s.physics_hz, control_hz=s.control_hz, gravity=s.gravity,
                                            max_tilt_deg=s.max_tilt_deg, drag=s.drag_coefficient,
                                            ground_effect=s.ground_effect,
                                            prefilter=sc.velocity_limits() is not None)
        self.shaper = ReferenceShaper(n, sc.velocity_limits(), sc.acceleration_limits(), 1.0 / s.control_hz)
        self.state_array = np.zeros((n, 13))   # position, quaternion, velocity, angular velocity (world)
        self.world.read_agent_states(self.state_array)
        self.shaper.reset(self.state_array[:, :3])
        self.time_limit = float(sc.task.time_limit_s)
        cap = int(math.ceil(self.time_limit * s.record_hz)) + 2
        self.recorder = Recorder(n, cap) if self.record_enabled else None
        self.ghost = sc.collisions == "ghost"
        self.diameter = float(max(p.collision_size[0], p.collision_size[1]))   # m, agent "diameter"
        self.task: Any = None
        self.construction: ConstructionRuntime | None = None
        if isinstance(sc.task, WaypointsTask):
            self.task = WaypointsRuntime(sc.task, self.starts)
        elif isinstance(sc.task, ConstructionTask):
            self.construction = ConstructionRuntime(sc.task, self.world, agent_half_height=0.5 * p.collision_size[2],
                                                    agent_radius=p.radius, ghost=sc.collisions == "ghost")
            self.task = self.construction
        else:
            from pybullet_swarm.tasks import TASK_RUNTIMES

            self.task = TASK_RUNTIMES[sc.task.kind](sc.task, self)
        self.max_height = self.starts[:, 2].copy()   # m, highest recorded altitude per agent
        self.contacts = ContactTracker(self._classify, self.dt, debounce_s=0.1)
        self.events: list[Event] = []
        self.step_count = 0
        self.exit_status = ExitStatus.RUNNING
        self.crashed_agent: int | None = None
        self.open_loop = False
        self._external = False
        self._wall_time = 0.0
        self.range_sensor: Any = None
        self.ranges = np.zeros((n, 0))   # (n, r) m, range readings of the last planner tick
        if sc.sensing.range.enabled:
            self.enable_range_sensors()
        self.info = self._task_info()
        self._make_planner()
        self.estimation: Any = None   # OnboardEstimation when sensing.state is estimated (or run_estimator)
        self.flying_on_estimate = False
        if sc.sensing.estimating:
            self._make_estimation()

    def enable_range_sensors(self) -> None:
        """Give every agent the fan of range rays of ``sensing.range`` (idempotent; avoidance layers
        that need readings call it); they are cast once per planner tick from then on."""
        if self.range_sensor is not None:
            return
        from pybullet_swarm.sensing.range import RangeFan, RangeSensor, fan_angles

        cfg = self.scenario.sensing.range
        fan = RangeFan(fan_angles(cfg.rays, cfg.fov_deg), float(cfg.range_m), float(self.params.radius) + 1e-3)
        self.range_sensor = RangeSensor(fan, cfg.noise_std_m, self.rng.spawn(1)[0])
        self.ranges = np.full((self.n, fan.rays), fan.range_m)

    def _cast_ranges(self) -> None:
        """Cast every agent's fan from its true pose (one batched call)."""
        s = self.state_array
        self.ranges = self.range_sensor.read(self.world, s[:, :3], quat_to_euler(s[:, 3:7])[:, 2])

    def _make_estimation(self) -> None:
        """IMU, positioning and the estimator, calibrated at rest; their generator is spawned after the
        planners' so that runs without estimation draw exactly as before."""
        from pybullet_swarm.metrics.estimation import EstimationErrors
        from pybullet_swarm.sensing.estimator import EstimatorParams, OnboardEstimation
        from pybullet_swarm.sensing.imu import ImuNoise
        from pybullet_swarm.sensing.positioning import PositioningParams

        cfg, s = self.scenario.sensing, self.scenario.sim
        self.estimation = OnboardEstimation(
            self.n, ImuNoise(**cfg.imu.model_dump()), PositioningParams(**cfg.positioning.model_dump()),
            EstimatorParams(**cfg.estimator.model_dump()), control_hz=s.control_hz, gravity=s.gravity,
            rng=self.rng.spawn(1)[0])
        self.estimation.start(self.state_array, self.time)
        self.estimation_errors = EstimationErrors()
        self.fix_every = s.physics_hz // cfg.positioning.rate_hz
        self.flying_on_estimate = cfg.state.value == "estimated"

    @property
    def sensed_state_array(self) -> NDArray[np.float64]:
        """(n, 13) what the agents know of themselves: the estimate when flying on it, else the true state."""
        return self.estimation.state_array if self.flying_on_estimate else self.state_array

    def _sense(self, k: int) -> None:
        """Sensors and estimator at physics step ``k``: a positioning fix when due, IMU and filters at control ticks."""
        est, s, t = self.estimation, self.state_array, self.time
        if k % self.fix_every == 0:
            est.score_fix(self.estimation_errors, est.take_fix(t, s), s)
        if k % self.control_every == 0:
            est.control_tick(t, s)
            est.score_tick(self.estimation_errors, s)

    def _task_info(self) -> TaskInfo:
        sc, p = self.scenario, self.params
        v = sc.velocity_limits()
        extra: dict[str, Any] = {}
        kw: dict[str, Any] = {}
        if isinstance(self.task, WaypointsRuntime):
            extra["schedule"] = self.task.targets
        if self.construction is not None:
            c = self.construction
            kw = dict(depot=c.start.copy(), slots=c.slots.copy(), box_size=c.size, grasp_height=c.grasp_height)
            extra.update(search_height=c.spec.search_height, attach_threshold=c.spec.attach_threshold,
                         view_radius=c.view_radius, view_norm=c.spec.view_norm)
            if sc.sensing.state.value == "estimated":   # what an agent can expect of its own position estimate
                from pybullet_swarm.sensing.estimator import EstimatorParams, expected_position_std
                from pybullet_swarm.sensing.positioning import PositioningParams

                extra["position_std"] = expected_position_std(
                    PositioningParams(**sc.sensing.positioning.model_dump()),
                    EstimatorParams(**sc.sensing.estimator.model_dump()), control_hz=sc.sim.control_hz)
        elif self.task is not None and hasattr(self.task, "task_info"):
            kw = dict(self.task.task_info())
            extra.update(kw.pop("extra", {}))
        return TaskInfo(arena_size=np.asarray(sc.arena.size, dtype=float), n_agents=self.n, agent_radius=p.radius,
                        v_max=np.full(3, np.inf) if v is None else v, a_max=sc.acceleration_limits(), extra=extra,
                        **kw)

    def _make_planner(self) -> None:
        from pybullet_swarm.planning.registry import avoidance_layers, planners

        factory = planners()[self.planner_name][0]
        # A planner may bring a shared medium (e.g. a pheromone grid): ``make_medium(sim) -> medium``.
        make_medium = getattr(factory, "make_medium", None)
        self.medium = make_medium(self) if callable(make_medium) else None
        av_factory = avoidance_layers()[self.avoidance_name][0]
        av_params = dict(self.scenario.data.get("avoidance_params", {}) or {})
        try:
            self.avoidance_layer = av_factory(self, **av_params) if av_factory is not None else None
        except ConfigError as exc:
            raise (exc.with_source(self.scenario.source) if exc.source is None else exc) from None
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"bad parameters for avoidance {self.avoidance_name!r}: {exc}",
                              source=self.scenario.source, field="avoidance_params") from None
        params = dict(self.scenario.planner.params) if self.scenario.planner.name in (None, self.planner_name) else {}
        try:
            if getattr(factory, "centralized", False):
                self.planner = factory(**params)
                self.planner.reset(self.n, self.rng, self.info)
                self.agent_planners = None
            else:
                self.planner = None
                self.agent_planners = [factory(**params) for _ in range(self.n)]
                child = self.rng.spawn(self.n)
                for i, pl in enumerate(self.agent_planners):
                    pl.reset(i, child[i], self.info)
        except ConfigError as exc:
            raise (exc.with_source(self.scenario.source) if exc.source is None else exc) from None
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"bad parameters for planner {self.planner_name!r}: {exc}",
                              source=self.scenario.source, field="planner.params") from None

    #: simulated frames per second of a video, and the playback rate (4x faster than real time)
    VIDEO_SIM_HZ = 5
    VIDEO_FPS = 20

    def _open_video(self, path: Path, quiet: bool) -> None:
        from pybullet_swarm.experiment.video import VideoWriter, camera_for_arena

        if self.physics_hz % self.VIDEO_SIM_HZ:
            raise ConfigError(f"must be a multiple of {self.VIDEO_SIM_HZ} Hz for video, got {self.physics_hz}",
                              source=self.scenario.source, field="sim.physics_hz")
        self.video_every = self.physics_hz // self.VIDEO_SIM_HZ
        height = max(1.0, float(np.max(self.starts[:, 2])) + 0.5)
        if self.construction is not None:
            height = max(0.6, self.construction.spec.search_height + 0.2)
        self.camera = camera_for_arena(self.scenario.arena.size, height)
        total = int(self.time_limit * self.VIDEO_SIM_HZ) + 1
        self.video = VideoWriter(path, fps=self.VIDEO_FPS, size=(480, 270), progress_total=total, quiet=quiet)
        self._frame()

    def _frame(self) -> None:
        from pybullet_swarm.experiment.video import render_frame

        assert self.video is not None
        self.video.add(render_frame(self.world, self.camera, self.video.size))

    def close_video(self) -> Path | None:
        """Finish the video (if any); returns its file."""
        if self.video is None:
            return None
        v, self.video = self.video, None
        return v.close()

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
            c = self.construction
            if c is None:
                return CollisionClass.AGENT_BOX
            box = c.body_to_box[b]
            if c.carried_by[box] == self.agent_index[a]:
                return None
            return CollisionClass.AGENT_STRUCTURE if c.state[box] == PLACED else CollisionClass.AGENT_BOX
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
        done = False
        if self.construction is not None:
            done = self.construction.update(t)
        elif isinstance(self.task, WaypointsRuntime):
            done = self.task.update(t, self.state_array[:, :3])
        elif self.task is not None:
            done = self.task.update(t, self)
        if done:
            self._finish(ExitStatus.COMPLETED)
            return
        if self.range_sensor is not None:
            self._cast_ranges()
        if not self._external:
            if self.planner is not None:
                commands = self.planner.plan_all(self.world_view())
            else:
                assert self.agent_planners is not None
                obs = self.observations()
                commands = [pl.plan(o, self.medium) for pl, o in zip(self.agent_planners, obs)]
            if self.avoidance_layer is not None:
                commands = self.avoidance_layer.filter(commands, self)
            self._apply(commands)
        if self.medium is not None:
            self.medium.step(1.0 / self.scenario.sim.planner_hz)
        if t >= self.time_limit - 1e-9:
            self._finish(ExitStatus.TIMEOUT)

    def _apply(self, commands: list[Command]) -> None:
        """Turn commands into shaper targets and task actions."""
        sh = self.shaper
        t = self.time
        for i, cmd in enumerate(commands):
            if cmd.kind == CommandKind.POSITION:
                sh.target[i] = cmd.vector
                sh.velocity_mode[i] = False
            elif cmd.kind == CommandKind.VELOCITY:
                sh.target[i] = cmd.vector
                sh.velocity_mode[i] = True
            else:
                sh.target[i] = sh.p[i]
                sh.velocity_mode[i] = False
            sh.yaw[i] = cmd.yaw
            if cmd.action and self.construction is not None:
                body = self.world.agent_bodies[i]
                if cmd.action == Action.GRASP:
                    if self.construction.grasp(i, body, self.state_array[i, :3], t) >= 0:
                        self.controller.set_payload(i, self.construction.spec.box_mass)
                elif cmd.action == Action.RELEASE:
                    if self.construction.release(i, body, t) >= 0:
                        self.controller.set_payload(i, 0.0)

    def world_view(self) -> WorldView:
        """Everything now (for centralised planners; agents as they know themselves)."""
        s = self.sensed_state_array
        c = self.construction
        if c is None:
            empty3 = np.zeros((0, 3))
            return WorldView(self.time, s[:, :3].copy(), s[:, 7:10].copy(), np.full(self.n, -1), empty3,
                             np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=bool))
        return WorldView(self.time, s[:, :3].copy(), s[:, 7:10].copy(), c.carrying(self.n), c.positions.copy(),
                         c.state.copy(), c.slot_box.copy(), c.slot_open)

    def observations(self) -> list[Observation]:
        """Each agent's local observation: own state, neighbours in the sensing radius, visible objects."""
        from scipy.spatial import cKDTree

        s = self.sensed_state_array
        pos, vel = s[:, :3], s[:, 7:10]
        yaw = quat_to_euler(s[:, 3:7])[:, 2]
        r = self.scenario.agents.sensing_radius
        true_pos = self.state_array[:, :3]
        near = cKDTree(true_pos).query_ball_point(true_pos, r) if self.n > 1 else [[0]]
        noisy = self.flying_on_estimate and self.n > 1   # neighbours: true positions plus positioning noise
        carrying = self.construction.carrying(self.n) if self.construction is not None else np.full(self.n, -1)
        out = []
        t = self.time
        no3 = np.zeros((0, 3))
        noi = np.zeros(0, dtype=np.int64)
        for i in range(self.n):
            nb = np.array([j for j in near[i] if j != i], dtype=np.int64)
            nb_pos = (true_pos[nb] + self.estimation.neighbour_noise(nb.size)) if noisy else pos[nb].copy()
            if self.construction is not None and self.flying_on_estimate:
                # boxes are seen from the airframe (where it truly is), relative to it: in the agent's
                # own estimated frame; slots are planned coordinates, compared with the estimate as they are
                boxes, slots = self.construction.visible(true_pos[i])
                bpos = self.construction.positions[boxes] + (pos[i] - true_pos[i])
                spos = self.construction.slots[slots]
            elif self.construction is not None:
                boxes, slots = self.construction.visible(pos[i])
                bpos, spos = self.construction.positions[boxes], self.construction.slots[slots]
            else:
                boxes, slots, bpos, spos = noi, noi, no3, no3
            out.append(Observation(i, t, pos[i].copy(), vel[i].copy(), float(yaw[i]), int(carrying[i]), nb,
                                   nb_pos, vel[nb].copy(), bpos, boxes, spos, slots,
                                   ranges=self.ranges[i].copy()))
        return out

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
        est = self.estimation
        fe = self.fix_every if est is not None else 0
        sensed = self.sensed_state_array
        running = ExitStatus.RUNNING
        closed = not self.open_loop
        ghost = self.ghost and self.n > 1
        k = self.step_count
        end = k + steps
        while k < end and self.exit_status is running:
            if est is not None and (k % ce == 0 or k % fe == 0):
                self._sense(k)
            if k % pe == 0:
                self._planner_tick()
                if self.exit_status is not running:
                    break
            if closed and k % ce == 0:
                ctrl.position_update(sensed, shaper.step())
            worst = tick(*args)
            apply(forces, torques)
            advance()
            k += 1
            self.step_count = k
            read(state)
            pairs = contact_pairs()
            if ghost:
                pairs = self._with_ghost_overlaps(pairs)
            if pairs or contacts._prev:
                self._on_contacts(pairs)
            if worst:
                self._on_status(worst)
            if k % re == 0:
                self._sample()
                if self.video is not None and k % self.video_every == 0:
                    self._frame()
        self._wall_time += time.perf_counter() - t0
        return self.exit_status

    def _with_ghost_overlaps(self, pairs: Any) -> Any:
        """Add overlapping agent pairs (their contacts are disabled in ghost mode) to ``pairs``."""
        pos = self.state_array[:, :3]
        reach = 2.0 * self.params.radius + 0.01
        if self.n <= 64:
            d2 = np.sum((pos[:, None, :] - pos[None, :, :]) ** 2, axis=2)
            ii, jj = np.nonzero(np.triu(d2 < reach * reach, 1))
            cand = zip(ii.tolist(), jj.tolist())
        else:
            from scipy.spatial import cKDTree

            cand = cKDTree(pos).query_pairs(reach)
        bodies = self.world.agent_bodies
        extra = set()
        for i, j in cand:
            a, b = bodies[i], bodies[j]
            if self.world.overlapping(a, b):
                extra.add((a, b) if a < b else (b, a))
        return (set(pairs) | extra) if extra else pairs

    def _sample(self) -> None:
        """Work done at the recording rate: the recorder and the altitude high-water mark."""
        np.maximum(self.max_height, self.state_array[:, 2], out=self.max_height)
        if self.recorder is not None:
            s = self.state_array
            self.recorder.record(self.time, s[:, :7], s[:, 7:], self.controller.rotor_speeds, self.shaper.p,
                                 self.shaper.v)
            if self.construction is not None:
                self.construction.read()
                self.recorder.record_extra("box_positions", self.construction.positions)
            if self.estimation is not None:
                for name, value in self.estimation.channels().items():
                    self.recorder.record_extra(name, value)

    def run(self) -> RunResult:
        """Run until the task completes, the time limit passes, or an agent crashes."""
        chunk = self.planner_every
        while self.exit_status is ExitStatus.RUNNING:
            self.step(chunk)
        return self.result()

    # ---------------------------------------------------------------- results
    def metrics(self, ts: TimeSeries | None = None) -> dict[str, Any]:
        """Metrics of the run so far (plain JSON data), from ``ts`` when given (else the recorder's series)."""
        if ts is None and self.recorder is not None:
            ts = self.recorder.series()
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
            **(self.construction.metrics() if self.construction is not None else {}),
            "collisions": {c: self.contacts.counts[c] for c in COLLISION_CLASSES},
            "collision_time_s": {c: round(self.contacts.time_s[c], 9) for c in COLLISION_CLASSES},
        }
        if ts is not None and ts.t.size:
            m.update(flight_metrics(ts, self.params.km))
            m.update(self._swarm_metrics(ts))
        if self.construction is not None:
            m.update(self._construction_metrics(m))
        elif self.task is not None and hasattr(self.task, "metrics") and not isinstance(self.task, WaypointsRuntime):
            m.update(self.task.metrics(self, ts))
        if self.medium is not None and hasattr(self.medium, "metrics"):
            m.update(self.medium.metrics())
        if self.avoidance_layer is not None and hasattr(self.avoidance_layer, "metrics"):
            m.update(self.avoidance_layer.metrics())
        if self.estimation is not None:
            m["estimation"] = self.estimation_errors.metrics(
                {"state": self.scenario.sensing.state.value, **self.estimation.summary()})
        return m

    def _swarm_metrics(self, ts: TimeSeries) -> dict[str, Any]:
        from pybullet_swarm.metrics.construction import proximity_metrics, thesis_proximity_metrics, utility_of_space

        pos = ts.positions.astype(float)
        out = proximity_metrics(ts.t, pos, self.diameter)
        out.update(thesis_proximity_metrics(pos, self.diameter))
        out["utility_of_space"] = utility_of_space(pos[:, :, :2], self.scenario.arena.size)
        return out

    def _construction_metrics(self, m: dict[str, Any]) -> dict[str, Any]:
        from pybullet_swarm.metrics.construction import task_lower_bound

        c = self.construction
        assert c is not None
        v = self.scenario.velocity_limits()
        lb = task_lower_bound(self.starts, c.start, c.slots, np.full(3, 1e9) if v is None else v,
                              grasp_height=c.grasp_height)
        done = m.get("completion_time_s")
        return {"task_lower_bound_s": lb["task_lower_bound_s"],
                "efficiency": (lb["task_lower_bound_s"] / done) if done else None}

    def result(self) -> RunResult:
        """The run's result now."""
        empty = Recorder(self.n, 1).series()
        ts = self.recorder.series() if self.recorder is not None else empty
        return RunResult(self.exit_status, self.metrics(ts), self.all_events(), ts, self.scenario,
                         artifacts=self.artifacts())

    def artifacts(self) -> dict[str, Any]:
        """Objects that write their own files into a run directory: ``write(out_dir, plots) -> [Path]``
        (the planner's medium, the avoidance layer, the task), by name."""
        found = {"medium": self.medium, "avoidance": self.avoidance_layer, "task": self.task}
        return {k: v for k, v in found.items() if v is not None and callable(getattr(v, "write", None))}

    def all_events(self) -> list[Event]:
        """Contact, crash and task events in time order."""
        events = list(self.events)
        if self.task is not None and hasattr(self.task, "events"):
            events += self.task.events
        return sorted(events, key=lambda e: e.time_s)

    def close(self) -> None:
        """Finish the video and release the Bullet client."""
        if self.video is not None:
            self.close_video()
        self.world.close()

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
