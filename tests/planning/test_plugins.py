"""Plug-ins from other packages (pybullet_swarm/plugins.py, planning/registry.py, tasks/__init__.py).

The example package ``examples/plugin_planner`` is pip-installed from a copy of its directory into a
temporary target (``--no-deps --no-build-isolation --target``), and ``pybullet-swarm`` runs in
subprocesses with that target on ``PYTHONPATH``: the test environment is never modified. A broken
plug-in is installed the same way and must be refused in one line naming its distribution.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

from pybullet_swarm import plugins
from pybullet_swarm.plugins import Origin, PluginRefused
from pybullet_swarm.planning.base import Command, Observation, TaskInfo
from pybullet_swarm.planning.registry import avoidance_entry, planner_entry

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "plugin_planner"
ORIGIN = Origin("someone-elses-planner", "1.2", "theirs.planner:Theirs")


def _install(source: Path, target: Path) -> None:
    """pip-install the package at ``source`` (a copy, so that its build leaves nothing behind) into ``target``."""
    copy = target.parent / f"src-{source.name}"
    shutil.copytree(source, copy)
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "-q",
            "--no-deps",
            "--no-build-isolation",
            "--target",
            str(target),
            str(copy),
        ],
        check=True,
        capture_output=True,
        text=True,
    )


def _cli(target: Path, *args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(target), str(REPO)])}
    return subprocess.run(
        [sys.executable, "-m", "pybullet_swarm.cli.main", *args], cwd=cwd, env=env, capture_output=True, text=True
    )


@pytest.fixture(scope="module")
def example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The target directory the example plug-in is installed into."""
    target = tmp_path_factory.mktemp("plugin") / "site"
    _install(EXAMPLE, target)
    return target


# ------------------------------------------------------------------ the example, installed
def test_list_shows_the_installed_planner_and_where_it_comes_from(example: Path, tmp_path: Path) -> None:
    out = _cli(example, "list", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    line = next(x for x in out.stdout.splitlines() if x.strip().startswith("follow_route "))
    assert "[tasks: route]" in line
    assert "[plug-in from plugin-planner 0.1.0 (plugin_planner.planner:FollowRoute)]" in line
    assert "refused plug-ins" not in out.stdout
    assert "switch_radius" in out.stdout  # its parameters are listed from its model


@pytest.mark.slow
def test_run_and_sweep_fly_the_installed_planner(example: Path, tmp_path: Path) -> None:
    run = _cli(
        example, "run", "flocking", "--planner", "follow_route", "--out", "r", "--no-plots", "--quiet", cwd=tmp_path
    )
    assert run.returncode == 0, run.stderr
    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert m["planner"] == "follow_route"
    assert m["exit_status"] == "completed"
    assert m["waypoints_passed"] == m["waypoints_total"] == 3
    assert sum(m["collisions"].values()) == 0
    sweep = _cli(
        example, "sweep", "flocking", "--planners", "follow_route", "--seeds", "2", "--workers", "1",
        "--out", "s", "--no-plots", "--quiet", cwd=tmp_path,
    )  # fmt: skip
    assert sweep.returncode == 0, sweep.stderr
    rows = _rows(tmp_path / "s")
    assert {r["planner"] for r in rows} == {"follow_route"}
    assert len(rows) == 2 and all(r["exit_status"] == "completed" for r in rows)


def _rows(sweep: Path) -> list[dict[str, Any]]:
    with open(sweep / "runs.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_a_scenario_parameter_of_the_plugin_is_validated_by_its_model(example: Path, tmp_path: Path) -> None:
    out = _cli(
        example,
        "check",
        "flocking",
        "--set",
        "planner.name=follow_route",
        "--set",
        "planner.params.speed=-1",
        cwd=tmp_path,
    )
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "planner.params.speed" in out.stderr


# ------------------------------------------------------------------ a broken plug-in
BROKEN = {
    "pyproject.toml": """\
        [build-system]
        requires = ["setuptools>=61", "wheel"]
        build-backend = "setuptools.build_meta"

        [project]
        name = "broken-planner"
        version = "0.3"

        [project.entry-points."pybullet_swarm.planners"]
        broken = "broken_planner:Broken"

        [project.entry-points."pybullet_swarm.avoidance"]
        absent = "broken_planner.nowhere:Layer"

        [project.entry-points."pybullet_swarm.tasks"]
        shapeless = "broken_planner:Shapeless"

        [tool.setuptools]
        py-modules = ["broken_planner"]
        """,
    "broken_planner.py": """\
        class Broken:
            name = "broken"
            centralized = False
            tasks = ("route",)

            def reset(self, agent_id, rng, info):
                pass


        class Shapeless:
            pass
        """,
}


def test_a_broken_plugin_is_refused_in_one_line_naming_its_package(tmp_path: Path) -> None:
    source = tmp_path / "broken"
    source.mkdir()
    for name, text in BROKEN.items():
        (source / name).write_text(textwrap.dedent(text))
    target = tmp_path / "site"
    _install(source, target)
    out = _cli(target, "list", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    refused = out.stdout.split("refused plug-ins:\n", 1)[1].splitlines()
    assert sorted(refused) == [
        "  avoidance plug-in 'absent' from broken-planner 0.3 (broken_planner.nowhere:Layer) refused: cannot be "
        "imported: ModuleNotFoundError: No module named 'broken_planner.nowhere'; 'broken_planner' is not a package",
        "  planner plug-in 'broken' from broken-planner 0.3 (broken_planner:Broken) refused: not a Planner: missing plan",
        "  task plug-in 'shapeless' from broken-planner 0.3 (broken_planner:Shapeless) refused: Model must be a "
        "pydantic model of the task section, got None",
    ]
    assert not any(line.strip().startswith("broken ") for line in out.stdout.split("refused plug-ins:")[0].splitlines())
    run = _cli(target, "check", "flocking", "--set", "planner.name=broken", cwd=tmp_path)
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1
    assert "planner.name: planner plug-in 'broken' from broken-planner 0.3" in run.stderr
    assert "not a Planner: missing plan" in run.stderr


# ------------------------------------------------------------------ checks when a class registers (in-process)
class _Decentral:
    name: ClassVar[str] = "d"
    centralized: ClassVar[bool] = False

    def reset(self, agent_id: int, rng: np.random.Generator, info: TaskInfo) -> None:
        pass

    def plan(self, obs: Observation, medium: Any | None) -> Command:
        return Command.hold()


class _Reporting(_Decentral):
    def activity(self) -> str:
        return "busy"

    @classmethod
    def check_task(cls, task: Any) -> None:
        pass


class _Central:
    name: ClassVar[str] = "c"
    centralized: ClassVar[bool] = True

    def reset(self, n: int, rng: np.random.Generator, info: TaskInfo) -> None:
        pass

    def plan(self, obs: Observation, medium: Any | None) -> Command:  # a decentralised method, not plan_all
        return Command.hold()


def test_capabilities_are_recorded_from_the_class() -> None:
    plain = planner_entry("d", _Decentral, "plain", ("route",), origin=ORIGIN)
    assert not plain.centralized and not plain.reports_activity and plain.check_task is None
    assert plain.make_medium is None and not plain.publishes_artefacts
    rich = planner_entry("r", _Reporting, "rich", ("route",), origin=ORIGIN)
    assert rich.reports_activity and rich.check_task is not None
    assert rich.origin == ORIGIN


@pytest.mark.parametrize(
    ("cls", "why"),
    [
        (_Central, "not a CentralPlanner: missing plan_all"),
        (object, "missing the class attribute centralized (True or False)"),
        (len, "must be a class, got builtin_function_or_method"),
    ],
)
def test_a_class_that_is_not_a_planner_is_refused(cls: Any, why: str) -> None:
    with pytest.raises(PluginRefused) as info:
        planner_entry("x", cls, "x", ("route",), origin=ORIGIN)
    assert (
        str(info.value) == f"planner plug-in 'x' from someone-elses-planner 1.2 (theirs.planner:Theirs) refused: {why}"
    )


def test_a_planner_without_tasks_is_refused() -> None:
    with pytest.raises(PluginRefused, match="tasks must name at least one task kind"):
        planner_entry("x", _Decentral, "x", (), origin=ORIGIN)


def test_a_layer_is_checked_and_a_builtin_that_fails_is_a_type_error() -> None:
    with pytest.raises(PluginRefused, match="not an AvoidanceLayer: missing filter, metrics, needs_range_sensors"):
        avoidance_entry("x", _Decentral, "x", origin=ORIGIN)
    with pytest.raises(TypeError, match="from pybullet_swarm refused"):
        avoidance_entry("x", _Decentral, "x")


def test_protocol_methods_are_listed_without_data_members() -> None:
    from pybullet_swarm.planning.base import AvoidanceLayer, Planner

    assert plugins.methods(Planner) == ["plan", "reset"]
    assert plugins.methods(AvoidanceLayer) == ["filter", "metrics"]


def test_the_guide_shows_the_example_as_it_is() -> None:
    guide = (REPO / "docs" / "guides" / "plugins.md").read_text(encoding="utf-8")
    for name in ("pyproject.toml", "plugin_planner/__init__.py", "plugin_planner/planner.py"):
        assert (EXAMPLE / name).read_text(encoding="utf-8") in guide, name
