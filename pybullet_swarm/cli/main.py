"""``pybullet-swarm``: run, check, layout, design, plot, sweep, compare, replay, report, list, benchmark (and
the subcommands later layers add).

Exit codes: 0 when the command did its work (a simulation's outcome is in ``exit_status``),
2 for bad input (one line on stderr naming the file, the field and the expectation), 1 for an
internal error.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import traceback
from pathlib import Path
from typing import Any, Sequence

from pybullet_swarm.cli import add_overrides_option
from pybullet_swarm.errors import ConfigError

PROG = "pybullet-swarm"


class _Parser(argparse.ArgumentParser):
    """argparse whose usage errors are one line and exit 2, like every other bad input."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise ConfigError(" ".join(message.split()), source=self.prog)


def _fail(message: str, code: int) -> int:
    print(f"{PROG}: error: {' '.join(str(message).split())}", file=sys.stderr)
    return code


# ---------------------------------------------------------------------- run
def _add_run(sub: Any) -> None:
    p = sub.add_parser("run", help="run a scenario and write its run directory")
    p.add_argument("scenario", help="scenario YAML file or bundled name (see `list`)")
    p.add_argument("--planner", default=None, help="planner name (default: the scenario's)")
    p.add_argument("--avoidance", default=None, help="local avoidance layer (default: the scenario's)")
    p.add_argument("--seed", type=int, default=None, help="seed of the run (default: the scenario's)")
    p.add_argument(
        "--out", type=Path, default=None, help="run directory (default: runs/<name>-<planner>-s<seed>-<time>)"
    )
    add_overrides_option(p, "override a scenario field (repeatable), e.g. --set agents.count=20")
    p.add_argument(
        "-c",
        "--config",
        type=Path,
        default=None,
        metavar="FILE",
        help="override file of key.path: value lines (e.g. best.yaml of `tune`), applied before --set",
    )
    p.add_argument(
        "--gui",
        action="store_true",
        help="watch in the Bullet GUI: the arena framed, paced to real time (see --speed), overlays",
    )
    p.add_argument(
        "--video",
        action="store_true",
        help="after the run, render RUN_DIR/video.mp4 (GIF without an MP4 encoder): the replay of "
        "`replay RUN_DIR`, 3d view, 4x faster than real time (see --speed)",
    )
    p.add_argument(
        "--speed",
        type=_speed,
        default=None,
        metavar="X",
        help="--gui: simulated seconds per wall-clock second (default 1, real time); "
        "--video: simulated seconds per second of video (default 4)",
    )
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")
    p.set_defaults(func=_cmd_run)


def _format_metrics(m: dict[str, Any]) -> str:
    rows: list[tuple[str, str]] = []

    def add(prefix: str, value: Any) -> None:
        if isinstance(value, dict):
            if prefix == "path_length_m":
                rows.append((prefix, f"{value['total']:.3f}"))
                return
            for k2, v2 in value.items():
                add(f"{prefix}.{k2}", v2)
        elif not isinstance(value, list):  # per-agent lists are in metrics.json
            rows.append((prefix, _fmt(value)))

    for key, value in m.items():
        add(key, value)
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"  {k.ljust(width)}  {v}" for k, v in rows)


def _check_display() -> None:
    """Refuse ``--gui`` where no window can open (Linux without an X or Wayland display)."""
    import os

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ConfigError(
            "needs a display (DISPLAY is not set); run without --gui, or record one with --video", source="--gui"
        )


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return "-" if v is None else str(v)


def _cmd_run(args: argparse.Namespace) -> int:
    from pybullet_swarm.experiment.rundir import default_run_dir
    from pybullet_swarm.experiment.runner import run
    from pybullet_swarm.experiment.scenario import load_scenario, parse_override

    overrides: Any = args.overrides
    planner, avoidance = args.planner, args.avoidance
    if args.config is not None:
        from pybullet_swarm.tuning.outputs import read_overrides_file

        config = dict(read_overrides_file(args.config))
        # the file's planner and avoidance layer are choices, as --planner and --avoidance (which win)
        file_planner, file_avoidance = config.pop("planner.name", None), config.pop("avoidance", None)
        planner = planner if planner is not None else file_planner
        avoidance = avoidance if avoidance is not None else file_avoidance
        overrides = config | dict(parse_override(o) for o in args.overrides)
    if args.seed is not None and args.seed < 0:
        raise ConfigError(f"must be >= 0, got {args.seed}", source="--seed")
    scenario = load_scenario(args.scenario, overrides, planner=planner, avoidance=avoidance, seed=args.seed)
    if args.gui:
        _check_display()
    from pybullet_swarm.experiment.rundir import check_run_dir

    out = (
        check_run_dir(args.out, source="--out")
        if args.out is not None
        else default_run_dir(scenario.name, str(scenario.planner.name), scenario.seed)
    )
    result = run(
        scenario,
        out=out,
        gui=args.gui,
        plots=not args.no_plots,
        video=args.video,
        speed=args.speed,
        report=True,
        quiet=args.quiet,
    )
    if not args.quiet:
        print(
            f"{scenario.name}: {result.exit_status.value} after {result.metrics['sim_time_s']:.2f} s simulated "
            f"({result.metrics['real_time_factor'] or 0:.1f}x real time)"
        )
        print(_format_metrics(result.metrics))
        print(f"run directory: {result.run_dir}")
        if "video" in result.metrics:
            print(f"video: {Path(result.run_dir) / result.metrics['video']}")
        print(f"report: {Path(result.run_dir) / 'report.html'}")
    return 0


def _speed(text: str) -> float:
    """A positive finite number (a pace or a playback speed)."""
    import math

    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in px, both even and at least 64."""
    import re

    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    size = (int(m.group(1)), int(m.group(2))) if m else (0, 1)
    if min(size) < 64 or size[0] % 2 or size[1] % 2:
        raise argparse.ArgumentTypeError(
            f"expected WIDTHxHEIGHT in px, both even and >= 64 (e.g. 1280x720), got {text!r}"
        )
    return size


# ------------------------------------------------------------------- replay
#: the replay's cameras (``plotting.replay.View``; spelled out so that the parser imports no matplotlib)
REPLAY_VIEWS = ("top", "chase", "orbit", "3d")


def _add_replay(sub: Any) -> None:
    p = sub.add_parser("replay", help="render a video of a finished run from its saved results (no re-simulation)")
    p.add_argument("run_dir", type=Path, metavar="RUN_DIR")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="FILE",
        help="video file (default RUN_DIR/video.mp4; .gif when no MP4 encoder is installed)",
    )
    p.add_argument(
        "--view",
        choices=REPLAY_VIEWS,
        default="3d",
        help="top (orthographic, from above), chase (behind the swarm), orbit (circling the arena) "
        "or 3d (fixed, framing the arena; default)",
    )
    p.add_argument(
        "--speed", type=_speed, default=4.0, metavar="X", help="simulated seconds per second of video (default 4)"
    )
    p.add_argument("--size", type=_size, default=(1280, 720), metavar="WxH", help="frame size in px (default 1280x720)")
    p.add_argument(
        "--frame",
        type=float,
        default=None,
        metavar="T",
        help="write only the frame at simulated time T s, as a PNG (default --out: RUN_DIR/frame.png)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar, print nothing on success")
    p.set_defaults(func=_cmd_replay)


def _cmd_replay(args: argparse.Namespace) -> int:
    from pybullet_swarm.experiment.replay import render_replay, render_still

    from pybullet_swarm.experiment.results import check_saved_run
    from pybullet_swarm.experiment.rundir import check_output_dir

    if not (args.run_dir / "timeseries.npz").is_file():
        raise ConfigError("not a run directory (no timeseries.npz)", source=str(args.run_dir))
    if args.out is not None and args.out.is_dir():
        raise ConfigError(
            "is a directory; give a file name (.mp4, .gif or, with --frame, .png)", source=f"--out {args.out}"
        )
    check_output_dir(args.out.parent if args.out is not None else args.run_dir, source="--out" if args.out else None)
    check_saved_run(args.run_dir)  # every saved file is read and checked before the first frame
    if args.frame is not None:
        path = render_still(args.run_dir, args.frame, args.out, view=args.view, size=args.size)
    else:
        path = render_replay(args.run_dir, args.out, view=args.view, speed=args.speed, size=args.size, quiet=args.quiet)
    if not args.quiet:
        print(path)
    return 0


# ------------------------------------------------------------------- report
def _add_report(sub: Any) -> None:
    p = sub.add_parser("report", help="write report.html into a run or sweep directory (one self-contained page)")
    p.add_argument("directory", type=Path, metavar="RUN_DIR|SWEEP_DIR")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")
    p.set_defaults(func=_cmd_report)


def _cmd_report(args: argparse.Namespace) -> int:
    from pybullet_swarm.experiment.report import write_run_report
    from pybullet_swarm.experiment.results import is_sweep_dir

    from pybullet_swarm.experiment.results import check_saved_run
    from pybullet_swarm.experiment.rundir import check_output_dir

    if is_sweep_dir(args.directory):
        from pybullet_swarm.experiment.sweep import load_sweep
        from pybullet_swarm.experiment.sweep_report import write_sweep_report

        check_output_dir(args.directory)
        load_sweep(args.directory)  # runs.csv, sweep.json and summary.csv checked before the page is made
        if (args.directory / "summary.csv").is_file():
            from pybullet_swarm.experiment.results import read_summary_csv

            read_summary_csv(args.directory / "summary.csv")
        path = write_sweep_report(args.directory)
    elif (args.directory / "timeseries.npz").is_file() or (args.directory / "metrics.json").is_file():
        check_output_dir(args.directory)
        if (args.directory / "timeseries.npz").is_file():
            check_saved_run(args.directory)
        else:
            from pybullet_swarm.experiment.results import read_metrics

            read_metrics(args.directory)
        path = write_run_report(args.directory)
    else:
        raise ConfigError(
            "not a run directory (no timeseries.npz) nor a sweep directory (no runs.csv)", source=str(args.directory)
        )
    if not args.quiet:
        print(path)
    return 0


# -------------------------------------------------------------------- check
def _add_check(sub: Any) -> None:
    p = sub.add_parser("check", help="validate a scenario and print it resolved")
    p.add_argument("scenario")
    add_overrides_option(p)
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_cmd_check)


def _cmd_check(args: argparse.Namespace) -> int:
    import yaml

    from pybullet_swarm.experiment.scenario import load_scenario

    scenario = load_scenario(args.scenario, args.overrides)
    from pybullet_swarm.experiment.runner import build_run

    build_run(scenario)  # what a run refuses when it starts, check refuses too
    if not args.quiet:
        print(yaml.safe_dump(dict(scenario.data), sort_keys=False), end="")
    return 0


# ------------------------------------------------------------------- layout
def _add_layout(sub: Any) -> None:
    from pybullet_swarm.experiment.layouts import SHAPES

    p = sub.add_parser(
        "layout", help="write a random construction scenario (structure, depot, swarm, arena) drawn from a seed"
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the layout (and of the scenario)")
    p.add_argument(
        "--agents",
        type=_agents,
        default=None,
        metavar="N|LO:HI",
        help="swarm size 1..20, or the range it is drawn in (default: drawn in 1..20)",
    )
    p.add_argument(
        "--arena",
        type=float,
        nargs=2,
        default=None,
        metavar=("LX", "LY"),
        help="arena size in m (default: drawn in 2..6 x 1..3 m)",
    )
    p.add_argument(
        "--max-arena",
        type=float,
        nargs=2,
        default=None,
        metavar=("LX", "LY"),
        help="largest arena drawn, m (default 6 x 3; at most 20 x 10)",
    )
    p.add_argument("--shape", choices=SHAPES, default=None, help="structure shape (default: drawn)")
    p.add_argument(
        "--depots", type=int, choices=(1, 2), default=1, help="depot grids: 1, or 2 along the long sides (default 1)"
    )
    p.add_argument(
        "--collisions", choices=("ghost", "physical"), default=None, help="default: the construction scenario's"
    )
    p.add_argument("--out", type=Path, default=None, metavar="FILE", help="scenario file to write (default: print it)")
    p.set_defaults(func=_cmd_layout)


def _agents(text: str) -> int | tuple[int, int]:
    """``N`` or ``LO:HI`` within 1..20."""
    try:
        parts = tuple(int(v) for v in text.split(":"))
    except ValueError:
        parts = ()
    if len(parts) not in (1, 2) or not all(1 <= v <= 20 for v in parts) or parts[0] > parts[-1]:
        raise argparse.ArgumentTypeError(f"must be an integer in 1..20 or a range LO:HI within it, got {text!r}")
    return parts[0] if len(parts) == 1 else (parts[0], parts[1])


def _cmd_layout(args: argparse.Namespace) -> int:
    import yaml

    from pybullet_swarm.experiment.layouts import MAX_ARENA, random_layout
    from pybullet_swarm.experiment.scenario import _seed

    if args.arena is not None and not all(0.5 <= v <= 100.0 for v in args.arena):
        raise ConfigError(f"each side must be in 0.5..100 m, got {args.arena}", source="--arena")
    data = random_layout(
        _seed(args.seed, "--seed"),
        agents=args.agents,
        arena=args.arena,
        shape=args.shape,
        depots=args.depots,
        collisions=args.collisions,
        max_arena=MAX_ARENA if args.max_arena is None else (args.max_arena[0], args.max_arena[1]),
    )
    text = f"# pybullet-swarm layout --seed {args.seed}: {data['description']}\n" + yaml.safe_dump(
        data, sort_keys=False, default_flow_style=None
    )
    if args.out is None:
        print(text, end="")
        return 0
    from pybullet_swarm.experiment.rundir import atomic_write

    if args.out.is_dir():
        raise ConfigError("is a directory; give a file name", source=str(args.out))
    atomic_write(args.out, lambda fh: fh.write(text))
    print(args.out)
    return 0


# ------------------------------------------------------------------- design
def _add_design(sub: Any) -> None:
    p = sub.add_parser(
        "design", help="design the controller of a vehicle and report poles, margins, bandwidths and rotor saturation"
    )
    p.add_argument(
        "--scenario",
        default=None,
        help="take vehicle, rates and gravity from this scenario and check its reference step "
        "(its limits) for rotor saturation",
    )
    p.add_argument("--vehicle", default=None, help="bundled vehicle name or vehicle YAML file (default quad150)")
    p.add_argument("--physics-hz", type=float, default=None, help="attitude-loop rate, Hz (default 240)")
    p.add_argument("--control-hz", type=float, default=None, help="position-loop rate, Hz (default 48)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument("--plot", type=Path, default=None, metavar="DIR", help="write Bode and step-response figures")
    p.set_defaults(func=_cmd_design)


def _cmd_design(args: argparse.Namespace) -> int:
    import math

    from pybullet_swarm.control.design import ReferenceStep, check_rates, design_controller, format_table
    from pybullet_swarm.vehicle import load_vehicle

    for option, value in (("--physics-hz", args.physics_hz), ("--control-hz", args.control_hz)):
        if value is not None and not (math.isfinite(value) and 0 < value <= 1e5):
            raise ConfigError(f"must be a rate in (0, 100000] Hz, got {value:g}", source=option)
    if args.plot is not None:
        from pybullet_swarm.experiment.rundir import check_output_dir

        check_output_dir(args.plot, source="--plot")
    vehicle, physics_hz, control_hz, gravity, step = "quad150", 240.0, 48.0, 9.81, None
    if args.scenario is not None:
        from pybullet_swarm.experiment.scenario import load_scenario

        sc = load_scenario(args.scenario)
        vehicle, physics_hz, control_hz, gravity = (
            sc.agents.vehicle,
            float(sc.sim.physics_hz),
            float(sc.sim.control_hz),
            float(sc.sim.gravity),
        )
        step = ReferenceStep.from_limits(sc.velocity_limits(), sc.acceleration_limits())
    vehicle = args.vehicle if args.vehicle is not None else vehicle
    physics_hz = args.physics_hz if args.physics_hz is not None else physics_hz
    control_hz = args.control_hz if args.control_hz is not None else control_hz
    try:
        params = load_vehicle(vehicle)
    except OSError as exc:  # e.g. a name too long for the file system
        raise ConfigError(
            f"must be a bundled vehicle name or a vehicle .yaml file ({exc.strerror})", source="--vehicle"
        ) from None
    try:
        check_rates(physics_hz, control_hz)
    except ValueError as exc:
        raise ConfigError(str(exc), source="--control-hz") from None
    # no gains for a loop, or a saturating step: a ConfigError naming the vehicle file and the loop
    design = design_controller(params, physics_hz=physics_hz, position_hz=control_hz, gravity=gravity)
    checked = design.check_step(step) if step is not None else None  # the scenario's step, the runtime's gains
    if args.json:
        data = design.to_json_dict()
        if checked is not None:
            data["scenario_saturation"] = checked.to_json_dict()
        print(json.dumps(data))
    else:
        print(format_table(design))
        if checked is not None:
            st = checked.step
            print(
                f"scenario {args.scenario}: step a = {st.acceleration} m/s^2, p = {st.position} m, yaw = {st.yaw:g} "
                f"rad: rotor speed {100 * checked.min_fraction:.1f} .. {100 * checked.peak_fraction:.1f} % of max"
            )
    if args.plot is not None:
        from pybullet_swarm.plotting.design_plots import plot_design

        files = plot_design(design, args.plot)
        if not args.json:
            print("figures: " + ", ".join(str(f) for f in files))
    return 0


# --------------------------------------------------------------------- plot
def _add_plot(sub: Any) -> None:
    p = sub.add_parser("plot", help="redraw the figures of a finished run, or the comparison figures of a sweep")
    p.add_argument("run_dir", type=Path, metavar="RUN_DIR|SWEEP_DIR")
    p.add_argument(
        "--out", type=Path, default=None, help="figure directory (default: RUN_DIR/plots or SWEEP_DIR/plots)"
    )
    p.add_argument(
        "--ci",
        choices=("t", "bootstrap"),
        default="t",
        help="95%% interval of the mean in the sweep table: t-interval or BCa bootstrap (default t)",
    )
    p.add_argument(
        "--metrics",
        type=_names,
        default=None,
        metavar="A,B,...",
        help="sweep: metrics of the table and box plots (default: headline metrics, every box plot)",
    )
    p.set_defaults(func=_cmd_plot)


def _cmd_plot(args: argparse.Namespace) -> int:
    from pybullet_swarm.experiment.results import is_sweep_dir

    if is_sweep_dir(args.run_dir):
        return _plot_sweep(args)
    from pybullet_swarm.experiment.results import check_saved_run
    from pybullet_swarm.experiment.rundir import check_output_dir
    from pybullet_swarm.plotting.run_plots import plot_run, plot_saved_artifacts

    if not (args.run_dir / "timeseries.npz").is_file():
        raise ConfigError(
            "not a run directory (no timeseries.npz) nor a sweep directory (no runs.csv)", source=str(args.run_dir)
        )
    out = check_output_dir(args.out or args.run_dir / "plots", source="--out" if args.out else None)
    saved = check_saved_run(args.run_dir)  # every saved file is read and checked before the first figure
    files = plot_run(saved["timeseries"], out, saved["metrics"], scenario=saved["scenario"], events=saved["events"])
    files += plot_saved_artifacts(args.run_dir, out)
    for f in files:
        print(f)
    return 0


def _plot_sweep(args: argparse.Namespace) -> int:
    from pybullet_swarm.experiment.summary import format_table, summarize
    from pybullet_swarm.experiment.sweep import draw_comparison, load_sweep

    from pybullet_swarm.experiment.rundir import check_output_dir

    out = check_output_dir(args.out or args.run_dir / "plots", source="--out" if args.out else None)
    rows, group_by = load_sweep(args.run_dir)
    if not rows:
        raise ConfigError("no finished run yet (runs.csv is empty)", source=str(args.run_dir))
    summary = summarize(rows, group_by, ci=args.ci)
    _check_metric_names(args.metrics, summary)
    print(format_table(summary, args.metrics))
    for f in draw_comparison(rows, group_by, out, args.metrics):
        print(f)
    return 0


def _check_metric_names(names: Sequence[str] | None, summary: Sequence[Any]) -> None:
    """Refuse ``--metrics`` names that no compared run has (a typo would silently show nothing)."""
    if not names:
        return
    present = list(dict.fromkeys(s.metric for s in summary))
    if not present:
        return  # no run finished without an error: the table says so
    unknown = [n for n in names if n not in present]
    if unknown:
        import difflib

        close = difflib.get_close_matches(unknown[0], present, n=3, cutoff=0.6)
        hint = (
            f"did you mean {', '.join(close)}?"
            if close
            else f"metrics of these runs: {', '.join(present[:30])}{' ...' if len(present) > 30 else ''}"
        )
        raise ConfigError(f"unknown metric {unknown[0]!r}; {hint}", source="--metrics")


# -------------------------------------------------------------------- sweep
def _names(text: str) -> tuple[str, ...]:
    """``a,b,c`` -> ('a', 'b', 'c'); empty names refused."""
    names = tuple(n.strip() for n in text.split(","))
    if not names or any(not n for n in names):
        raise argparse.ArgumentTypeError(f"expected comma-separated names, got {text!r}")
    return names


def _grid(text: str) -> tuple[str, list[Any]]:
    """``key.path=v1,v2,...`` -> (key, [v1, v2, ...]); the values are read as one YAML flow list."""
    from pybullet_swarm.experiment.scenario import parse_override
    from pybullet_swarm.validation import parse_yaml

    key, _ = parse_override(text.partition("=")[0] + "=", source="--grid")
    raw = text.partition("=")[2]
    try:
        values = parse_yaml(f"[{raw}]", source="--grid") if raw.strip() else None
    except ConfigError:
        values = None
    if not isinstance(values, list) or not values:
        raise ConfigError(f"expected key.path=v1,v2,..., got {text!r}", source="--grid", field=key)
    return key, values


def _add_sweep(sub: Any) -> None:
    p = sub.add_parser("sweep", help="run planners x avoidance x grid values x seeds in parallel, resumable")
    p.add_argument("scenario", help="scenario YAML file or bundled name (see `list`)")
    p.add_argument(
        "--planners",
        type=_names,
        default=(None,),
        metavar="A,B,...",
        help="planners to compare (default: the scenario's)",
    )
    p.add_argument(
        "--avoidance",
        type=_names,
        default=(None,),
        metavar="A,B,...",
        help="avoidance layers to compare, e.g. none,orca (default: the scenario's)",
    )
    p.add_argument("--seeds", type=int, required=True, metavar="N", help="runs per configuration: N seeds")
    p.add_argument("--seed-start", type=int, default=0, metavar="S", help="first seed (default 0): seeds S .. S+N-1")
    add_overrides_option(p, "override a scenario field in every run (repeatable)")
    p.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="KEY.PATH=V1,V2,...",
        help="sweep a scenario field over values (repeatable: every combination runs)",
    )
    p.add_argument(
        "--executor",
        choices=("local", "ray"),
        default="local",
        help="local: a process pool on this machine (default); ray: Ray tasks",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="K",
        help="parallel runs (default: the number of cores; with --address: the cluster's CPUs)",
    )
    p.add_argument(
        "--address",
        default=None,
        metavar="ADDR",
        help="Ray cluster to use (auto or host:port); without it --executor ray starts a local Ray",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="sweep directory (default: runs/sweep-<scenario>-<hash of scenario and --set>)",
    )
    p.add_argument("--retry-failed", action="store_true", help="run again the runs recorded as errors")
    p.add_argument(
        "--run-plots",
        action="store_true",
        help="draw each run's own figures and report.html too (later: pybullet-swarm plot/report RUN_DIR)",
    )
    p.add_argument("--no-plots", action="store_true", help="skip the comparison figures")
    p.add_argument(
        "--ci",
        choices=("t", "bootstrap"),
        default="t",
        help="95%% interval of the mean in summary.csv: t-interval or BCa bootstrap (default t)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar, no table (for scripts)")
    p.set_defaults(func=_cmd_sweep)


def _cmd_sweep(args: argparse.Namespace) -> int:
    from pybullet_swarm.experiment.sweep import Sweep, run_sweep

    if args.seeds < 1:
        raise ConfigError(f"must be >= 1, got {args.seeds}", source="--seeds")
    if args.seed_start < 0:
        raise ConfigError(f"must be >= 0, got {args.seed_start}", source="--seed-start")
    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"must be >= 1, got {args.workers}", source="--workers")
    if args.address is not None and args.executor != "ray":
        raise ConfigError("needs --executor ray", source="--address")
    grid = [_grid(g) for g in args.grid]
    if args.out is not None:
        from pybullet_swarm.experiment.rundir import check_output_dir

        check_output_dir(args.out, source="--out")
    sweep = Sweep(
        args.scenario,
        planners=args.planners,
        avoidance=args.avoidance,
        grid=grid,
        seeds=range(args.seed_start, args.seed_start + args.seeds),
        overrides=args.overrides,
    )
    result = run_sweep(
        sweep,
        args.out,
        executor=args.executor,
        workers=args.workers,
        address=args.address,
        plots=args.run_plots,
        figures=not args.no_plots,
        retry_failed=args.retry_failed,
        ci=args.ci,
        quiet=args.quiet,
    )
    if result.interrupted:
        return _fail(
            f"interrupted; {len(result.rows)} runs recorded in {result.out}; run the same command again to resume", 130
        )
    from pybullet_swarm.experiment.sweep_report import write_sweep_report

    page = write_sweep_report(result.out)
    if not args.quiet:
        print(result.table())
        print(
            f"sweep directory: {result.out} ({result.n_planned} runs: {result.n_run} run now, "
            f"{result.n_skipped} skipped, {result.n_failed} failed; {result.wall_time_s:.1f} s)"
        )
        t = result.timings
        if t:
            print(
                f"time: planning {t['plan_s']:.2f} s, runs {t['runs_s']:.2f} s (the runs themselves "
                f"{t['busy_s']:.2f} s in their workers), summary and figures {t['finish_s']:.2f} s"
            )
        print(f"report: {page}")
    if result.n_failed:
        return _fail(
            f"{result.n_failed} of {result.n_planned} runs failed (exit_status=error in "
            f"{result.out / 'runs.csv'}; --retry-failed runs them again)",
            1,
        )
    return 0


# ------------------------------------------------------------------ compare
def _add_compare(sub: Any) -> None:
    p = sub.add_parser("compare", help="compare finished runs (or sweeps): table and comparison figures")
    p.add_argument("dirs", type=Path, nargs="+", metavar="RUN_DIR", help="run directories or sweep directories")
    p.add_argument("--out", type=Path, default=None, help="figure directory (default: runs/compare-<time>)")
    p.add_argument(
        "--ci",
        choices=("t", "bootstrap"),
        default="t",
        help="95%% interval of the mean: t-interval or BCa bootstrap (default t)",
    )
    p.add_argument(
        "--metrics",
        type=_names,
        default=None,
        metavar="A,B,...",
        help="metrics of the table and box plots (default: headline metrics, every box plot)",
    )
    p.set_defaults(func=_cmd_compare)


def _cmd_compare(args: argparse.Namespace) -> int:
    import time

    from pybullet_swarm.experiment.results import is_run_dir, is_sweep_dir, run_dir_row
    from pybullet_swarm.experiment.summary import format_table, summarize, write_summary
    from pybullet_swarm.experiment.sweep import draw_comparison, load_sweep

    from pybullet_swarm.experiment.rundir import check_output_dir

    out = args.out or Path("runs") / f"compare-{time.strftime('%Y%m%d-%H%M%S')}"
    check_output_dir(out, source="--out" if args.out else None)
    rows: list[dict[str, Any]] = []
    grid: list[str] = []
    for d in args.dirs:
        if is_sweep_dir(d):
            sweep_rows, group_by = load_sweep(d)
            rows += [{**r, "sweep": d.name} for r in sweep_rows]
            grid += [g for g in group_by[2:] if g not in grid]
        elif is_run_dir(d):
            rows.append(run_dir_row(d))
        else:
            raise ConfigError(
                "not a finished run directory (no metrics.json) nor a sweep directory (no runs.csv)", source=str(d)
            )
    if not rows:
        raise ConfigError("no finished run to compare", source="compare")
    by = [c for c in ("sweep", "scenario", "planner", "avoidance", "config", *grid) if any(c in r for r in rows)]
    summary = summarize(rows, by, ci=args.ci)
    _check_metric_names(args.metrics, summary)
    print(format_table(summary, args.metrics))
    write_summary(out / "summary.csv", summary)
    for f in [out / "summary.csv", *draw_comparison(rows, by, out, args.metrics)]:
        print(f)
    return 0


# --------------------------------------------------------------------- list
def _add_list(sub: Any) -> None:
    p = sub.add_parser("list", help="list vehicles, scenarios, planners and avoidance layers with their parameters")
    p.set_defaults(func=_cmd_list)


def _cmd_list(args: argparse.Namespace) -> int:
    from pybullet_swarm.planning import available_avoidance, available_planners
    from pybullet_swarm.resources import bundled_scenarios, bundled_vehicles
    from pybullet_swarm.vehicle import load_vehicle

    print("vehicles:")
    for name in bundled_vehicles():
        v = load_vehicle(name)
        print(
            f"  {name:10s} {v.mass * 1000:.0f} g, arm {v.arm_length * 100:.1f} cm, "
            f"thrust/weight {v.thrust_to_weight():.2f}, motor tau {v.motor_time_constant * 1000:.0f} ms"
        )
    print("scenarios:")
    from pybullet_swarm.experiment.scenario import resolve_scenario_path
    from pybullet_swarm.validation import read_yaml

    for name in bundled_scenarios():
        try:
            desc = (read_yaml(resolve_scenario_path(name)) or {}).get("description", "")
        except ConfigError:
            desc = "(invalid)"
        print(f"  {name:18s} {desc}")
    from pybullet_swarm import tasks
    from pybullet_swarm.planning import registry

    print("tasks:")
    for kind, task in tasks.task_entries().items():
        doc = (task.model.__doc__ or "").strip().partition("\n")[0]
        print(f"  {kind:18s} {doc}{_from(task.origin)}")
    print("planners (parameters: name, type, default, range, description; set them in planner.params):")
    for name, text in available_planners().items():
        entry = registry.planners()[name]
        print(f"  {name:18s} {text}{_from(entry.origin)}")
        _print_params(entry.params)
    print("avoidance (parameters in avoidance_params):")
    for name, text in available_avoidance().items():
        layer = registry.avoidance_layers()[name]
        print(f"  {name:18s} {text}{_from(layer.origin)}")
        _print_params(layer.params)
    refusals = {**tasks.refused(), **registry.refused()}
    if refusals:
        print("refused plug-ins:")
        for exc in refusals.values():
            print(f"  {exc}")
    return 0


def _from(origin: Any) -> str:
    """' [plug-in from DIST VERSION (module:Class)]' for a plug-in, '' for what pybullet_swarm brings."""
    return "" if origin.builtin else f" [plug-in from {origin}]"


def _print_params(model: Any) -> None:
    """One line per parameter of a plug-in's model: name, type, default, range, description."""
    from pybullet_swarm.planning.params import describe

    rows = [
        (p.name, p.type, "null" if p.default is None else json.dumps(p.default), p.range_text(), p.description)
        for p in describe(model)
    ]
    if not rows:
        print("      (no parameters)")
        return
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    for r in rows:
        print("      " + "  ".join(c.ljust(w) for c, w in zip(r[:4], widths)) + "  " + r[4])


# --------------------------------------------------------------------- main
def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``pybullet-swarm``."""
    parser = _Parser(prog=PROG, description="A testbed for quadrotor swarms in PyBullet.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    for add in (
        _add_run,
        _add_check,
        _add_layout,
        _add_design,
        _add_plot,
        _add_sweep,
        _add_compare,
        _add_replay,
        _add_report,
        _add_list,
    ):
        add(sub)
    from pybullet_swarm.cli import benchmark

    benchmark.register(sub)
    try:
        from pybullet_swarm.cli import tsp
    except ImportError:
        pass
    else:
        tsp.register(sub)
    try:
        from pybullet_swarm.cli import tune
    except ImportError:
        pass
    else:
        tune.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    debug = False
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        debug = bool(getattr(args, "debug", False))
        return int(args.func(args) or 0)
    except ConfigError as exc:
        return _fail(str(exc), 2)
    except KeyboardInterrupt:
        return _fail("interrupted", 130)
    except BrokenPipeError:  # the reader of stdout stopped (`| head`): nothing more to say, not a failure
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # no second error when the interpreter flushes stdout at exit
        return 0
    except SystemExit as exc:  # --help and friends
        return int(exc.code or 0) if isinstance(exc.code, int) else 0
    except Exception as exc:  # noqa: BLE001 - the last line of defence of a command-line tool
        if debug:
            traceback.print_exc()
        return _fail(f"internal error: {exc.__class__.__name__}: {exc}", 1)


if __name__ == "__main__":
    sys.exit(main())
