"""The engine under every learning environment: one scenario run, stepped by arrays of actions.

An episode is exactly a ``Simulation`` run of the scenario with the given seed in which the
actions take the place of the planner: the same physics, clock, task judgement, collision
counting and metrics as ``pybullet-swarm run``. Fed with the set-points a planner would issue,
an episode ends with the metrics of the plain run (wall-time fields aside).

Timing. An environment step covers one planner, control or physics period (``EnvConfig.period``).
The action is applied when the step begins: velocity and waypoint set-points go to the
reference shaper (so the next position-loop tick uses them), rotor speeds to the motors, and
GRASP/RELEASE at the first planner tick of the step, after the task has judged the boxes, as
the task applies a planner's commands. When a step ends on a planner tick, the task is judged at
once: a step that completes the task (or reaches the time limit) reports it itself, never the
step after.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from pybullet_swarm.envs.actions import ActionMapper
from pybullet_swarm.envs.config import ActionType, EnvConfig, StepPeriod
from pybullet_swarm.envs.rewards import RewardTracker, StepOutcome
from pybullet_swarm.envs.spaces import RANGE_BOUND, ObservationBuilder, ObservationLayout
from pybullet_swarm.experiment.scenario import Scenario
from pybullet_swarm.experiment.simulation import Simulation
from pybullet_swarm.planning.base import Action, Command, CommandKind, TaskInfo, WorldView
from pybullet_swarm.planning.views.waypoints import set_points_of
from pybullet_swarm.types import ExitStatus

TERMINAL = frozenset({ExitStatus.COMPLETED, ExitStatus.CRASHED, ExitStatus.DIVERGED})


class ActionBridge:
    """A centralised planner that issues the environment's latest actions as commands.

    Installed in place of the scenario's planner when actions carry GRASP/RELEASE or when the
    scenario has an avoidance layer, so that they go through the simulation's own command path
    (task actions after the task update, the avoidance filter) at each planner tick.
    """

    name: ClassVar[str] = "env"
    centralized: ClassVar[bool] = True

    def __init__(self, n: int, yaw: NDArray[np.float64]) -> None:
        self.kind = CommandKind.HOLD
        self.vectors = np.zeros((n, 3))  # m or m/s
        self.actions = np.zeros(n, dtype=np.int64)
        self.yaw = yaw  # (n,) rad, the shaper's yaw (kept)

    def reset(self, n: int, rng: np.random.Generator, info: TaskInfo) -> None:
        """Nothing to prepare."""

    def set(self, kind: CommandKind, vectors: NDArray[np.float64] | None, actions: NDArray[np.int64] | None) -> None:
        """The commands of the next planner ticks."""
        self.kind = kind
        if vectors is not None:
            self.vectors = np.array(vectors, dtype=float).reshape(-1, 3)
        if actions is None:
            self.actions = np.zeros(len(self.actions), dtype=np.int64)
        else:  # a request waits for the next planner tick unless a newer one replaces it
            self.actions = np.where(actions != int(Action.NONE), actions, self.actions)

    def plan_all(self, view: WorldView) -> list[Command]:
        """One command per agent; a task action is used once."""
        kind, vec, act, yaw = self.kind, self.vectors, self.actions, self.yaw
        out = [Command(kind, vec[i], float(yaw[i]), Action(int(act[i]))) for i in range(len(act))]
        if act.any():
            self.actions = np.zeros_like(act)
        return out


def _task_done(sim: Simulation) -> bool:
    """Judge the task now, as the next planner tick will (tasks judge idempotently)."""
    return bool(sim.task.update(sim.time, sim.state_array[:, :3]))


class SwarmEpisode:
    """Runs episodes of one scenario driven by action arrays (n, dim).

    Args:
        scenario: a validated scenario.
        config: validated environment options.
    """

    def __init__(self, scenario: Scenario, config: EnvConfig) -> None:
        self.scenario = scenario
        self.config = config
        self.sim: Simulation = Simulation(scenario, seed=scenario.seed, record=config.record)
        self._pristine = True  # self.sim is fresh (not stepped): a reset with its seed may use it
        self.n = self.sim.n
        self.n_ranges = int(self.sim.ranges.shape[1])  # (n, r) m, readings of the last planner tick
        sensor = self.sim.range_sensor
        range_bound = float(sensor.fan.range_m) if self.n_ranges and sensor is not None else RANGE_BOUND
        self.mapper = ActionMapper(self.sim, config)
        self.builder = ObservationBuilder(
            self.sim,
            neighbours=config.neighbours,
            boxes=config.boxes,
            slots=config.slots,
            points=config.points,
            ranges=self.n_ranges,
            range_bound=range_bound,
        )
        self.layout: ObservationLayout = self.builder.layout
        self.done = False
        self.steps = 0
        self.returns = np.zeros(self.n)
        self._start()

    # ------------------------------------------------------------------ set-up
    def _period(self) -> int:
        sim, period = self.sim, StepPeriod(self.config.period)
        if period is StepPeriod.PLANNER:
            return int(sim.planner_every)
        if period is StepPeriod.CONTROL:
            return int(sim.control_every)
        return 1

    def _start(self) -> None:
        sim = self.sim
        self.period_steps = self._period()
        self.dt = self.period_steps * sim.dt
        self.bridge: ActionBridge | None = None
        rotor = self.mapper.type is ActionType.ROTOR_SPEED
        if self.mapper.gripper or (sim.avoidance_layer is not None and not rotor):
            self.bridge = ActionBridge(self.n, sim.shaper.yaw)
            sim.planner = self.bridge
            sim.agent_planners = None
        elif rotor:
            sim.set_targets(sim.state_array[:, :3].copy())  # the scenario's planner stays idle
        self._camera: Any = None
        self.rewards = RewardTracker(sim, self.config.rewards)
        self.targets = self._targets()
        self.rewards.start(self.targets, sim.state_array[:, :3])
        self.done = False
        self.steps = 0
        self.returns = np.zeros(self.n)

    def reset(self, seed: int) -> NDArray[np.float32]:
        """Start a new episode of the scenario run with ``seed``; returns the observations (n, dim)."""
        if not (self._pristine and self.sim.seed == int(seed)):
            self.sim.close()
            self.sim = Simulation(self.scenario, seed=int(seed), record=self.config.record)
        self._pristine = False
        self._start()
        return self.observe()

    # ------------------------------------------------------------------- steps
    def _targets(self) -> NDArray[np.float64] | None:
        """(n, 3) m, the set-points active now (timed set-point tasks), else None."""
        shown = set_points_of(self.sim.task.view(self.sim.time))
        return shown.targets if shown is not None and len(shown.targets) == self.n else None

    def observe(self) -> NDArray[np.float32]:
        """Observation rows (n, dim) of every agent now."""
        return self.builder.build(self.sim, self.targets)

    def _apply(self, actions: NDArray[Any]) -> None:
        sim, mapper = self.sim, self.mapper
        cmd, grip = mapper.to_physical(np.asarray(actions).reshape(self.n, mapper.dim))
        kind = mapper.type
        if kind is ActionType.ROTOR_SPEED:
            sim.set_open_loop(cmd)
            if self.bridge is not None:
                self.bridge.set(CommandKind.HOLD, None, grip)
        elif self.bridge is not None:
            self.bridge.set(CommandKind.VELOCITY if kind is ActionType.VELOCITY else CommandKind.POSITION, cmd, grip)
        else:
            sim.set_targets(cmd, velocities=kind is ActionType.VELOCITY)

    def _close_if_due(self) -> None:
        """On a planner tick: when the task is done or the time is up, run that tick now (it ends the run
        before any physics step), so that this step reports the end."""
        sim = self.sim
        if sim.exit_status is not ExitStatus.RUNNING or sim.step_count % sim.planner_every:
            return
        if sim.time >= sim.time_limit - 1e-9 or _task_done(sim):
            if self.bridge is not None:
                self.bridge.set(self.bridge.kind, None, None)  # no task action at the closing tick
            sim.step(1)

    def step(self, actions: NDArray[Any]) -> tuple[NDArray[np.float32], StepOutcome, bool, bool]:
        """Apply ``actions`` (n, dim), advance one period; returns observations, outcome, terminated, truncated."""
        if self.done:
            raise RuntimeError("the episode has ended; call reset() first")
        sim = self.sim
        self._apply(actions)
        t0 = sim.time
        sim.step(self.period_steps)
        self._close_if_due()
        sim.task.refresh()
        status = sim.exit_status
        self.targets = self._targets()
        outcome = self.rewards.end(sim, sim.time - t0, status is ExitStatus.COMPLETED, self.targets)
        terminated = status in TERMINAL
        truncated = status in (ExitStatus.TIMEOUT, ExitStatus.STALLED)
        self.done = terminated or truncated
        self.steps += 1
        self.returns += outcome.rewards
        return self.observe(), outcome, terminated, truncated

    # ----------------------------------------------------------------- metrics
    def running_metrics(self) -> dict[str, Any]:
        """Cheap metrics of the episode so far (status, time, collision counts, task progress); once the
        episode has ended, the run's full metrics (what ``pybullet-swarm run`` writes to ``metrics.json``)."""
        sim = self.sim
        if self.done:
            return sim.metrics()
        contacts = sim.contacts
        m = {
            "exit_status": sim.exit_status.value,
            "sim_time_s": round(sim.time, 9),
            "collisions": dict(contacts.counts),
            "collision_time_s": dict(contacts.time_s),
        }
        m.update(self.rewards.progress())
        return m

    def render(self) -> NDArray[np.uint8]:
        """An RGB frame (height, width, 3) of the arena now, from the DIRECT-mode software renderer."""
        from pybullet_swarm.experiment.video import camera_for_arena, render_frame

        sim = self.sim
        if self._camera is None:  # one camera per episode, framing the flight volume as the run's video does
            height = sim.task.framing().height
            if height is None:
                height = max(1.0, float(np.max(sim.starts[:, 2])) + 0.5)
                targets = self._targets()
                if targets is not None:
                    height = max(height, float(np.max(targets[:, 2])) + 0.3)
            self._camera = camera_for_arena(self.scenario.arena.size, height)
        w, h = self.config.render_size
        return render_frame(sim.world, self._camera, (w, h))

    def close(self) -> None:
        """Release the simulation (idempotent)."""
        self.sim.close()
