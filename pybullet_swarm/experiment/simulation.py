"""The simulation loop: one clock for physics, control, planner and recording ticks.

The loop can be stepped from outside (``reset``, ``step``, ``state``), which is what learning
environments wrap, or run to the end with ``run``.
"""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path
from typing import AbstractSet, Any

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.control.cascade import CascadeController
from pybullet_swarm.control.design import ReferenceStep
from pybullet_swarm.control.kernels import STATUS_FLIPPED, STATUS_NONFINITE, physics_tick
from pybullet_swarm.control.reference import ReferenceShaper
from pybullet_swarm.control.rotations import quat_to_euler
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.recorder import Recorder, TimeSeries
from pybullet_swarm.experiment.scenario import WALL_THICKNESS, Scenario
from pybullet_swarm.metrics.collisions import COLLISION_CLASSES, CollisionClass, ContactTracker, IncidentCounter
from pybullet_swarm.metrics.flight import flight_metrics
from pybullet_swarm.rng import named_rng
from pybullet_swarm.planning.base import (
    Action,
    AvoidanceSetup,
    CarriesPayload,
    Command,
    CommandKind,
    Observation,
    Payload,
    TaskInfo,
    TaskView,
    WorldView,
)
from pybullet_swarm.sensing.perception import PerceptionStage
from pybullet_swarm.tasks import task_runtimes
from pybullet_swarm.tasks.base import NOT_MINE, TaskContext, TaskRuntime
from pybullet_swarm.types import Event, ExitStatus, Perception, SwarmState
from pybullet_swarm.vehicle import VehicleParams, load_vehicle
from pybullet_swarm.vehicle.downwash import Downwash
from pybullet_swarm.world import BodyKind, World

CRASH_LOOKBACK_S = 3.0
"""s: a crash is put down to what happened to the agent this long before it (``crash_cause``)."""
WAKE_CAUSE_FRACTION = 0.05
"""A crash with no agent-agent contact before it counts as the wake's when another agent's downwash pushed the
agent down with at least this fraction of its weight within ``CRASH_LOOKBACK_S`` (the fraction at which ORCA's
``wake_depth`` ends the column under an agent)."""


@dataclasses.dataclass(frozen=True)
class RunResult:
    """Outcome of a run.

    Attributes:
        exit_status: how it ended.
        artifacts: files for the run directory as data by file name (``.json``: plain data, ``.npz``:
            arrays by name): the planner's medium, the task's plan and state.
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
        planner: planner name (default: the scenario's).
        avoidance: avoidance layer name (default: the scenario's).
        gui: watch in the Bullet GUI.
        record: keep time series.

    ``planner``, ``avoidance`` and ``seed`` are applied to the scenario and validated with it
    (``Scenario.with_choices``): ``self.scenario`` names what runs.
    """

    def __init__(
        self,
        scenario: Scenario,
        *,
        seed: int | None = None,
        planner: str | None = None,
        avoidance: str | None = None,
        gui: bool = False,
        record: bool = True,
        video: Path | None = None,
        video_quiet: bool = False,
    ) -> None:
        # the choices are applied to the scenario and validated with it (its data then name them)
        scenario = scenario.with_choices(planner=planner, avoidance=avoidance, seed=seed)
        self.scenario = scenario
        self.seed = scenario.seed
        self.planner_name = str(scenario.planner.name)
        self.avoidance_name = scenario.avoidance
        s = scenario.sim
        self.physics_hz = s.physics_hz
        self.dt = 1.0 / s.physics_hz
        self.control_every = s.physics_hz // s.control_hz
        self.planner_every = s.physics_hz // s.planner_hz
        self.record_every = s.physics_hz // s.record_hz
        self.contact_every = s.physics_hz // (s.contact_hz or s.physics_hz)  # physics steps between contact reads
        self.params: VehicleParams = load_vehicle(scenario.agents.vehicle)
        self.n = scenario.agents.count
        self.gui = gui
        self.record_enabled = record
        self._build()
        self.video: Any = None  # a VideoWriter while recording
        if video is not None:
            self._open_video(Path(video), video_quiet)

    # ------------------------------------------------------------------ set-up
    def _build(self) -> None:
        sc, s, p, n = self.scenario, self.scenario.sim, self.params, self.n
        # read every step, the ghost pairs get one broad phase per control period (their exact query still runs
        # every step); read less often, one at each read
        horizon = self.control_every if self.contact_every == 1 else 1
        self.world = World(physics_hz=s.physics_hz, gravity=s.gravity, gui=self.gui, ghost_horizon=horizon)
        self.world.add_ground()
        if sc.arena.walls:
            self.world.add_walls(sc.arena.size, sc.arena.wall_height, thickness=WALL_THICKNESS)
        for k, ob in enumerate(sc.arena.obstacles):  # static pillars and boxes: contacts are agent_obstacle
            if ob.shape == "cylinder":
                self.world.add_cylinder(ob.center().tolist(), ob.size[0], ob.size[1], name=f"obstacle{k}")
            else:
                self.world.add_box(ob.center().tolist(), ob.size, yaw=math.radians(ob.yaw_deg), name=f"obstacle{k}")
        self.rest_height = 0.5 * p.collision_size[2] + 1e-3
        self.starts = sc.start_positions(self.rest_height)
        jitter = sc.agents.start_jitter
        if jitter > 0.0:  # hand placement is never exact; the seed decides how
            self.starts[:, :2] += named_rng(self.seed, "start_jitter").uniform(-jitter, jitter, size=(n, 2))
        self.world.add_agents(p.urdf_path, self.starts, mass=p.mass, inertia=p.inertia)
        if sc.collisions == "ghost":
            self.world.set_agent_collisions(False)
        self.agent_index = {b: i for i, b in enumerate(self.world.agent_bodies)}
        self.controller = CascadeController(
            p,
            n,
            physics_hz=s.physics_hz,
            control_hz=s.control_hz,
            gravity=s.gravity,
            max_tilt_deg=s.max_tilt_deg,
            drag=s.drag_coefficient,
            ground_effect=s.ground_effect,
            prefilter=sc.velocity_limits() is not None,
            reference_step=ReferenceStep.from_limits(sc.velocity_limits(), sc.acceleration_limits()),
        )
        self.shaper = ReferenceShaper(n, sc.velocity_limits(), sc.acceleration_limits(), 1.0 / s.control_hz)
        # rotor wakes on the vehicles and boxes below them, added to the forces every physics step
        self.downwash = Downwash(p.downwash_params) if s.downwash else None
        self.state_array = np.zeros((n, 13))  # position, quaternion, velocity, angular velocity (world)
        self.world.read_agent_states(self.state_array)
        self.shaper.reset(self.state_array[:, :3])
        self.time_limit = float(sc.task.time_limit_s)
        cap = int(math.ceil(self.time_limit * s.record_hz)) + 2
        self.recorder = Recorder(n, cap) if self.record_enabled else None
        self.ghost = sc.collisions == "ghost"
        self.diameter = float(max(p.collision_size[0], p.collision_size[1]))  # m, agent "diameter"
        self.max_height = self.starts[:, 2].copy()  # m, highest recorded altitude per agent
        self.contacts = ContactTracker(self._classify, self.dt * self.contact_every, debounce_s=0.1)
        self.incidents = IncidentCounter(self.contacts.debounce_s)  # contact events that belong together count once
        # m/s, each agent's lowest vertical velocity since the last contact read (a ground impact's speed); the
        # state's own when contacts are read every step
        self._vz_low = np.full(n, np.inf) if self.contact_every > 1 else self.state_array[:, 9]
        self.events: list[Event] = []
        self.step_count = 0
        self.exit_status = ExitStatus.RUNNING
        self.crashed_agent: int | None = None
        self.crash_cause: str | None = None  # what came before the crash (``_crash_cause``)
        # N, the downwash each agent carried at the last recording instants (``CRASH_LOOKBACK_S``), and when
        hist = int(math.ceil(CRASH_LOOKBACK_S * s.record_hz)) + 1
        self._wake_hist = np.zeros((hist, n))
        self._wake_t = np.full(hist, -np.inf)
        self._wake_k = 0
        self.weight = float(p.mass) * float(s.gravity)  # N
        self.open_loop = False
        self._external = False
        self._wall_time = 0.0
        self.range_sensor: Any = None
        self.ranges = np.zeros((n, 0))  # (n, r) m, range readings of the last planner tick
        from pybullet_swarm.planning.registry import avoidance_layers

        self.avoidance_entry = avoidance_layers()[self.avoidance_name]
        self.avoidance_factory = self.avoidance_entry.factory  # None: no avoidance layer
        if sc.sensing.range.enabled or self.avoidance_entry.needs_range_sensors:
            self.enable_range_sensors()
        self.position_std = self._expected_position_std()
        self.task: TaskRuntime = task_runtimes()[sc.task.kind](
            sc.task,
            TaskContext(
                world=self.world,
                n=n,
                starts=self.starts.copy(),
                agent_radius=float(p.radius),
                collision_size=np.asarray(p.collision_size, dtype=float),
                arena_size=np.asarray(sc.arena.size, dtype=float),
                arena_height=sc.arena.height,
                v_max=sc.velocity_limits(),
                a_max=sc.acceleration_limits(),
                ghost=self.ghost,
                position_std=self.position_std,
                rng=named_rng(self.seed, "task"),
            ),
        )
        self.info = self._task_info()
        #: what an agent carries under it, when the task's layout says so (the wakes push on it too)
        self.payload: Payload | None = (
            self.info.layout.payload if isinstance(self.info.layout, CarriesPayload) else None
        )
        # the boxes the wakes push on (every movable one, free or carried), their poses read every physics step
        sizes = self.world.dynamic_boxes if self.downwash is not None else {}
        self.wake_boxes = list(sizes)
        self._box_pose = np.zeros((len(sizes), 7))
        self._box_half = 0.5 * np.array(list(sizes.values()), dtype=float).reshape(-1, 3)
        self._box_force = np.zeros((len(sizes), 3))
        # stall detection: the task's progress count and when (and where the agents were) it last changed
        self.stall_time: float | None = self.task.stall_time_s
        self._progress: int | None = None
        self._progress_at = 0.0
        self._progress_positions = self.starts.copy()
        self.estimation: Any = None  # OnboardEstimation when sensing.state is estimated (or run_estimator)
        self.flying_on_estimate = sc.sensing.state.value == "estimated"
        self._make_planner()
        if sc.sensing.estimating:
            self._make_estimation()
        self.perception_stage = PerceptionStage(
            n,
            float(sc.agents.sensing_radius),
            position_std=self.position_std,
            neighbour_noise=(lambda k: self.estimation.neighbour_noise(k))
            if self.flying_on_estimate and n > 1
            else None,
            radio=self._make_radio(),
        )
        self.wind = self._make_wind()
        self.task_view: TaskView = self.task.view(0.0)
        self.perception: Perception | None = None

    def _make_radio(self) -> Any:
        """The radio of the ``comm`` flight condition, or None when it is off (neighbours perceived directly)."""
        sc = self.scenario
        if not sc.comm.enabled:
            return None
        from pybullet_swarm.sensing.comm import CommParams, Radio

        return Radio(
            self.n,
            CommParams(**sc.comm.model_dump()),
            sensing_radius=float(sc.agents.sensing_radius),
            planner_dt=1.0 / sc.sim.planner_hz,
            loss_rng=named_rng(self.seed, "comm/loss"),
            gps_rng=named_rng(self.seed, "comm/gps"),
        )

    def _make_wind(self) -> Any:
        """The ``wind`` flight condition on every vehicle and every movable box, or None when it is off."""
        sc = self.scenario
        if not sc.wind.enabled:
            return None
        from pybullet_swarm.vehicle.wind import Wind, WindParams

        boxes = self.world.dynamic_boxes
        self.wind_boxes = list(boxes)
        areas = np.array([(a * b + b * c + a * c) / 3.0 for a, b, c in boxes.values()], dtype=float)  # mean face, m^2
        self._box_velocities = np.zeros((len(boxes), 6))
        w = sc.wind
        return Wind(
            WindParams(tuple(w.velocity), w.turbulence, w.length_scale_m),  # type: ignore[arg-type]
            self.n,
            self.params.drag_coefficients,
            areas,
            self.dt,
            named_rng(self.seed, "wind"),
        )

    def _blow(self, state: NDArray[np.float64], forces: NDArray[np.float64]) -> None:
        """One physics period of wind: gusts advance, drag on the vehicles (into ``forces``) and the boxes."""
        wind = self.wind
        wind.step()
        wind.add_to(state, forces)
        if self.wind_boxes:
            self.world.read_body_velocities(self.wind_boxes, self._box_velocities)
            self.world.apply_body_forces(self.wind_boxes, wind.box_forces(self._box_velocities[:, :3]))

    def _push_boxes(self, box_force: NDArray[np.float64]) -> None:
        """Apply the wakes' forces (k, 3) N on the boxes that have one (most boxes are in no wake)."""
        hit = np.flatnonzero(box_force.any(axis=1))
        if hit.size:
            self.world.apply_body_forces([self.wake_boxes[i] for i in hit.tolist()], box_force[hit])

    def enable_range_sensors(self) -> None:
        """Give every agent the fan of range rays of ``sensing.range`` (idempotent; avoidance layers
        that need readings call it); they are cast once per planner tick from then on."""
        if self.range_sensor is not None:
            return
        from pybullet_swarm.sensing.range import RangeFan, RangeSensor, fan_angles

        cfg = self.scenario.sensing.range
        fan = RangeFan(fan_angles(cfg.rays, cfg.fov_deg), float(cfg.range_m), float(self.params.radius) + 1e-3)
        self.range_sensor = RangeSensor(fan, cfg.noise_std_m, named_rng(self.seed, "range_noise"))
        self.ranges = np.full((self.n, fan.rays), fan.range_m)

    def _cast_ranges(self) -> None:
        """Cast every agent's fan from its true pose (one batched call)."""
        s = self.state_array
        self.ranges = self.range_sensor.read(self.world, s[:, :3], quat_to_euler(s[:, 3:7])[:, 2])

    def _make_estimation(self) -> None:
        """IMU, positioning and the estimator, calibrated at rest; their generators are children of the
        run's ``estimation`` stream (``pybullet_swarm.rng``), so that no other consumer's draws depend on them."""
        from pybullet_swarm.metrics.estimation import EstimationErrors
        from pybullet_swarm.sensing.estimator import EstimatorParams, OnboardEstimation
        from pybullet_swarm.sensing.imu import ImuNoise
        from pybullet_swarm.sensing.positioning import PositioningParams

        cfg, s = self.scenario.sensing, self.scenario.sim
        self.estimation = OnboardEstimation(
            self.n,
            ImuNoise(**cfg.imu.model_dump()),
            PositioningParams(**cfg.positioning.model_dump()),
            EstimatorParams(**cfg.estimator.model_dump()),
            control_hz=s.control_hz,
            gravity=s.gravity,
            rng=named_rng(self.seed, "estimation"),
        )
        self.estimation.start(self.state_array, self.time)
        self.estimation_errors = EstimationErrors()
        self.fix_every = s.physics_hz // cfg.positioning.rate_hz

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

    def _expected_position_std(self) -> float:
        """m, per-axis standard deviation an agent can expect of its own position estimate (0 on true state)."""
        sc = self.scenario
        if sc.sensing.state.value != "estimated":
            return 0.0
        from pybullet_swarm.sensing.estimator import EstimatorParams, expected_position_std
        from pybullet_swarm.sensing.positioning import PositioningParams

        return float(
            expected_position_std(
                PositioningParams(**sc.sensing.positioning.model_dump()),
                EstimatorParams(**sc.sensing.estimator.model_dump()),
                control_hz=sc.sim.control_hz,
            )
        )

    def _task_info(self) -> TaskInfo:
        """The static layout every agent knows: the arena, limits and what the task publishes."""
        sc, p = self.scenario, self.params
        v = sc.velocity_limits()
        kw = dict(self.task.task_info())
        extra = dict(kw.pop("extra", {}))
        if sc.sensing.state.value == "estimated":  # what an agent can expect of its own position estimate
            extra["position_std"] = self.position_std
        extra["downwash"] = bool(sc.sim.downwash)  # whether vehicles' wakes act on each other (rules minding them)
        # whether an avoidance layer keeps agents apart (a planner may share a lane only with one)
        extra["avoidance"] = self.avoidance_factory is not None
        # the arena as flocking models see it: walls and pillars (a box as the circle around its footprint)
        extra["arena_walls"] = bool(sc.arena.walls)
        extra["pillars"] = sc.arena.pillars()
        return TaskInfo(
            arena_size=np.asarray(sc.arena.size, dtype=float),
            n_agents=self.n,
            agent_radius=p.radius,
            v_max=np.full(3, np.inf) if v is None else v,
            a_max=sc.acceleration_limits(),
            extra=extra,
            **kw,
        )

    def _avoidance_setup(self) -> AvoidanceSetup:
        sc, p = self.scenario, self.params
        fan = self.range_sensor.fan if self.range_sensor is not None else None
        return AvoidanceSetup(
            n=self.n,
            info=self.info,
            agent_radius=float(p.radius),
            collision_size=np.asarray(p.collision_size, dtype=float),
            v_max=sc.velocity_limits(),
            a_max=sc.acceleration_limits(),
            control_dt=1.0 / sc.sim.control_hz,
            planner_dt=1.0 / sc.sim.planner_hz,
            sensing_radius=float(sc.agents.sensing_radius),
            range_angles=np.zeros(0) if fan is None else np.asarray(fan.angles, dtype=float),
            range_m=0.0 if fan is None else float(fan.range_m),
            range_offset=0.0 if fan is None else float(fan.start_offset),
            obstacles=sc.arena.obstacle_boxes(),
            downwash=bool(sc.sim.downwash),
            downwash_model=p.downwash_params,
            mass=float(p.mass),
            payload=self.payload,
        )

    def _make_planner(self) -> None:
        from pybullet_swarm.planning.registry import make_medium, planners

        self.planner_entry = entry = planners()[self.planner_name]
        factory = entry.factory
        params = self.scenario.planner_params  # validated when the scenario was loaded
        self.medium = make_medium(entry, params, self.info)  # a medium shared by every agent (a pheromone grid)
        av_factory = self.avoidance_factory
        self.avoidance_layer = (
            av_factory(self._avoidance_setup(), self.scenario.avoidance_params) if av_factory is not None else None
        )
        try:
            if entry.centralized:
                self.planner = factory(params)
                self.planner.reset(self.n, named_rng(self.seed, "planner"), self.info)
                self.agent_planners = None
            else:
                self.planner = None
                self.agent_planners = [factory(params) for _ in range(self.n)]
                for i, pl in enumerate(self.agent_planners):
                    pl.reset(i, named_rng(self.seed, f"planner/{i}"), self.info)
        except ConfigError as exc:  # what only the task's layout shows (e.g. altitudes that do not rise)
            raise (exc.with_source(self.scenario.source) if exc.source is None else exc) from None

    #: simulated frames per second of a video, and the playback rate (4x faster than real time)
    VIDEO_SIM_HZ = 5
    VIDEO_FPS = 20

    def _open_video(self, path: Path, quiet: bool) -> None:
        from pybullet_swarm.experiment.video import VideoWriter, camera_for_arena

        if self.physics_hz % self.VIDEO_SIM_HZ:
            raise ConfigError(
                f"must be a multiple of {self.VIDEO_SIM_HZ} Hz for video, got {self.physics_hz}",
                source=self.scenario.source,
                field="sim.physics_hz",
            )
        self.video_every = self.physics_hz // self.VIDEO_SIM_HZ
        framing = self.task.framing()
        height = framing.height if framing.height is not None else max(1.0, float(np.max(self.starts[:, 2])) + 0.5)
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
            load = self.task.body_contact_class(a, b)
            return None if load is None else CollisionClass(load)
        if kb is BodyKind.AGENT:
            return CollisionClass.AGENT_AGENT
        if kb is BodyKind.GROUND:
            i = self.agent_index[a]
            airborne = max(self.max_height[i], self.state_array[i, 2]) > self.rest_height + 0.05
            return CollisionClass.AGENT_GROUND if airborne else None
        owned = self.task.contact_class(self.agent_index[a], b)
        if owned != NOT_MINE:
            return None if owned is None else CollisionClass(owned)
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

    def set_targets(
        self, positions: NDArray[np.float64] | None, yaw: NDArray[np.float64] | None = None, *, velocities: bool = False
    ) -> None:
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
        if self.task.update(t, self.state_array[:, :3]):
            self._finish(ExitStatus.COMPLETED)
            return
        if self.stall_time is not None and self._stalled(t):
            return
        if self.range_sensor is not None:
            self._cast_ranges()
        self.task_view = self.task.view(t)
        if not self._external:
            self.perception = perception = self.perceive()
            if self.planner is not None:
                commands = self.planner.plan_all(WorldView.of(perception, self.task_view))
            else:
                assert self.agent_planners is not None
                obs = self.observations(perception)
                commands = [pl.plan(o, self.medium) for pl, o in zip(self.agent_planners, obs)]
            if self.avoidance_layer is not None:
                commands = self.avoidance_layer.filter(commands, perception, self.task_view)
            self._apply(commands)
        if self.medium is not None:
            self.medium.step(1.0 / self.scenario.sim.planner_hz)
        if t >= self.time_limit - 1e-9:
            self._finish(ExitStatus.TIMEOUT)

    def _stalled(self, t: float) -> bool:
        """True (and the run ends as stalled, its agents' doings in the events) when the task's progress
        count has not changed for ``stall_time`` s."""
        count = self.task.progress()
        if count != self._progress:
            self._progress, self._progress_at = count, t
            self._progress_positions = self.state_array[:, :3].copy()
            return False
        assert self.stall_time is not None
        if t - self._progress_at < self.stall_time - 1e-9:
            return False
        self.events.append(
            Event(
                t,
                ExitStatus.STALLED.value,
                "",
                "",
                f"no task progress for {t - self._progress_at:g} s (since {self._progress_at:g} s)",
            )
        )
        doing = self.activities()
        carrying = self.task.view(t).carrying
        target, velocity = self.shaper.target, self.shaper.velocity_mode
        for i in range(self.n):
            p = self.state_array[i, :3]
            moved = float(np.linalg.norm(p - self._progress_positions[i]))
            what = f"{doing[i]}; " if doing[i] else ""
            ref = "velocity command" if velocity[i] else "target"  # an avoidance layer commands velocities
            self.events.append(
                Event(
                    t,
                    "stalled_agent",
                    f"agent{i}",
                    f"box{carrying[i]}" if i < len(carrying) and carrying[i] >= 0 else "",
                    f"{what}at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m, {ref} ({target[i, 0]:.2f}, "
                    f"{target[i, 1]:.2f}, {target[i, 2]:.2f}) {'m/s' if velocity[i] else 'm'}, {moved:.2f} m from "
                    f"where it was at {self._progress_at:g} s",
                )
            )
        self._finish(ExitStatus.STALLED)
        return True

    def activities(self) -> list[str]:
        """What each agent's planner says it is doing (its phase and target), '' where it says nothing."""
        if not self.planner_entry.reports_activity:
            out: list[str] = []
        elif self.planner is not None:
            out = list(self.planner.activities())
        else:
            out = [pl.activity() for pl in self.agent_planners or []]
        return (out + [""] * self.n)[: self.n]

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
            if cmd.action:
                self.act(i, cmd.action, t)

    def act(self, agent: int, action: Action, t: float | None = None) -> None:
        """Hand an agent's task action to the task now; a changed payload goes to the controller."""
        payload = self.task.apply(agent, action, self.time if t is None else t, self.state_array[agent, :3])
        if payload is not None:
            self.controller.set_payload(agent, payload + self.own_wake_load(payload))
            self.contacts.reclassify_all()  # a box changed role: its touching pairs count differently

    def own_wake_load(self, payload: float) -> float:
        """kg, what the drag of a carrier's own wake on the box it holds weighs, for the thrust feed-forward of a
        carrier of ``payload`` kg (0 without wakes or a box): the drag is k T at thrust T (the wake's dynamic
        pressure grows with T), so the carrier hovers at T = (m + payload) g / (1 - k), and the box pulls like
        ``(m + payload) k / (1 - k)`` kg more. Without it the position loop's integrator alone would carry a load
        of about a quarter of the weight, more than its limit: the carrier would hang below its reference."""
        box = self.payload
        if self.downwash is None or payload <= 0.0 or box is None:
            return 0.0
        k = self.downwash.params.force_on_box(box.hang - 0.5 * box.edge, box.edge, thrust=1.0)
        k = min(k, 0.5)  # a box that takes more than half the thrust is no load to feed forward
        return (float(self.params.mass) + payload) * k / (1.0 - k)

    def perceive(self, *, neighbours: bool | None = None) -> Perception:
        """The swarm's perception snapshot now (one spatial query; neighbour noise drawn when flying on
        estimates). Neighbours are perceived when asked for, by default when a decentralised planner or
        an avoidance layer will read them."""
        if neighbours is None:
            neighbours = self.agent_planners is not None or self.avoidance_layer is not None
        return self.perception_stage.snapshot(
            self.time,
            self.state_array,
            self.sensed_state_array,
            self.ranges,
            self.task_view.carrying,
            neighbours=neighbours,
        )

    def world_view(self) -> WorldView:
        """Everything now (for centralised planners; agents as they know themselves)."""
        return WorldView.of(self.perceive(), self.task.view(self.time))

    def observations(self, perception: Perception | None = None) -> list[Observation]:
        """Each agent's local observation: its row of the perception snapshot and the task objects it sees."""
        pc = self.perceive(neighbours=True) if perception is None else perception
        local = self.task.local_views(self.state_array[:, :3], pc.positions)
        out = []
        t = pc.time_s
        for i in range(self.n):
            nb = pc.neighbours(i)
            seen = local[i] if local is not None else None
            out.append(
                Observation(
                    i,
                    t,
                    pc.positions[i],
                    pc.velocities[i],
                    float(pc.yaws[i]),
                    int(pc.carrying[i]),
                    pc.nb_ids[nb],
                    pc.nb_positions[nb],
                    pc.nb_velocities[nb],
                    seen,
                    ranges=pc.ranges[i],
                    neighbour_carrying=pc.carrying[pc.nb_ids[nb]] >= 0,
                )
            )
        return out

    def _finish(self, status: ExitStatus, agent: int | None = None, detail: str = "") -> None:
        if self.exit_status is ExitStatus.RUNNING:
            self.exit_status = status
            if agent is not None:
                self.crashed_agent = agent
            if status is ExitStatus.CRASHED and agent is not None:
                self.crash_cause, why = self._crash_cause(agent)
                detail = f"{detail}; {why}" if detail else why
            if status in (ExitStatus.CRASHED, ExitStatus.DIVERGED):
                self.events.append(
                    Event(self.time, status.value, f"agent{agent}" if agent is not None else "", "", detail)
                )

    def _crash_cause(self, i: int) -> tuple[str, str]:
        """What came before agent ``i``'s crash within ``CRASH_LOOKBACK_S``, as a cause and in words: an
        agent-agent contact of its own (``agent_agent_contact``), else another agent's wake pushing it down with at
        least ``WAKE_CAUSE_FRACTION`` of its weight at a recording instant (``wake``), else ``other``."""
        t0 = self.time - CRASH_LOOKBACK_S
        name = f"agent{i}"
        hits = [
            e
            for e in self.events
            if e.kind == CollisionClass.AGENT_AGENT.value and e.time_s >= t0 and name in (e.a, e.b)
        ]
        recent = self._wake_t >= t0
        peak = float(np.max(self._wake_hist[recent, i])) if recent.any() else 0.0
        wake = f"downwash on it up to {peak:.3f} N ({100.0 * peak / self.weight:.0f} % of its weight)"
        if hits:
            other = hits[-1].b if hits[-1].a == name else hits[-1].a
            return "agent_agent_contact", f"{self.time - hits[-1].time_s:.2f} s after a contact with {other}; {wake}"
        if peak >= WAKE_CAUSE_FRACTION * self.weight:
            return "wake", f"no agent-agent contact in the last {CRASH_LOOKBACK_S:g} s; {wake}"
        return "other", f"no agent-agent contact in the last {CRASH_LOOKBACK_S:g} s; {wake}"

    def _unit(self, body: int) -> str | None:
        """What a body in a contact event stands for when events are grouped into incidents: an agent, a held
        body as its holder, any other moving body as itself; the ground, walls and obstacles as nothing."""
        kind = self.world.body_kind(body)
        if kind in (BodyKind.GROUND, BodyKind.WALL, BodyKind.OBSTACLE):
            return None
        holder = self.world.holder(body) if kind is not BodyKind.AGENT else None
        return self.world.body_name(body if holder is None else holder)

    def _on_contacts(self, pairs: AbstractSet[tuple[int, int]]) -> None:
        t = self.time
        for cls, a, b in self.contacts.update(pairs, t):
            wa, wb = self.world.body_name(a), self.world.body_name(b)
            self.events.append(Event(t, cls.value, wa, wb))
            self.incidents.add(t, tuple(u for u in (self._unit(a), self._unit(b)) if u is not None))
            if cls is CollisionClass.AGENT_GROUND:
                body = a if self.world.body_kind(a) is BodyKind.AGENT else b
                i = self.agent_index[body]
                vz = self._vz_low[i]
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
        interact = self.downwash.add_to if self.downwash is not None and (self.n > 1 or self.wake_boxes) else None
        boxes, box_pose, box_half, box_force = self.wake_boxes, self._box_pose, self._box_half, self._box_force
        read_boxes = world.read_body_poses
        push = self._push_boxes
        blow = self._blow if self.wind is not None else None
        rotor_speeds = ctrl.rotor_speeds
        apply, advance, read, contact_pairs = (
            world.apply_agent_wrenches,
            world.step,
            world.read_agent_states,
            world.contact_pairs,
        )
        ce, pe, re, cte = self.control_every, self.planner_every, self.record_every, self.contact_every
        vz_low = self._vz_low
        est = self.estimation
        fe = self.fix_every if est is not None else 0
        sensed = self.sensed_state_array
        running = ExitStatus.RUNNING
        closed = not self.open_loop
        leash = self.scenario.sim.reference_leash
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
                if leash is not None:
                    shaper.leash(sensed[:, :3], leash)
                ctrl.position_update(sensed, shaper.step())
            worst = tick(*args)
            if interact is not None:
                if boxes:
                    read_boxes(boxes, box_pose)
                    box_force[:] = 0.0
                interact(state, rotor_speeds, forces, box_pose, box_half, box_force)
                if boxes:
                    push(box_force)
            if blow is not None:
                blow(state, forces)
            apply(forces, torques)
            advance()
            k += 1
            self.step_count = k
            read(state)
            if cte == 1:
                pairs = contact_pairs()  # ghost mode's overlaps included (World.set_ghost_pair)
                if pairs or contacts._prev:
                    self._on_contacts(pairs)
            else:
                np.minimum(vz_low, state[:, 9], out=vz_low)
                if k % cte == 0:
                    pairs = contact_pairs()
                    if pairs or contacts._prev:
                        self._on_contacts(pairs)
                    vz_low[:] = np.inf
            if worst:
                self._on_status(worst)
            if k % re == 0:
                self._sample()
                if self.video is not None and k % self.video_every == 0:
                    self._frame()
        self._wall_time += time.perf_counter() - t0
        return self.exit_status

    def _sample(self) -> None:
        """Work done at the recording rate: the recorder and the altitude high-water mark."""
        np.maximum(self.max_height, self.state_array[:, 2], out=self.max_height)
        if self.downwash is not None and self.downwash.last.size:
            k = self._wake_k % len(self._wake_t)
            self._wake_hist[k] = self.downwash.last
            self._wake_t[k] = self.time
            self._wake_k += 1
        if self.recorder is not None:
            s = self.state_array
            self.recorder.record(
                self.time, s[:, :7], s[:, 7:], self.controller.rotor_speeds, self.shaper.p, self.shaper.v
            )
            for name, value in self.task.sample().items():
                self.recorder.record_extra(name, value)
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
            "crash_cause": self.crash_cause,
            "completion_time_s": self.task.completed_at,
            "collisions": {c: self.contacts.counts[c] for c in COLLISION_CLASSES},
            "collision_time_s": {c: round(self.contacts.time_s[c], 9) for c in COLLISION_CLASSES},
            "incidents": self.incidents.count,
        }
        if ts is not None and ts.t.size:
            m.update(flight_metrics(ts, self.params.km))
            m.update(self._swarm_metrics(ts))
        m.update(self.task.metrics(ts, self.planner_artefacts()))
        for part in (self.medium, self.avoidance_layer):  # both protocols report metrics
            if part is not None:
                m.update(part.metrics())
        if self.estimation is not None:
            m["estimation"] = self.estimation_errors.metrics(
                {"state": self.scenario.sensing.state.value, **self.estimation.summary()}
            )
        return m

    def planner_artefacts(self) -> dict[str, Any]:
        """What the planner publishes as data (e.g. a tour planner's ``tour_plan``)."""
        if self.planner is None or not self.planner_entry.publishes_artefacts:
            return {}
        return dict(self.planner.artefacts())

    def _swarm_metrics(self, ts: TimeSeries) -> dict[str, Any]:
        from pybullet_swarm.metrics.proximity import proximity_metrics, thesis_proximity_metrics, utility_of_space

        pos = ts.positions.astype(float)
        out = proximity_metrics(ts.t, pos, self.diameter)
        out.update(thesis_proximity_metrics(pos, self.diameter))
        out["utility_of_space"] = utility_of_space(pos[:, :, :2], self.scenario.arena.size)
        return out

    def result(self) -> RunResult:
        """The run's result now."""
        empty = Recorder(self.n, 1).series()
        ts = self.recorder.series() if self.recorder is not None else empty
        return RunResult(
            self.exit_status, self.metrics(ts), self.all_events(), ts, self.scenario, artifacts=self.artifacts()
        )

    def artifacts(self) -> dict[str, Any]:
        """Files for the run directory as data by file name: the medium's, the task's, the layer's."""
        out: dict[str, Any] = dict(self.task.artefacts(self.planner_artefacts()))
        if self.medium is not None:
            out.update(self.medium.artefacts())
        if self.avoidance_layer is not None and self.avoidance_entry.publishes_artefacts:
            out.update(self.avoidance_layer.artefacts())
        return out

    def all_events(self) -> list[Event]:
        """Contact, crash and task events in time order."""
        events = list(self.events) + list(self.task.events)
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
