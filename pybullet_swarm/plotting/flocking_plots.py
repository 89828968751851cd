"""Figures of a route run (flocking or formation): fitness over time, top view of the course, formation error."""

from __future__ import annotations

from pathlib import Path
from collections.abc import Mapping
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon, Rectangle
from numpy.typing import ArrayLike, NDArray

from pybullet_swarm.plotting.common import save_figure


def _pass_lines(ax: Axes, pass_times: list[float | None] | None) -> None:
    for k, t in enumerate(pass_times or []):
        if t is not None:
            ax.axvline(float(t), color="0.5", lw=0.8, ls=":")
            ax.annotate(
                f"wp {k}",
                (float(t), 1.0),
                xycoords=("data", "axes fraction"),
                xytext=(2, -10),
                textcoords="offset points",
                fontsize=7,
                color="0.35",
            )


def plot_fitness(
    t: ArrayLike,
    series: dict[str, NDArray[np.float64]],
    path: Path | str,
    *,
    pass_times: list[float | None] | None = None,
    title: str = "flocking fitness",
) -> Path:
    """Fitness and its components over time.

    Args:
        t: (T,) s.
        series: per-step arrays (T,) by name, ``fitness`` among them (e.g. ``o``, ``d``, ``v``).
        path: PNG file.
        pass_times: s, when each waypoint was passed (dotted lines).
    """
    t = np.asarray(t, dtype=float)
    fig = Figure(figsize=(9, 5), layout="constrained")
    ax = fig.subplots()
    for name, x in series.items():
        if name in ("fitness", "error"):
            continue
        ax.plot(t, x, lw=1.0, alpha=0.8, label=name)
    ax.plot(t, series["fitness"], lw=2.0, color="k", label=f"fitness (mean {np.mean(series['fitness']):.3f})")
    _pass_lines(ax, pass_times)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("metric [-]")
    ax.set_ylim(-0.02, max(1.05, float(np.nanmax([np.max(x) for x in series.values()]) + 0.05)))
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    return save_figure(fig, path)


def _draw_obstacle(ax: Axes, ob: dict[str, Any]) -> None:
    pos, size = ob["position"], ob["size"]
    style = dict(facecolor="0.55", edgecolor="k", lw=0.8, zorder=4)
    if ob["shape"] == "cylinder":
        ax.add_patch(Circle((pos[0], pos[1]), size[0], **style))
        return
    yaw = np.radians(ob.get("yaw_deg", 0.0))
    hx, hy = 0.5 * size[0], 0.5 * size[1]
    corners = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    c, s = np.cos(yaw), np.sin(yaw)
    ax.add_patch(Polygon(corners @ np.array([[c, s], [-s, c]]) + np.asarray(pos[:2]), closed=True, **style))


def plot_course(
    positions: ArrayLike,
    path: Path | str,
    *,
    route: ArrayLike,
    obstacles: list[dict[str, Any]],
    arena_size: ArrayLike | None = None,
    pass_radius: float | None = None,
    collisions: list[tuple[float, float]] | None = None,
) -> Path:
    """Top view of the course: arena, obstacles, waypoints (with their pass radius) and every flown path.

    Args:
        positions: (T, n, 3) m, recorded positions.
        path: PNG file.
        route: (W, 3) m, waypoints.
        obstacles: the scenario's ``arena.obstacles`` entries.
        arena_size: (2,) m.
        pass_radius: m, drawn around each waypoint.
        collisions: (x, y) m of contact events (red crosses).
    """
    p = np.asarray(positions, dtype=float)
    w = np.asarray(route, dtype=float).reshape(-1, 3)
    fig = Figure(figsize=(9, 6), layout="constrained")
    ax = fig.subplots()
    if arena_size is not None:
        lx, ly = (float(v) for v in np.asarray(arena_size, dtype=float)[:2])
        ax.add_patch(Rectangle((0, 0), lx, ly, fill=False, ec="k", lw=1.0))
        ax.set_xlim(-0.1, lx + 0.1)
        ax.set_ylim(-0.1, ly + 0.1)
    for ob in obstacles:
        _draw_obstacle(ax, ob)
    for i in range(p.shape[1]):
        ax.plot(p[:, i, 0], p[:, i, 1], lw=0.9, color=f"C{i % 10}", zorder=3)
        ax.plot(p[0, i, 0], p[0, i, 1], "o", ms=4, color=f"C{i % 10}", zorder=5)
    c = p.mean(axis=1)
    ax.plot(c[:, 0], c[:, 1], "k--", lw=1.2, label="centroid", zorder=5)
    ax.plot(w[:, 0], w[:, 1], "k*", ms=12, zorder=6, label="waypoints")
    for k, q in enumerate(w):
        if pass_radius:
            ax.add_patch(Circle((q[0], q[1]), pass_radius, fill=False, ls=":", ec="k", zorder=6))
        ax.annotate(str(k), (q[0], q[1]), xytext=(6, 6), textcoords="offset points", fontsize=9)
    if collisions:
        xy = np.asarray(collisions, dtype=float).reshape(-1, 2)
        ax.plot(xy[:, 0], xy[:, 1], "rx", ms=9, mew=2, zorder=7, label="contact")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("course: obstacles, waypoints and flown paths (top view)")
    ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.25)
    return save_figure(fig, path)


def plot_formation_error(
    t: ArrayLike, errors: ArrayLike, path: Path | str, *, pass_times: list[float | None] | None = None
) -> Path:
    """Slot error of every agent (thin) and their mean (thick) over time.

    Args:
        t: (T,) s.
        errors: (T, n) m, per-agent slot errors.
        path: PNG file.
    """
    t = np.asarray(t, dtype=float)
    e = np.asarray(errors, dtype=float)
    fig = Figure(figsize=(9, 4.5), layout="constrained")
    ax = fig.subplots()
    for i in range(e.shape[1]):
        ax.plot(t, e[:, i], lw=0.8, alpha=0.7, color=f"C{i % 10}", label=f"agent {i}")
    ax.plot(t, e.mean(axis=1), lw=2.0, color="k", label="mean")
    _pass_lines(ax, pass_times)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("slot error [m]")
    ax.set_title("formation error")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=3, loc="upper right")
    return save_figure(fig, path)


def plot_route_run(
    ts: Any, out_dir: Path, metrics: dict[str, Any], scenario: Mapping[str, Any], events: list[Any]
) -> list[Path]:
    """Every route figure of a run from its saved results (time series, metrics, scenario, events)."""
    from pybullet_swarm.metrics.flocking import route_fitness_series, slot_errors
    from pybullet_swarm.tasks.route import FormationSpec

    task = scenario["task"]
    route = np.asarray(task["waypoints"], dtype=float)
    pass_times = metrics.get("waypoint_times_s") or [None] * len(route)
    lim = (scenario.get("limits") or {}).get("velocity")
    v_axis = np.broadcast_to(np.asarray(lim if lim is not None else 1.0, dtype=float), (3,))
    slots = FormationSpec(**task["formation"]).slot_array() if task.get("formation") else None
    pos = ts.positions.astype(float)
    s = route_fitness_series(ts.t, pos, ts.velocities.astype(float), route, pass_times, v_axis, slots)
    out_dir = Path(out_dir)
    files = [plot_fitness(ts.t, s["flocking"], out_dir / "fitness.png", pass_times=pass_times)]
    hits = []
    names = {f"agent{i}": i for i in range(pos.shape[1])}
    for e in events:
        kind = getattr(e, "kind", None)
        if kind in ("agent_obstacle", "agent_agent"):
            i = names.get(e.a, names.get(e.b))
            if i is not None:
                k = int(np.argmin(np.abs(ts.t - e.time_s)))
                hits.append((pos[k, i, 0], pos[k, i, 1]))
    files.append(
        plot_course(
            pos,
            out_dir / "course.png",
            route=route,
            obstacles=list(scenario.get("arena", {}).get("obstacles", [])),
            arena_size=scenario.get("arena", {}).get("size"),
            pass_radius=task.get("pass_radius"),
            collisions=hits,
        )
    )
    if slots is not None and s["formation"] is not None:
        files.append(
            plot_fitness(
                ts.t,
                {k: v for k, v in s["formation"].items()},
                out_dir / "formation_fitness.png",
                pass_times=pass_times,
                title="formation fitness",
            )
        )
        files.append(
            plot_formation_error(ts.t, slot_errors(pos, slots), out_dir / "formation_error.png", pass_times=pass_times)
        )
    return files


#: order parameters drawn over time (``plot_order_parameters``), each in [0, 1]
ORDER_CURVES = ("velocity_correlation", "order", "union", "connectivity", "safety")


def plot_order_parameters(
    t: ArrayLike, series: Mapping[str, NDArray[np.float64]], path: Path | str, *, warmup_s: float = 0.0
) -> Path:
    """The flock's order parameters (T,) over time (T,) s, the warm-up shaded."""
    t = np.asarray(t, dtype=float)
    fig = Figure(figsize=(9, 4.5), layout="constrained")
    ax = fig.subplots()
    for name in ORDER_CURVES:
        ax.plot(t, series[name], lw=1.0, label=name)
    ax.axvspan(float(t[0]) if t.size else 0.0, warmup_s, color="0.9", label="warm-up")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("order parameter [-]")
    ax.set_ylim(-0.05, 1.05)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title("order parameters of the flock")
    return save_figure(fig, path)


def plot_min_distance(t: ArrayLike, min_distance: ArrayLike, r_coll: float, path: Path | str) -> Path:
    """The closest pair's distance (T,) m over time (T,) s, with the collision distance ``r_coll`` m."""
    t = np.asarray(t, dtype=float)
    d = np.asarray(min_distance, dtype=float)
    fig = Figure(figsize=(9, 4), layout="constrained")
    ax = fig.subplots()
    ax.plot(t, d, lw=1.0, color="C0", label=f"closest pair (min {np.min(d):.2f} m)")
    ax.axhline(r_coll, color="C3", ls="--", lw=1.2, label=f"r_coll = {r_coll:g} m")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("distance [m]")
    ax.set_ylim(0.0, max(float(np.max(d)) * 1.05, 2.0 * r_coll))
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("minimum pair distance")
    return save_figure(fig, path)


def plot_flock_trajectories(
    positions: ArrayLike, path: Path | str, *, arena_size: ArrayLike, obstacles: list[dict[str, Any]]
) -> Path:
    """Top view of the paths (T, n, 3) m inside the walls of the arena (2,) m, pillars drawn, last position dotted."""
    p = np.asarray(positions, dtype=float)
    lx, ly = (float(v) for v in np.asarray(arena_size, dtype=float)[:2])
    fig = Figure(figsize=(7, 7), layout="constrained")
    ax = fig.subplots()
    ax.add_patch(Rectangle((0, 0), lx, ly, fill=False, ec="k", lw=2.0))
    for ob in obstacles:
        _draw_obstacle(ax, ob)
    for i in range(p.shape[1]):
        ax.plot(p[:, i, 0], p[:, i, 1], lw=0.6, alpha=0.7, color=f"C{i % 10}")
        ax.plot(p[-1, i, 0], p[-1, i, 1], "o", ms=3, color=f"C{i % 10}")
    ax.set_xlim(-0.05 * lx, 1.05 * lx)
    ax.set_ylim(-0.05 * ly, 1.05 * ly)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("trajectories and walls")
    return save_figure(fig, path)


#: s, the trajectories figure shows this last stretch of the run
TRAJECTORY_WINDOW_S = 60.0


def plot_flock_run(ts: Any, out_dir: Path, scenario: Mapping[str, Any]) -> list[Path]:
    """Every flock figure of a run from its saved results: order parameters, closest pair, trajectories."""
    from pybullet_swarm.metrics.flock import order_series

    task = scenario["task"]
    arena = scenario.get("arena", {})
    size = arena.get("size", [3.0, 1.0])
    t = np.asarray(ts.t, dtype=float)
    pos = ts.positions.astype(float)
    s = order_series(
        pos,
        ts.velocities.astype(float),
        arena_size=size,
        r_coll=float(task["r_coll"]),
        connection_range=float(task["connection_range_m"]),
    )
    out_dir = Path(out_dir)
    last = t >= t[-1] - TRAJECTORY_WINDOW_S
    return [
        plot_order_parameters(t, s, out_dir / "order_parameters.png", warmup_s=float(task.get("warmup_s", 0.0))),
        plot_min_distance(t, s["min_distance_m"], float(task["r_coll"]), out_dir / "min_distance.png"),
        plot_flock_trajectories(
            pos[last], out_dir / "trajectories.png", arena_size=size, obstacles=list(arena.get("obstacles", []))
        ),
    ]
