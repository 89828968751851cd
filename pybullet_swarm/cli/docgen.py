"""The documentation's generated parts: reference pages drawn from the code, result tables from JSON.

The docs site (``docs/hooks.py``, a MkDocs hook) replaces marker lines in its pages with what these
functions return, so that the reference follows the code and no result table is typed by hand:

- ``<!-- reference: cli -->``: ``cli_reference()``, every command and flag of ``pybullet-swarm``,
  read from its argparse parser;
- ``<!-- reference: scenario -->``: ``scenario_reference()``, every field of a scenario file, read
  from the pydantic models of ``experiment/scenario.py`` and of each task kind;
- ``<!-- reference: parameters -->``: ``parameter_reference()``, every parameter of every
  registered planner and avoidance layer, read from their parameter models;
- ``<!-- reference: presets -->``: ``preset_reference()``, what each preset of those models changes;
- ``<!-- results-table: NAME -->``: ``results_table(data)`` of ``docs/results/data/NAME.json``;
- ``<!-- benchmark-compare: PATH -->``: the benchmark module's ``compare_table`` of a JSON file
  written by ``pybullet-swarm benchmark compare A B --out PATH``;
- ``<!-- benchmark-table: PATH -->``: the benchmark module's own ``markdown_table`` of a JSON
  file written by ``pybullet-swarm benchmark``.

Tests use these functions without MkDocs. Descriptions of scenario fields are the fields'
``description`` or, where a field has none, the comment beside it or right above it in its model.
"""

from __future__ import annotations

import argparse
import ast
import datetime
import enum
import functools
import inspect
import io
import json
import math
import re
import textwrap
import tokenize
import types
import typing
from pathlib import Path
from typing import Any, Iterator

import pydantic

from pybullet_swarm.errors import ConfigError

#: keys of a results-table JSON file (``docs/results/data/NAME.json``), each with its expected type
RESULTS_TABLE_KEYS: dict[str, str] = {
    "title": "a non-empty string",
    "command": "a non-empty string",
    "commit": "a non-empty string",
    "date": "a date YYYY-MM-DD",
    "columns": "a non-empty list of strings",
    "rows": "a list of rows, each a list of numbers or strings as long as columns",
    "notes": "a list of strings",
}

MARKER = re.compile(
    r"^<!--\s*(reference|results-table|benchmark-table|benchmark-compare):\s*(\S+)\s*-->\s*$", re.MULTILINE
)


# ----------------------------------------------------------------- markdown helpers
def _cell(text: Any) -> str:
    """Text safe inside a Markdown table cell: one line; pipes, brackets and angle brackets escaped."""
    text = " ".join(str(text).split()).replace("|", "\\|").replace("[", "\\[").replace("]", "\\]")
    return text.replace("<", "&lt;").replace(">", "&gt;")


def _code(text: str) -> str:
    """A code span, or plain escaped text when the text holds a pipe (a pipe splits a table row)."""
    return _cell(text) if "|" in text else f"`{text}`"


def _table(columns: list[str], rows: list[list[str]], right: frozenset[int] | set[int] = frozenset()) -> str:
    head = "| " + " | ".join(_cell(c) for c in columns) + " |"
    rule = "|" + "|".join("---:" if i in right else "---" for i in range(len(columns))) + "|"
    body = ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join([head, rule, *body])


def _value(value: Any) -> str:
    """A default value as YAML would hold it."""
    if isinstance(value, enum.Enum):
        value = value.value
    if isinstance(value, pydantic.BaseModel):
        return "(section)"
    if value is None:
        return "`null`"
    return _code(json.dumps(value, default=str))


# ----------------------------------------------------------------- the command line
def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """(name, help, parser) of each subcommand of ``parser``, in the order they were added."""
    out = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            seen: set[int] = set()
            for name, sub in action.choices.items():
                if id(sub) not in seen:
                    seen.add(id(sub))
                    out.append((name, helps.get(name, ""), sub))
    return out


def _argument_rows(parser: argparse.ArgumentParser) -> list[list[str]]:
    rows = []
    for a in parser._actions:
        if isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)) or a.help == argparse.SUPPRESS:
            continue
        if a.option_strings:
            name = ", ".join(f"`{o}`" for o in a.option_strings)
            takes = a.nargs != 0
            metavar = a.metavar if isinstance(a.metavar, str) else a.dest.upper()
            value = (
                " \\| ".join(str(c) for c in a.choices)
                if a.choices
                else (_code(metavar) + (" ..." if a.nargs in ("*", "+", argparse.REMAINDER) else ""))
            )
            value = value if takes else "(switch)"
            default = "" if a.default in (None, False, argparse.SUPPRESS) or not takes else _value(a.default)
        else:
            name = f"`{a.metavar if isinstance(a.metavar, str) else a.dest}`"
            value = " \\| ".join(str(c) for c in a.choices) if a.choices else "(positional)"
            default = ""
        rows.append([name, value, default, _cell(a.help or "")])
    return rows


def _command_section(prog: str, help_text: str, parser: argparse.ArgumentParser, level: int) -> list[str]:
    usage = parser.format_usage().strip()
    usage = usage[len("usage: ") :] if usage.startswith("usage: ") else usage
    lines = [f"{'#' * level} `{prog}`", ""]
    if help_text:
        lines += [help_text[0].upper() + help_text[1:] + ("" if help_text.endswith(".") else "."), ""]
    lines += ["```text", usage, "```", ""]
    rows = _argument_rows(parser)
    if rows:
        lines += [_table(["argument", "value", "default", "description"], rows), ""]
    for name, sub_help, sub in _subcommands(parser):
        lines += _command_section(f"{prog} {name}", sub_help, sub, min(level + 1, 4))
    return lines


def cli_reference(parser: argparse.ArgumentParser | None = None) -> str:
    """Every command of ``pybullet-swarm`` with its usage and every flag (Markdown), from its argparse parser."""
    if parser is None:
        from pybullet_swarm.cli.main import build_parser

        parser = build_parser()
    lines = []
    if parser.description:
        lines += [parser.description, ""]
    for name, help_text, sub in _subcommands(parser):
        lines += _command_section(f"{parser.prog} {name}", help_text, sub, 2)
    return "\n".join(lines).rstrip() + "\n"


# ----------------------------------------------------------------- scenario fields
@functools.lru_cache(maxsize=None)
def _comments(cls: type) -> dict[str, str]:
    """Field name -> the comment beside its declaration in ``cls``'s body, or the comment lines right above it."""
    try:
        source = textwrap.dedent(inspect.getsource(cls))
    except (OSError, TypeError):
        return {}
    comments: dict[int, str] = {}
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            comments[tok.start[0]] = tok.string.lstrip("#").strip()
    lines = source.splitlines()
    body = ast.parse(source).body[0]
    out: dict[str, str] = {}
    for stmt in getattr(body, "body", []):
        if not (isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name)):
            continue
        above: list[str] = []
        n = stmt.lineno - 1
        while n >= 1 and n in comments and lines[n - 1].lstrip().startswith("#"):
            above.insert(0, comments[n])
            n -= 1
        beside = [comments[i] for i in range(stmt.lineno, (stmt.end_lineno or stmt.lineno) + 1) if i in comments]
        text = " ".join(t for t in [*above, *beside] if t and not t.startswith("---"))
        out[stmt.target.id] = text
    return out


def field_description(model: type[pydantic.BaseModel], name: str) -> str:
    """The description of a model's field: its ``description``, else its comment in the model's source."""
    f = model.model_fields[name]
    if f.description:
        return " ".join(f.description.split())
    for cls in model.__mro__:
        if isinstance(cls, type) and issubclass(cls, pydantic.BaseModel) and _comments(cls).get(name):
            return _comments(cls)[name]
    for inner in nested_models(f.annotation):  # a section: its model's own docstring
        if inner.__dict__.get("__doc__"):
            return " ".join(inspect.cleandoc(inner.__doc__ or "").split("\n\n")[0].split())
    return ""


def nested_models(annotation: Any) -> list[type[pydantic.BaseModel]]:
    """The pydantic models a field's annotation holds (``Obstacle`` in ``list[Obstacle] | None``)."""
    if isinstance(annotation, type) and issubclass(annotation, pydantic.BaseModel):
        return [annotation]
    out: list[type[pydantic.BaseModel]] = []
    for arg in typing.get_args(annotation):
        for m in nested_models(arg):
            if m not in out:
                out.append(m)
    return out


def _is_list(annotation: Any) -> bool:
    if typing.get_origin(annotation) is typing.Annotated:
        annotation = typing.get_args(annotation)[0]
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return any(_is_list(a) for a in typing.get_args(annotation) if a is not type(None))
    return typing.get_origin(annotation) in (list, tuple)


def model_fields(
    model: type[pydantic.BaseModel], prefix: str = ""
) -> Iterator[tuple[str, type[pydantic.BaseModel], str]]:
    """(dotted path, model, field name) of every field of ``model`` and of the models nested in it,
    depth first; a list of models adds ``[]`` to the path (``arena.obstacles[].shape``)."""
    for name, f in model.model_fields.items():
        path = f"{prefix}{name}"
        yield path, model, name
        for inner in nested_models(f.annotation):
            yield from model_fields(inner, f"{path}{'[]' if _is_list(f.annotation) else ''}.")


def _field_row(path: str, model: type[pydantic.BaseModel], name: str) -> list[str]:
    from pybullet_swarm.planning.params import field_info

    f = model.model_fields[name]
    info = field_info(name, f.annotation, f.metadata)
    if f.is_required():
        default = "required"
    else:
        default = _value(f.get_default(call_default_factory=True))
    kind = "section" if nested_models(f.annotation) and not _is_list(f.annotation) else info.type
    return [f"`{path}`", _cell(kind), default, _cell(info.range_text()), _cell(field_description(model, name))]


def _fields_table(model: type[pydantic.BaseModel], prefix: str = "") -> str:
    rows = [_field_row(path, m, name) for path, m, name in model_fields(model, prefix)]
    return _table(["field", "type", "default", "range", "description"], rows)


def scenario_reference() -> str:
    """Every field of a scenario file (Markdown): the top-level sections, then the ``task`` section of each task kind."""
    from pybullet_swarm.experiment.scenario import _ScenarioFile
    from pybullet_swarm.tasks import task_models

    lines = [
        "Every field a scenario file may hold, read from the models that validate it "
        "(`pybullet_swarm/experiment/scenario.py` and each task kind's model). A field left out takes its "
        "default; nested sections are written as YAML mappings, `[]` marks a list of them. "
        "`planner.params` and `avoidance_params` are checked against the chosen planner's and layer's "
        "parameter models (the [parameter reference](parameters.md)).",
        "",
        "## Scenario file",
        "",
        _fields_table(_ScenarioFile),
        "",
        "The `task` section's fields depend on its `kind`, which names the task; every kind has "
        "`time_limit_s` (s: a run still going then ends as `timeout`).",
        "",
    ]
    for kind, model in sorted(task_models().items()):
        lines += [f"## `task` of kind `{kind}`", ""]
        lines += [*_summary(model), _fields_table(model, "task."), ""]
    return "\n".join([*lines, *_layout_reference()]).rstrip() + "\n"


def _summary(model: type[Any]) -> list[str]:
    """The first paragraph of a model's own docstring, as one line (none when it has no docstring of its own)."""
    doc = model.__dict__.get("__doc__")
    return [" ".join(inspect.cleandoc(doc).split("\n\n")[0].split()), ""] if doc else []


def _layout_reference() -> list[str]:
    """The compact forms of ``task.structure`` and ``task.boxes``: voxels and named shapes."""
    from pybullet_swarm.tasks.layouts import SHAPES, Voxels

    lines = [
        "## Structures and depots",
        "",
        "`task.structure` and `task.boxes` of a construction task are lists of box centres `[x, y, z]`, "
        "or written compactly (`pybullet_swarm/tasks/layouts.py`): voxels, a named shape, or a list of "
        "several; they are expanded to box centres when the scenario loads. "
        "See [building your own structure](../guides/structures.md).",
        "",
        "### Voxels",
        "",
        *_summary(Voxels),
        _fields_table(Voxels, "task.structure.voxels."),
        "",
    ]
    for name, model in SHAPES.items():
        lines += [f"### Shape `{name}`", "", *_summary(model), _fields_table(model, "task.structure."), ""]
    return lines


# ----------------------------------------------------------------- plug-in parameters
def _params_section(title: str, description: str, model: type[Any], key: str, extra: str = "") -> list[str]:
    from pybullet_swarm.planning.params import describe

    lines = [f"### {title}", "", _cell(description) + (f" {extra}" if extra else ""), ""]
    infos = describe(model)
    if not infos:
        return [*lines, "No parameters.", ""]
    rows = [
        [
            f"`{key}.{p.name}`",
            _cell(p.type),
            _value(p.default),
            _cell(p.range_text()),
            _cell(p.description),
        ]
        for p in infos
    ]
    return [*lines, _table(["parameter", "type", "default", "range", "description"], rows), ""]


def parameter_reference() -> str:
    """Every parameter of every registered planner and avoidance layer (Markdown), from their parameter models."""
    from pybullet_swarm.planning.registry import avoidance_layers, planners

    lines = [
        "Every planner and avoidance layer declares its parameters as a typed model; a scenario sets them "
        "under `planner.params` and `avoidance_params`, and they are checked when it is loaded "
        "(`pybullet-swarm list` prints the same). A range is the values the model accepts.",
        "",
        "## Planners",
        "",
    ]
    for name, entry in planners().items():
        tasks = ", ".join(f"`{t}`" for t in entry.tasks)
        lines += _params_section(f"`{name}`", entry.description, entry.params, "planner.params", f"Tasks: {tasks}.")
    lines += ["## Avoidance layers", ""]
    for name, layer in avoidance_layers().items():
        lines += _params_section(f"`{name}`", layer.description, layer.params, "avoidance_params")
    return "\n".join(lines).rstrip() + "\n"


def preset_reference() -> str:
    """Every preset of every planner and avoidance layer (Markdown): the parameters it sets to a value other
    than the default, with both values and the parameter's description."""
    from pybullet_swarm.planning.params import describe, extensions
    from pybullet_swarm.planning.registry import avoidance_layers, planners

    plugins = [(name, e.params, "planner.params") for name, e in planners().items()]
    plugins += [(name, e.params, "avoidance_params") for name, e in avoidance_layers().items()]
    lines = []
    for name, model, key in plugins:
        descriptions = {p.name: p.description for p in describe(model)}
        for preset in model.PRESETS:
            changed = extensions(model, preset)
            lines += [
                f"### `{name}`: `{key}.preset: {preset.value}`",
                "",
                f"{len(changed)} parameters differ from the defaults.",
                "",
            ]
            rows = [
                [f"`{key}.{field}`", _value(default), _value(value), _cell(descriptions.get(field, ""))]
                for field, (value, default) in changed.items()
            ]
            lines += [_table(["parameter", "default", preset.value, "description"], rows), ""]
    return "\n".join(lines).rstrip() + "\n"


# ----------------------------------------------------------------- result tables
def _bad(source: str, key: str, got: Any) -> ConfigError:
    text = json.dumps(got, default=str)
    text = text if len(text) <= 40 else text[:37] + "..."
    return ConfigError(f"must be {RESULTS_TABLE_KEYS[key]}, got {text}", source=source, field=key)


def _is_cell(value: Any) -> bool:
    if isinstance(value, bool):
        return False
    if isinstance(value, (int, float)):
        return math.isfinite(value)
    return isinstance(value, str)


def check_results_table(data: Any, *, source: str) -> None:
    """Refuse (``ConfigError``, one line naming ``source`` and the key) data that is not a results table."""
    if not isinstance(data, dict):
        raise ConfigError(f"must be a JSON object with keys {', '.join(RESULTS_TABLE_KEYS)}", source=source)
    missing = [k for k in RESULTS_TABLE_KEYS if k not in data]
    unknown = [k for k in data if k not in RESULTS_TABLE_KEYS]
    if missing:
        raise ConfigError("missing key", source=source, field=missing[0])
    if unknown:
        raise ConfigError("unknown key", source=source, field=str(unknown[0]))
    for key in ("title", "command", "commit"):
        if not (isinstance(data[key], str) and data[key].strip()):
            raise _bad(source, key, data[key])
    try:
        if not isinstance(data["date"], str):
            raise ValueError
        datetime.date.fromisoformat(data["date"])
    except ValueError:
        raise _bad(source, "date", data["date"]) from None
    columns = data["columns"]
    if not (isinstance(columns, list) and columns and all(isinstance(c, str) for c in columns)):
        raise _bad(source, "columns", columns)
    rows = data["rows"]
    if not isinstance(rows, list):
        raise _bad(source, "rows", rows)
    for i, row in enumerate(rows):
        if not (isinstance(row, list) and len(row) == len(columns) and all(_is_cell(c) for c in row)):
            raise ConfigError(
                f"must be a list of {len(columns)} numbers or strings, got {json.dumps(row, default=str)[:40]}",
                source=source,
                field=f"rows[{i}]",
            )
    notes = data["notes"]
    if not (isinstance(notes, list) and all(isinstance(n, str) for n in notes)):
        raise _bad(source, "notes", notes)


def _number(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def results_table(data: Any, *, source: str = "results table") -> str:
    """A results-table JSON object rendered as Markdown: title, table, command, commit, date and notes.

    Raises ``ConfigError`` (one line naming ``source`` and the key) when ``data`` does not follow
    the schema of ``RESULTS_TABLE_KEYS``.
    """
    check_results_table(data, source=source)
    columns, rows = data["columns"], data["rows"]
    numeric = {i for i in range(len(columns)) if rows and all(not isinstance(r[i], str) for r in rows)}
    body = [[_cell(_number(c)) for c in row] for row in rows]
    lines = [
        f"**{_cell(data['title'])}**",
        "",
        _table(columns, body, numeric),
        "",
        f"Measured with `{' '.join(data['command'].split())}` on commit `{data['commit']}`, "
        f"{data['date']} (data: `{source}`).",
        "",
    ]
    lines += [f"- {' '.join(n.split())}" for n in data["notes"]]
    return "\n".join(lines).rstrip() + "\n"


def read_json(path: Path, *, source: str) -> Any:
    """A JSON file's content; ``ConfigError`` naming ``source`` when it is missing or not JSON."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError("no such file", source=source) from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ConfigError(f"not readable JSON ({exc.__class__.__name__}: {exc})", source=source) from None


def results_table_file(name: str, data_dir: Path, *, source: str | None = None) -> str:
    """``results_table`` of ``data_dir/NAME.json`` (``ConfigError`` for a missing or malformed file)."""
    if not re.fullmatch(r"[A-Za-z0-9_.-]+", name) or name.startswith("."):
        raise ConfigError(f"a results table is named by letters, digits and . _ -, got {name!r}")
    path = data_dir / f"{name}.json"
    src = source or str(path)
    return results_table(read_json(path, source=src), source=src)


def benchmark_table_file(path: str, root: Path) -> str:
    """A benchmark JSON file (``path`` relative to ``root``) rendered by the benchmark module's ``markdown_table``."""
    try:
        from pybullet_swarm.experiment.benchmark import markdown_table
    except ImportError:
        raise ConfigError(
            "pybullet_swarm.experiment.benchmark.markdown_table is not available to render it", source=path
        ) from None
    return str(markdown_table(read_json(root / path, source=path)))


def benchmark_compare_file(path: str, root: Path) -> str:
    """A ``benchmark compare`` JSON file (``path`` relative to ``root``) rendered by ``compare_table``."""
    from pybullet_swarm.experiment.benchmark import compare_table

    data = read_json(root / path, source=path)
    if not isinstance(data, dict) or data.get("kind") != "pybullet_swarm.benchmark_compare":
        raise ConfigError("is not the JSON of `pybullet-swarm benchmark compare --out`", source=path)
    return str(compare_table(data))


#: a generated block of the README (read on GitHub, where no hook runs): the marker, the table, the end marker
README_BLOCK = re.compile(r"(<!-- benchmark-table: (\S+) -->\n)(.*?)(<!-- /benchmark-table -->)", re.DOTALL)


def refresh_readme(text: str, root: Path) -> str:
    """The README with every block between ``<!-- benchmark-table: PATH -->`` and ``<!-- /benchmark-table -->``
    rendered again from its benchmark JSON (``scripts/readme_results.py`` writes it; a test checks it is current).
    """

    def replace(match: re.Match[str]) -> str:
        table = benchmark_table_file(match.group(2), root).rstrip("\n")
        return f"{match.group(1)}{table}\n{match.group(4)}"

    return README_BLOCK.sub(replace, text)


def render_markers(markdown: str, *, root: Path, data_dir: Path) -> str:
    """Replace every marker line of a page (see the module's docstring) with what it names; markers
    inside fenced code blocks are left as they are.

    Raises ``ConfigError`` (one line) for an unknown reference, a missing or malformed results
    file, or a benchmark table when the benchmark module is not there.
    """
    generators = {
        "cli": cli_reference,
        "scenario": scenario_reference,
        "parameters": parameter_reference,
        "presets": preset_reference,
    }

    def generate(kind: str, arg: str) -> str:
        if kind == "reference":
            if arg not in generators:
                raise ConfigError(f"unknown reference {arg!r}; one of {', '.join(generators)}")
            return generators[arg]()
        if kind == "results-table":
            source = (data_dir / f"{arg}.json").relative_to(root) if data_dir.is_relative_to(root) else None
            return results_table_file(arg, data_dir, source=str(source) if source else None)
        if kind == "benchmark-compare":
            return benchmark_compare_file(arg, root)
        return benchmark_table_file(arg, root)

    def replace(match: re.Match[str]) -> str:  # a block of its own: a blank line after it
        return generate(match.group(1), match.group(2)).rstrip("\n") + "\n\n"

    out, fence = [], ""
    for line in markdown.splitlines(keepends=True):  # markers inside fenced code stay as they are
        stripped = line.lstrip()
        if fence and stripped.startswith(fence):
            fence = ""
        elif not fence and stripped.startswith(("```", "~~~")):
            fence = stripped[:3]
        elif not fence:
            line = MARKER.sub(replace, line)
        out.append(line)
    return "".join(out)
