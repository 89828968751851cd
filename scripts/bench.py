#!/usr/bin/env python3
"""Benchmark: N cf2x agents hovering with the full stack, against the bare floor of the same bodies.

Full stack: attitude loop, mixer and motors at the physics rate (240 Hz), position loop at
48 Hz, planner/task ticks, contacts read every physics step, recording on. Floor: the same
Bullet bodies with only the state reads, the two wrench calls per drone and the physics step.

    python scripts/bench.py --agents 1,5,50,100,200 --sim-seconds 10 --json bench.json

Full stack and floor are measured alternately (``--repeats``) on the same bodies and the best
of each is kept.

``--env`` measures the learning interface instead: environment steps per second of
``SwarmParallelEnv`` (velocity actions, one step per ``--env-period``) against the plain
``Simulation`` stepped by the same period, for 1, 5 and 50 agents by default (needs the ``rl`` extra):

    python scripts/bench.py --env --sim-seconds 10 --json bench_env.json
 Prints one row per N and writes a JSON list of objects with at least ``agents`` and
``real_time_factor``. Figures depend on the machine; nothing here is asserted.

``--task construction`` (or ``route``) measures the task layer: each bundled scenario of the task
(default ``construction`` with 5 agents and ``construction_large`` with 50 agents and 100 boxes;
``flocking`` for the route task) runs with ``--planner``/``--avoidance`` (default stigmergy + orca
for construction, the scenario's own for route) and is measured side by side, in one run, with
the hover full stack and the bare floor of the same agent count and vehicle:

    python scripts/bench.py --task construction --sim-seconds 30 --json bench_construction.json
    python scripts/bench.py --task construction --scenario construction_large --agents 50

Each task row gives the real-time factor, microseconds per agent-step and the share of the wall
time spent in Bullet's ``stepSimulation`` (the ``World.step`` call, timed), for the task, the
hover full stack and (share only) the floor. The task runs one trajectory (after 1 s of warm-up),
cut into ``--repeats`` parts that alternate with the hover and floor measurements.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from pybullet_swarm.experiment.scenario import load_scenario
from pybullet_swarm.experiment.simulation import Simulation


#: the clock of every measurement: wall-clock time (default), or this process's CPU time with
#: ``--clock cpu`` (on a machine shared with other work, CPU time is what the process itself spent)
CLOCK = time.perf_counter


#: default scenarios, planner and avoidance layer of each task (None: the scenario's own)
TASKS: dict[str, tuple[tuple[str, ...], str | None, str | None]] = {
    "construction": (("construction", "construction_large"), "stigmergy", "orca"),
    "route": (("flocking",), None, None),
}


def hover_scenario(n: int, vehicle: str = "cf2x", sim_seconds: float = 100.0):
    """hover_swarm with n agents starting in the air at 1 m, holding position (time limit: enough
    for ``sim_seconds`` of measurement; the recorder's buffers are sized by it)."""
    return load_scenario(
        "hover_swarm",
        {
            "agents.count": n,
            "agents.vehicle": vehicle,
            "agents.spacing": 0.3,
            "task.time_limit_s": float(sim_seconds) + 10.0,
            "task.waypoints": [{"t_s": 0.0, "position": [0.0, 0.0, 0.0]}],
            "task.hold_s": 1e4,
        },
    )


class StepTimer:
    """Wall-clock seconds spent in ``World.step`` (Bullet's ``stepSimulation``) of one simulation."""

    def __init__(self, sim: Simulation) -> None:
        self.seconds = 0.0
        step = sim.world.step
        clock = CLOCK

        def timed() -> None:
            t0 = clock()
            step()
            self.seconds += clock() - t0

        sim.world.step = timed  # type: ignore[method-assign]  # an instance attribute: Simulation.step looks it up


def start_hovering(sim: Simulation) -> None:
    """Lift every agent to 1 m with its rotors at hover speed, so the timing sees steady hover."""
    w = sim.params.hover_rotor_speed(sim.scenario.sim.gravity)
    for i in range(sim.n):
        p = sim.starts[i]
        sim.world.reset_agent(i, [p[0], p[1], 1.0])
    sim.world.read_agent_states(sim.state_array)
    sim.shaper.reset(sim.state_array[:, :3])
    sim.set_targets(sim.state_array[:, :3].copy())
    sim.controller.rotor_speeds[:] = w
    sim.controller.rotor_commands[:] = w


def bench_full(sim: Simulation, sim_seconds: float) -> float:
    """Wall-clock seconds for ``sim_seconds`` of the full stack."""
    steps = int(round(sim_seconds * sim.physics_hz))
    t0 = CLOCK()
    sim.step(steps)
    wall = CLOCK() - t0
    if sim.exit_status.value != "running":
        raise RuntimeError(f"benchmark run ended early: {sim.exit_status.value}")
    return wall


def bench_floor(sim: Simulation, sim_seconds: float, *, timed: bool = False) -> Any:
    """Wall-clock seconds of the bare floor on the same World and bodies (one force and one torque
    call, two state reads per drone per step, and the physics step); with ``timed`` also the seconds
    spent in the physics step."""
    import pybullet as pb

    world = sim.world
    cid = world._cid  # the benchmark measures the World's own client, on purpose
    bodies = list(world.agent_bodies)
    gp, gv, af, at, st = (
        pb.getBasePositionAndOrientation,
        pb.getBaseVelocity,
        pb.applyExternalForce,
        pb.applyExternalTorque,
        pb.stepSimulation,
    )
    wf = pb.WORLD_FRAME
    f = [0.0, 0.0, sim.params.mass * sim.scenario.sim.gravity]
    zero = [0.0, 0.0, 0.0]
    steps = int(round(sim_seconds * sim.physics_hz))
    clock = CLOCK
    in_step = 0.0
    t0 = clock()
    for _ in range(steps):
        for b in bodies:
            pos, _q = gp(b, cid)
            gv(b, cid)
            af(b, -1, f, pos, wf, cid)
            at(b, -1, zero, wf, cid)
        if timed:
            t1 = clock()
            st(cid)
            in_step += clock() - t1
        else:
            st(cid)
    wall = clock() - t0
    return (wall, in_step) if timed else wall


def bench_task(sim: Simulation, sim_seconds: float, timer: StepTimer) -> tuple[float, float, float]:
    """Run the task for ``sim_seconds`` (less when it ends first): wall seconds, simulated seconds
    advanced and seconds spent in ``stepSimulation``."""
    k0, s0 = sim.step_count, timer.seconds
    t0 = CLOCK()
    sim.step(int(round(sim_seconds * sim.physics_hz)))
    wall = CLOCK() - t0
    return wall, (sim.step_count - k0) / sim.physics_hz, timer.seconds - s0


def task_scenario(name: str, agents: int | None, sim_seconds: float, overrides: Sequence[str] = ()):
    """The bundled scenario ``name`` with ``overrides`` (``key.path=value``), a time limit just past
    the measurement (and ``agents``)."""
    from pybullet_swarm.experiment.scenario import parse_override

    data: dict = dict(parse_override(o) for o in overrides)
    data["task.time_limit_s"] = float(sim_seconds) + 5.0
    if agents is not None:
        data["agents.count"] = agents
    return load_scenario(name, data)


def bench_tasks(
    task: str,
    scenarios: list[str],
    agents: list[int | None],
    sim_seconds: float,
    repeats: int,
    planner: str | None,
    avoidance: str | None,
    overrides: Sequence[str] = (),
) -> list[dict]:
    """One row per scenario and agent count: the task against hover and floor of as many agents."""
    rows = []
    head = (
        f"{'scenario':<20} {'N':>5} {'boxes':>5} {'task RTF':>9} {'us/a-s':>7} {'step %':>7} "
        f"{'hover RTF':>10} {'us/a-s':>7} {'step %':>7} {'floor RTF':>10} {'us/a-s':>7} {'step %':>7} "
        f"{'task/hover':>10}"
    )
    print(head)
    for name in scenarios:
        for n_req in agents:
            scenario = task_scenario(name, n_req, sim_seconds + 1.0, overrides)
            sim = Simulation(scenario, planner=planner, avoidance=avoidance)
            n = sim.n
            hover = Simulation(hover_scenario(n, scenario.agents.vehicle, sim_seconds))
            task_timer, hover_timer = StepTimer(sim), StepTimer(hover)
            start_hovering(hover)
            sim.step(sim.physics_hz)  # warm-up: one simulated second (kernels loaded, caches hot)
            hover.step(hover.physics_hz // 2)
            part = sim_seconds / max(repeats, 1)
            t_wall = t_sim = t_step = 0.0
            hovers, floors = [], []
            for _ in range(max(repeats, 1)):  # alternate, so all three see the same machine state
                if sim.exit_status.value == "running":
                    w, s, st = bench_task(sim, part, task_timer)
                    t_wall, t_sim, t_step = t_wall + w, t_sim + s, t_step + st
                s0 = hover_timer.seconds
                hovers.append((bench_full(hover, part), hover_timer.seconds - s0))
                floors.append(bench_floor(hover, part, timed=True))
            h_wall, h_step = min(hovers)
            f_wall, f_step = min(floors)
            h_steps = int(round(part * hover.physics_hz))
            task_steps = int(round(t_sim * sim.physics_hz))
            row = {
                "task": task,
                "scenario": name,
                "planner": sim.planner_name,
                "avoidance": sim.avoidance_name,
                "vehicle": scenario.agents.vehicle,
                "collisions": scenario.collisions,
                "overrides": list(overrides),
                "agents": n,
                "boxes": len(getattr(scenario.task, "boxes", []) or []),
                "sim_seconds": round(t_sim, 6),
                "exit_status": sim.exit_status.value,
                "physics_hz": sim.physics_hz,
                "real_time_factor": t_sim / t_wall,
                "us_per_agent_step": t_wall / (task_steps * n) * 1e6,
                "step_simulation_share": t_step / t_wall,
                "hover_real_time_factor": part / h_wall,
                "hover_us_per_agent_step": h_wall / (h_steps * n) * 1e6,
                "hover_step_simulation_share": h_step / h_wall,
                "floor_real_time_factor": part / f_wall,
                "floor_us_per_agent_step": f_wall / (h_steps * n) * 1e6,
                "floor_step_simulation_share": f_step / f_wall,
            }
            row["ratio_to_hover"] = row["real_time_factor"] / row["hover_real_time_factor"]
            sim.close()
            hover.close()
            rows.append(row)
            print(
                f"{name:<20} {n:>5} {row['boxes']:>5} {row['real_time_factor']:>9.1f} "
                f"{row['us_per_agent_step']:>7.2f} {100 * row['step_simulation_share']:>6.0f}% "
                f"{row['hover_real_time_factor']:>10.1f} {row['hover_us_per_agent_step']:>7.2f} "
                f"{100 * row['hover_step_simulation_share']:>6.0f}% {row['floor_real_time_factor']:>10.1f} "
                f"{row['floor_us_per_agent_step']:>7.2f} {100 * row['floor_step_simulation_share']:>6.0f}% "
                f"{row['ratio_to_hover']:>10.2f}",
                flush=True,
            )
    return rows


def bench_env(counts: list[int], sim_seconds: float, repeats: int, period: str) -> list[dict]:
    """Environment steps per second of ``SwarmParallelEnv`` against the plain simulation, per agent count.

    Both hover the same agents with the full stack and recording on; the environment adds its
    action mapping, observations of every agent, rewards and infos at each step.
    """
    from pybullet_swarm.envs import SwarmParallelEnv

    rows = []
    print(f"{'N':>5} {'period s':>9} {'env steps/s':>12} {'plain steps/s':>14} {'env/plain':>10} {'env RTF':>8}")
    for n in counts:
        scenario = hover_scenario(n)
        env = SwarmParallelEnv(scenario, action_type="velocity", period=period)
        env.reset(seed=scenario.seed)
        start_hovering(env.sim)
        actions = {a: np.zeros(3, dtype=np.float32) for a in env.agents}
        plain = Simulation(scenario)
        start_hovering(plain)
        chunk = int(round(env.dt * plain.physics_hz))  # physics steps per environment step
        steps = max(1, int(round(sim_seconds / max(repeats, 1) / env.dt)))

        def run_env() -> float:
            t0 = CLOCK()
            for _ in range(steps):
                env.step(actions)
            return CLOCK() - t0

        def run_plain() -> float:
            t0 = CLOCK()
            for _ in range(steps):
                plain.step(chunk)
            return CLOCK() - t0

        warm = max(1, int(round(0.5 / env.dt)))  # warm-up: compiled kernels loaded, caches hot
        for _ in range(warm):
            env.step(actions)
            plain.step(chunk)
        env_walls, plain_walls = [], []
        for _ in range(max(repeats, 1)):  # alternate, so both see the same machine state
            env_walls.append(run_env())
            plain_walls.append(run_plain())
        if env.sim.exit_status.value != "running" or plain.exit_status.value != "running":
            raise RuntimeError("benchmark run ended early")
        env_rate, plain_rate = steps / min(env_walls), steps / min(plain_walls)
        row = {
            "mode": "env",
            "agents": n,
            "period": period,
            "period_s": env.dt,
            "env_steps_per_s": env_rate,
            "plain_steps_per_s": plain_rate,
            "ratio_to_plain": env_rate / plain_rate,
            "env_real_time_factor": env_rate * env.dt,
            "real_time_factor": plain_rate * env.dt,
        }
        env.close()
        plain.close()
        rows.append(row)
        print(
            f"{n:>5} {env.dt:>9.4f} {env_rate:>12.1f} {plain_rate:>14.1f} {row['ratio_to_plain']:>10.2f} "
            f"{row['env_real_time_factor']:>8.1f}",
            flush=True,
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--agents",
        default="1,5,50,100,200",
        help="comma-separated agent counts (with --task: override each scenario's count; default its own)",
    )
    ap.add_argument(
        "--sim-seconds",
        type=float,
        default=None,
        help="simulated seconds per measurement (default 10; with --task 30)",
    )
    ap.add_argument(
        "--task",
        choices=sorted(TASKS),
        default=None,
        help="measure a task's scenarios against hover and floor of the same agent count",
    )
    ap.add_argument(
        "--scenario",
        default=None,
        help="with --task: comma-separated bundled scenarios (default: the task's, see TASKS)",
    )
    ap.add_argument("--planner", default=None, help="with --task: planner (default: the task's)")
    ap.add_argument("--avoidance", default=None, help="with --task: avoidance layer (default: the task's)")
    ap.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY.PATH=VALUE",
        help="with --task: override a field of every task scenario (repeatable), e.g. collisions=physical",
    )
    ap.add_argument(
        "--repeats",
        type=int,
        default=3,
        help="alternate full and floor measurements this many times; the best of each is kept",
    )
    ap.add_argument("--json", type=Path, default=None, metavar="FILE", help="write the results as JSON")
    ap.add_argument(
        "--clock",
        choices=("wall", "cpu"),
        default="wall",
        help="time with the wall clock (default) or this process's CPU time (a machine shared with other work)",
    )
    ap.add_argument(
        "--env",
        action="store_true",
        help="environment steps per second of SwarmParallelEnv vs the plain simulation (default agents 1,5,50)",
    )
    ap.add_argument(
        "--env-period",
        default="planner",
        choices=("planner", "control", "physics"),
        help="simulated time of one environment step in --env mode",
    )
    args = ap.parse_args(argv)
    global CLOCK
    CLOCK = time.process_time if args.clock == "cpu" else time.perf_counter
    meta = {
        "clock": args.clock,
        "load_average": [round(x, 2) for x in os.getloadavg()],
        "python": sys.version.split()[0],
        "machine": platform.machine(),
        "numpy": np.__version__,
        "cpus": os.cpu_count(),
    }
    if args.task is not None:
        names, planner, avoidance = TASKS[args.task]
        scenarios = args.scenario.split(",") if args.scenario else list(names)
        counts_t: list[int | None] = (
            [None] if args.agents == ap.get_default("agents") else [int(x) for x in args.agents.split(",") if x.strip()]
        )
        rows = bench_tasks(
            args.task,
            scenarios,
            counts_t,
            args.sim_seconds or 30.0,
            args.repeats,
            args.planner or planner,
            args.avoidance or avoidance,
            args.overrides,
        )
        if args.json is not None:
            args.json.write_text(json.dumps([{**r, **meta} for r in rows], indent=2) + "\n")
        return 0
    if args.sim_seconds is None:
        args.sim_seconds = 10.0
    if args.env and args.agents == ap.get_default("agents"):
        args.agents = "1,5,50"
    counts = [int(x) for x in args.agents.split(",") if x.strip()]
    if args.env:
        rows = bench_env(counts, args.sim_seconds, args.repeats, args.env_period)
        if args.json is not None:
            args.json.write_text(json.dumps([{**r, **meta} for r in rows], indent=2) + "\n")
        return 0
    rows = []
    print(f"{'N':>5} {'full RTF':>10} {'us/drone-step':>14} {'floor RTF':>10} {'floor us/d-s':>13} {'full/floor':>10}")
    for n in counts:
        sim = Simulation(hover_scenario(n, sim_seconds=args.sim_seconds))
        start_hovering(sim)
        sim.step(sim.physics_hz // 2)  # warm-up: compiled kernels loaded, caches hot
        part = args.sim_seconds / max(args.repeats, 1)
        walls, floors = [], []
        for _ in range(max(args.repeats, 1)):  # alternate, so both see the same machine state
            walls.append(bench_full(sim, part))
            floors.append(bench_floor(sim, part))
        wall = min(walls) * args.repeats
        floor = min(floors) * args.repeats
        steps = int(round(args.sim_seconds * sim.physics_hz))
        sim.close()
        row = {
            "agents": n,
            "sim_seconds": args.sim_seconds,
            "physics_hz": sim.physics_hz,
            "real_time_factor": args.sim_seconds / wall,
            "us_per_drone_step": wall / (steps * n) * 1e6,
            "floor_real_time_factor": args.sim_seconds / floor,
            "floor_us_per_drone_step": floor / (steps * n) * 1e6,
            "ratio_to_floor": floor / wall,
        }
        rows.append(row)
        print(
            f"{n:>5} {row['real_time_factor']:>10.1f} {row['us_per_drone_step']:>14.2f} "
            f"{row['floor_real_time_factor']:>10.1f} {row['floor_us_per_drone_step']:>13.2f} "
            f"{row['ratio_to_floor']:>10.2f}",
            flush=True,
        )
    if args.json is not None:
        for r in rows:
            r.update(meta)
        args.json.write_text(json.dumps(rows, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
