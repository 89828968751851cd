"""``pybullet-swarm``: run, check, design, plot, list (and the subcommands later layers add).

Exit codes: 0 when the command did its work (a simulation's outcome is in ``exit_status``),
2 for bad input (one line on stderr naming the file, the field and the expectation), 1 for an
internal error.
"""
from __future__ import annotations

import argparse
import json
import sys
import traceback
from pathlib import Path
from typing import Any, Sequence

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
    p.add_argument("--out", type=Path, default=None, help="run directory (default: runs/<name>-<planner>-s<seed>-<time>)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE",
                   help="override a scenario field (repeatable), e.g. --set agents.count=20")
    p.add_argument("--gui", action="store_true", help="watch in the Bullet GUI")
    p.add_argument("--video", action="store_true",
                   help="render RUN_DIR/video.mp4 (GIF without an MP4 encoder), 4x faster than real time")
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")
    p.set_defaults(func=_cmd_run)


def _format_metrics(m: dict[str, Any]) -> str:
    rows: list[tuple[str, str]] = []
    for key, value in m.items():
        if isinstance(value, dict):
            if key == "path_length_m":
                rows.append((key, f"{value['total']:.3f}"))
                continue
            for k2, v2 in value.items():
                rows.append((f"{key}.{k2}", _fmt(v2)))
        elif isinstance(value, list):
            continue
        else:
            rows.append((key, _fmt(value)))
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"  {k.ljust(width)}  {v}" for k, v in rows)


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return "-" if v is None else str(v)


def _cmd_run(args: argparse.Namespace) -> int:
    from pybullet_swarm.experiment.rundir import default_run_dir
    from pybullet_swarm.experiment.runner import run
    from pybullet_swarm.experiment.scenario import load_scenario

    scenario = load_scenario(args.scenario, args.overrides)
    seed = scenario.seed if args.seed is None else args.seed
    if seed < 0:
        raise ConfigError(f"must be >= 0, got {seed}", source="--seed")
    planner = args.planner or scenario.planner.name or "waypoints"
    out = args.out or default_run_dir(scenario.name, planner, seed)
    result = run(scenario, planner=args.planner, avoidance=args.avoidance, seed=seed, out=out, gui=args.gui,
                 plots=not args.no_plots, video=args.video, quiet=args.quiet)
    if not args.quiet:
        print(f"{scenario.name}: {result.exit_status.value} after {result.metrics['sim_time_s']:.2f} s simulated "
              f"({result.metrics['real_time_factor'] or 0:.1f}x real time)")
        print(_format_metrics(result.metrics))
        print(f"run directory: {result.run_dir}")
    return 0


# -------------------------------------------------------------------- check
def _add_check(sub: Any) -> None:
    p = sub.add_parser("check", help="validate a scenario and print it resolved")
    p.add_argument("scenario")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_cmd_check)


def _cmd_check(args: argparse.Namespace) -> int:
    import yaml

    from pybullet_swarm.experiment.scenario import load_scenario

    scenario = load_scenario(args.scenario, args.overrides)
    if not args.quiet:
        print(yaml.safe_dump(dict(scenario.data), sort_keys=False), end="")
    return 0


# ------------------------------------------------------------------- design
def _add_design(sub: Any) -> None:
    p = sub.add_parser("design", help="design the controller of a vehicle and report margins and bandwidths")
    p.add_argument("--vehicle", default="quad150", help="bundled vehicle name or vehicle YAML file")
    p.add_argument("--physics-hz", type=float, default=240.0, help="attitude-loop rate, Hz")
    p.add_argument("--control-hz", type=float, default=48.0, help="position-loop rate, Hz")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument("--plot", type=Path, default=None, metavar="DIR", help="write Bode and step-response figures")
    p.set_defaults(func=_cmd_design)


def _cmd_design(args: argparse.Namespace) -> int:
    from pybullet_swarm.control.design import design_controller, format_table
    from pybullet_swarm.vehicle import load_vehicle

    try:
        params = load_vehicle(args.vehicle)
    except OSError as exc:  # e.g. a name too long for the file system
        raise ConfigError(f"must be a bundled vehicle name or a vehicle .yaml file ({exc.strerror})",
                          source="--vehicle") from None
    if args.physics_hz <= 0 or args.control_hz <= 0:
        raise ConfigError("rates must be > 0", source="--physics-hz/--control-hz")
    try:
        design = design_controller(params, physics_hz=args.physics_hz, position_hz=args.control_hz)
    except ValueError as exc:
        raise ConfigError(str(exc), source="--control-hz") from None
    if args.json:
        print(json.dumps(design.to_json_dict()))
    else:
        print(format_table(design))
    if args.plot is not None:
        from pybullet_swarm.plotting.design_plots import plot_design

        files = plot_design(design, args.plot)
        if not args.json:
            print("figures: " + ", ".join(str(f) for f in files))
    return 0


# --------------------------------------------------------------------- plot
def _add_plot(sub: Any) -> None:
    p = sub.add_parser("plot", help="redraw the figures of a finished run from its saved files")
    p.add_argument("run_dir", type=Path)
    p.add_argument("--out", type=Path, default=None, help="figure directory (default: RUN_DIR/plots)")
    p.set_defaults(func=_cmd_plot)


def _cmd_plot(args: argparse.Namespace) -> int:
    from pybullet_swarm.experiment.recorder import TimeSeries
    from pybullet_swarm.plotting.run_plots import plot_run

    npz = args.run_dir / "timeseries.npz"
    if not npz.is_file():
        raise ConfigError("not a run directory (no timeseries.npz)", source=str(args.run_dir))
    metrics_path = args.run_dir / "metrics.json"
    metrics = json.loads(metrics_path.read_text()) if metrics_path.is_file() else {}
    files = plot_run(TimeSeries.load(npz), args.out or args.run_dir / "plots", metrics)
    for f in files:
        print(f)
    return 0


# --------------------------------------------------------------------- list
def _add_list(sub: Any) -> None:
    p = sub.add_parser("list", help="list vehicles, scenarios and planners")
    p.set_defaults(func=_cmd_list)


def _cmd_list(args: argparse.Namespace) -> int:
    from pybullet_swarm.planning import available_avoidance, available_planners
    from pybullet_swarm.resources import bundled_scenarios, bundled_vehicles
    from pybullet_swarm.vehicle import load_vehicle

    print("vehicles:")
    for name in bundled_vehicles():
        v = load_vehicle(name)
        print(f"  {name:10s} {v.mass * 1000:.0f} g, arm {v.arm_length * 100:.1f} cm, "
              f"thrust/weight {v.thrust_to_weight():.2f}, motor tau {v.motor_time_constant * 1000:.0f} ms")
    print("scenarios:")
    from pybullet_swarm.experiment.scenario import resolve_scenario_path
    from pybullet_swarm.validation import read_yaml

    for name in bundled_scenarios():
        try:
            desc = (read_yaml(resolve_scenario_path(name)) or {}).get("description", "")
        except ConfigError:
            desc = "(invalid)"
        print(f"  {name:18s} {desc}")
    print("planners:")
    for name, text in available_planners().items():
        print(f"  {name:18s} {text}")
    print("avoidance:")
    for name, text in available_avoidance().items():
        print(f"  {name:18s} {text}")
    return 0


# --------------------------------------------------------------------- main
def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``pybullet-swarm``."""
    parser = _Parser(prog=PROG, description="A testbed for quadrotor swarms in PyBullet.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    for add in (_add_run, _add_check, _add_design, _add_plot, _add_list):
        add(sub)
    try:
        from pybullet_swarm.cli import tsp
    except ImportError:
        pass
    else:
        tsp.register(sub)
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
    except SystemExit as exc:  # --help and friends
        return int(exc.code or 0) if isinstance(exc.code, int) else 0
    except Exception as exc:  # noqa: BLE001 - the last line of defence of a command-line tool
        if debug:
            traceback.print_exc()
        return _fail(f"internal error: {exc.__class__.__name__}: {exc}", 1)


if __name__ == "__main__":
    sys.exit(main())
