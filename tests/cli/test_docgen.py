"""The documentation's generated reference covers the code, and result tables come only from well-formed JSON."""

from __future__ import annotations

import argparse
import copy
import importlib.util
import json
import subprocess
import sys
import types
import typing
from pathlib import Path
from typing import Any, Iterator

import pydantic
import pytest

from pybullet_swarm.cli import docgen
from pybullet_swarm.cli.main import build_parser
from pybullet_swarm.errors import ConfigError
from pybullet_swarm.experiment.scenario import _ScenarioFile
from pybullet_swarm.planning.registry import avoidance_layers, planners
from pybullet_swarm.tasks import task_models

ROOT = Path(__file__).resolve().parents[2]


def _models_in(annotation: Any) -> Iterator[type[pydantic.BaseModel]]:
    if isinstance(annotation, type) and issubclass(annotation, pydantic.BaseModel):
        yield annotation
    for arg in typing.get_args(annotation):
        yield from _models_in(arg)


def _holds_list(annotation: Any) -> bool:
    """True for ``list[...]`` / ``tuple[...]``, also inside ``Annotated`` and unions."""
    origin = typing.get_origin(annotation)
    if origin in (list, tuple):
        return True
    if origin is typing.Annotated:
        return _holds_list(typing.get_args(annotation)[0])
    return origin in (typing.Union, types.UnionType) and any(_holds_list(a) for a in typing.get_args(annotation))


def _paths(model: type[pydantic.BaseModel], prefix: str = "") -> Iterator[str]:
    """Every field of a model and of the models nested in it, as dotted paths (``[]`` for a list of models)."""
    for name, f in model.model_fields.items():
        yield prefix + name
        for inner in set(_models_in(f.annotation)):
            yield from _paths(inner, f"{prefix}{name}{'[]' if _holds_list(f.annotation) else ''}.")


def _section(text: str, heading: str) -> str:
    """The part of a Markdown text from ``heading`` to the next heading of the same or a higher level."""
    level = heading.split(" ")[0]
    start = text.index(heading + "\n")
    rest = text[start + len(heading) :]
    ends = [i for i in (rest.find(f"\n{'#' * n} ") for n in range(1, len(level) + 1)) if i >= 0]
    return rest[: min(ends)] if ends else rest


def test_scenario_reference_names_every_field_of_every_model() -> None:
    ref = docgen.scenario_reference()
    paths = list(_paths(_ScenarioFile))
    assert "sim.physics_hz" in paths and "arena.obstacles[].shape" in paths and "sensing.imu.gyro_bias" in paths
    missing = [p for p in paths if f"| `{p}` |" not in ref]
    assert not missing
    for kind, model in task_models().items():
        section = _section(ref, f"## `task` of kind `{kind}`")
        missing = [p for p in _paths(model, "task.") if f"| `{p}` |" not in section]
        assert not missing, kind


def test_scenario_reference_names_every_field_of_the_structure_forms() -> None:
    from pybullet_swarm.tasks.layouts import SHAPES, Voxels

    section = _section(docgen.scenario_reference(), "## Structures and depots")
    assert all(f"| `{p}` |" in section for p in _paths(Voxels, "task.structure.voxels."))
    for name, model in SHAPES.items():
        shape = _section(section, f"### Shape `{name}`")
        assert all(f"| `{p}` |" in shape for p in _paths(model, "task.structure.")), name


def test_preset_reference_names_every_parameter_a_preset_changes() -> None:
    from pybullet_swarm.planning.params import extensions

    ref = docgen.preset_reference()
    found = 0
    for key, entries in (("planner.params", planners()), ("avoidance_params", avoidance_layers())):
        for name, entry in entries.items():
            for preset in entry.params.PRESETS:
                section = _section(ref, f"### `{name}`: `{key}.preset: {preset.value}`")
                changed = extensions(entry.params, preset)
                assert changed and all(f"| `{key}.{field}` |" in section for field in changed)
                found += 1
    assert found >= 2  # the thesis preset of the construction planners, ORCA's paper preset


def test_scenario_reference_reads_descriptions_from_the_models() -> None:
    ref = docgen.scenario_reference()
    # a comment beside the field and a comment block above it
    assert "| `sim.physics_hz` | int | `240` | \\[60, 10000\\] | Hz, physics and attitude-loop rate |" in ref
    row = next(line for line in ref.splitlines() if line.startswith("| `sim.contact_hz` |"))
    assert "contact and overlap reads for collision counting" in row


def test_parameter_reference_names_every_parameter_of_every_plugin() -> None:
    ref = docgen.parameter_reference()
    plans = _section(ref, "## Planners")
    layers = _section(ref, "## Avoidance layers")
    assert planners() and avoidance_layers()
    for name, entry in planners().items():
        section = _section(plans, f"### `{name}`")
        assert all(f"| `planner.params.{p}` |" in section for p in entry.params.model_fields), name
    for name, layer in avoidance_layers().items():
        section = _section(layers, f"### `{name}`")
        assert all(f"| `avoidance_params.{p}` |" in section for p in layer.params.model_fields), name


def _commands(parser: argparse.ArgumentParser, prog: str) -> Iterator[tuple[str, argparse.ArgumentParser]]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield f"{prog} {name}", sub
                yield from _commands(sub, f"{prog} {name}")


def test_cli_reference_names_every_command_and_flag() -> None:
    parser = build_parser()
    ref = docgen.cli_reference(parser)
    commands = list(_commands(parser, parser.prog))
    assert {"pybullet-swarm run", "pybullet-swarm sweep", "pybullet-swarm replay"} <= {c for c, _ in commands}
    for command, sub in commands:
        level = "#" * min(2 + command.count(" ") - 1, 4)
        section = _section(ref, f"{level} `{command}`")
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction) or action.help == argparse.SUPPRESS:
                continue
            for flag in action.option_strings:
                assert f"`{flag}`" in section, (command, flag)


SAMPLE = {
    "title": "Completion of the thesis task",
    "command": "pybullet-swarm sweep construction --seeds 2",
    "commit": "b32a59e",
    "date": "2026-11-28",
    "columns": ["planner", "completed", "median time [s]"],
    "rows": [["stigmergy", 2, 95.25], ["shortest_path | orca", 1, 160.0]],
    "notes": ["two seeds only"],
}


def test_results_table_renders_title_table_command_commit_date_and_notes() -> None:
    text = docgen.results_table(SAMPLE, source="docs/results/data/sample.json")
    lines = text.splitlines()
    assert lines[0] == "**Completion of the thesis task**"
    assert "| planner | completed | median time \\[s\\] |" in lines
    assert "|---|---:|---:|" in lines
    assert "| stigmergy | 2 | 95.25 |" in lines
    assert "| shortest_path \\| orca | 1 | 160 |" in lines
    assert any(
        "`pybullet-swarm sweep construction --seeds 2`" in line and "`b32a59e`" in line and "2026-11-28" in line
        for line in lines
    )
    assert "- two seeds only" in lines


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"rows": [["stigmergy", 2]]}, "rows[0]"),
        ({"rows": [["stigmergy", 2, True]]}, "rows[0]"),
        ({"rows": [["stigmergy", 2, float("nan")]]}, "rows[0]"),
        ({"date": "28.11.2026"}, "date"),
        ({"columns": []}, "columns"),
        ({"title": ""}, "title"),
        ({"notes": "one note"}, "notes"),
        ({"commit": None}, "commit"),
        ({"extra": 1}, "extra"),
        ({"command": ...}, "command"),
    ],
)
def test_results_table_refuses_malformed_data_in_one_line(change: dict[str, Any], field: str) -> None:
    data = copy.deepcopy(SAMPLE)
    for key, value in change.items():
        if value is ...:
            del data[key]
        else:
            data[key] = value
    with pytest.raises(ConfigError) as info:
        docgen.results_table(data, source="docs/results/data/sample.json")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"docs/results/data/sample.json: {field}: ")


def test_markers_are_replaced_and_a_missing_or_broken_file_fails(tmp_path: Path) -> None:
    data_dir = tmp_path / "docs" / "results" / "data"
    data_dir.mkdir(parents=True)
    (data_dir / "sample.json").write_text(json.dumps(SAMPLE))
    page = "# Results\n\n<!-- results-table: sample -->\n\nafter\n"
    out = docgen.render_markers(page, root=tmp_path, data_dir=data_dir)
    assert "<!--" not in out and "| stigmergy | 2 | 95.25 |" in out and out.endswith("after\n")
    assert "(data: `docs/results/data/sample.json`)" in out

    with pytest.raises(ConfigError, match=r"^docs/results/data/absent\.json: no such file$"):
        docgen.render_markers("<!-- results-table: absent -->\n", root=tmp_path, data_dir=data_dir)
    (data_dir / "broken.json").write_text('{"title": ')
    with pytest.raises(ConfigError, match=r"^docs/results/data/broken\.json: not readable JSON"):
        docgen.render_markers("<!-- results-table: broken -->\n", root=tmp_path, data_dir=data_dir)
    with pytest.raises(ConfigError, match="unknown reference"):
        docgen.render_markers("<!-- reference: everything -->\n", root=tmp_path, data_dir=data_dir)


def test_markers_in_fenced_code_are_left_alone(tmp_path: Path) -> None:
    page = "```markdown\n<!-- results-table: absent -->\n```\n"
    assert docgen.render_markers(page, root=tmp_path, data_dir=tmp_path) == page


def test_a_benchmark_table_is_rendered_by_the_benchmark_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import types as _types

    fake = _types.ModuleType("pybullet_swarm.experiment.benchmark")
    fake.markdown_table = lambda data: f"| split |\n|---|\n| {data['split']} |"  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "pybullet_swarm.experiment.benchmark", fake)
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "b.json").write_text(json.dumps({"split": "holdout"}))
    out = docgen.render_markers(
        "before\n<!-- benchmark-table: runs/b.json -->\nafter\n", root=tmp_path, data_dir=tmp_path
    )
    assert out == "before\n| split |\n|---|\n| holdout |\n\nafter\n"
    with pytest.raises(ConfigError, match=r"^runs/absent\.json: no such file$"):
        docgen.render_markers("<!-- benchmark-table: runs/absent.json -->\n", root=tmp_path, data_dir=tmp_path)


def test_a_compare_marker_renders_a_compare_json_and_refuses_another(tmp_path: Path) -> None:
    from pybullet_swarm.experiment import benchmark

    runs = [
        {"layout": "l", "planner": "p", "avoidance": "orca", "seed": s, "exit_status": "completed",
         "completion_time_s": 10.0 + s, "contacts": {"agent_agent": 0}, "incidents": 0.0}
        for s in range(3)
    ]  # fmt: skip
    data = {"commit": "abc", "suite": "s", "suite_version": 1, "split": "holdout", "runs": runs,
            "configurations": [{"planner": "p", "avoidance": "orca"}], "contact_classes": ["agent_agent"]}  # fmt: skip
    (tmp_path / "c.json").write_text(json.dumps(benchmark.compare(data, data)))
    out = docgen.render_markers("<!-- benchmark-compare: c.json -->\n", root=tmp_path, data_dir=tmp_path)
    assert "| p + orca | 3 | completion_rate |" in out
    assert out.count("\n|") >= 3
    (tmp_path / "b.json").write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=r"^b\.json: is not the JSON of `pybullet-swarm benchmark compare"):
        docgen.render_markers("<!-- benchmark-compare: b.json -->\n", root=tmp_path, data_dir=tmp_path)


def test_a_benchmark_table_needs_the_benchmark_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pybullet_swarm.experiment.benchmark", None)  # import fails
    (tmp_path / "b.json").write_text("{}")
    with pytest.raises(ConfigError, match=r"^b\.json: pybullet_swarm\.experiment\.benchmark\.markdown_table"):
        docgen.render_markers("<!-- benchmark-table: b.json -->\n", root=tmp_path, data_dir=tmp_path)
    # pages without that marker do not need it
    assert docgen.render_markers("no markers\n", root=tmp_path, data_dir=tmp_path) == "no markers\n"


@pytest.mark.slow
@pytest.mark.skipif(
    not all(importlib.util.find_spec(m) for m in ("mkdocs", "material", "mkdocstrings_handlers")),
    reason="needs the docs extra",
)
def test_the_site_builds_strictly(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert (tmp_path / "site" / "reference" / "parameters" / "index.html").is_file()
