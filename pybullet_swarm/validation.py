"""Turn pydantic validation errors and YAML syntax errors into one-line ``ConfigError``s."""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any, TypeVar

import pydantic
import yaml

from pybullet_swarm.errors import ConfigError

M = TypeVar("M", bound=pydantic.BaseModel)


MAX_DEPTH = 32          # deepest nesting of mappings and lists accepted in a configuration file
MAX_INT_BITS = 10_000   # larger integers cannot even be printed (Python's int-to-str digit limit)


def _short(value: Any, limit: int = 60) -> str:
    try:
        text = " ".join(repr(value).split())
    except (ValueError, RecursionError):  # e.g. an int beyond the int-to-str digit limit
        text = f"<{type(value).__name__} too large to show>"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _field_path(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int) and not isinstance(part, bool):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def _clean_loc(loc: tuple[Any, ...], data: Any, kind: str) -> tuple[Any, ...]:
    """The part of a pydantic error location that names the user's data.

    Union members add tags such as ``'constrained-float'`` or ``'list[constrained-float]'`` and
    validators ``'function-after[...]'``: they are not keys of the data, so they are dropped by
    walking ``data`` along ``loc``. An error about a mapping key (``'[key]'``, ``invalid_key``)
    is reported at the mapping.
    """
    out: list[Any] = []
    node = data
    for i, part in enumerate(loc):
        last = i == len(loc) - 1
        if part == "[key]":
            return tuple(out[:-1])
        if isinstance(node, dict) and not isinstance(part, bool) and part in node:
            if last and kind == "invalid_key":
                return tuple(out)
            out.append(part)
            node = node[part]
        elif isinstance(part, int) and isinstance(node, (list, tuple)) and 0 <= part < len(node):
            out.append(part)
            node = node[part]
        elif isinstance(part, str) and not (last and kind == "missing"):
            continue  # a union-member tag or validator name, not a field
        else:
            out.append(part)
            node = None
    return tuple(out)


def _is_type_mismatch(err: dict[str, Any]) -> bool:
    kind = str(err.get("type", ""))
    return kind.endswith("_type") or kind in ("none_required", "is_instance_of")


def _expectation(err: dict[str, Any]) -> str:
    kind = err.get("type", "")
    ctx = err.get("ctx") or {}
    if kind == "missing":
        return "is required"
    if kind == "extra_forbidden":
        return "unknown field"
    if kind == "invalid_key" or "[key]" in err.get("loc", ()):
        return "keys must be strings"
    if kind == "too_short":
        n = ctx.get("min_length", "?")
        return f"must have at least {n} item{'' if n == 1 else 's'}"
    if kind == "too_long":
        n = ctx.get("max_length", "?")
        return f"must have at most {n} item{'' if n == 1 else 's'}"
    if kind in ("greater_than_equal", "greater_than", "less_than_equal", "less_than"):
        op = {"greater_than_equal": ">=", "greater_than": ">", "less_than_equal": "<=", "less_than": "<"}[kind]
        bound = next(iter(ctx.values())) if ctx else "?"
        return f"must be {op} {bound}"
    if kind == "value_error":
        msg = str(ctx.get("error", err.get("msg", "")))
        return msg
    msg = str(err.get("msg", "invalid value"))
    # pydantic phrases start with "Input should be ...": keep the expectation, lower-cased.
    msg = msg.replace("Input should be", "must be").replace("Value error, ", "")
    msg = re.sub(r" or instance of \w+", "", msg)
    return msg[0].lower() + msg[1:] if msg else "invalid value"


def _rule_field(err: Any) -> tuple[str, ...]:
    """The field a model validator blamed: a ValueError it raised with a ``field`` attribute (e.g.
    ``planning.params.ParamRuleError``) is reported at that field."""
    field = getattr((err.get("ctx") or {}).get("error"), "field", None)
    return (field,) if err.get("type") == "value_error" and isinstance(field, str) and field else ()


def from_pydantic(exc: pydantic.ValidationError, *, source: str | None, prefix: str = "",
                  data: Any = None) -> ConfigError:
    """The first error of ``exc`` as a one-line ``ConfigError``.

    ``data`` (what was validated) tells field names from union-member tags. When the first field
    failed every member of a union, the member whose type matched but whose constraint failed is
    reported (``[1, 2]`` for ``float | list of 3``: "must have at least 3 items"); when no member
    matched the type, the expectations are joined ("must be a valid number or a valid list").
    """
    errors = exc.errors(include_url=False)
    items = [(_clean_loc(tuple(e.get("loc", ())), data, str(e.get("type", ""))) + _rule_field(e), e) for e in errors]
    loc0 = items[0][0]
    group = [(loc, e) for loc, e in items if loc[: len(loc0)] == loc0]
    specific = [(loc, e) for loc, e in group if not _is_type_mismatch(e)]
    if specific:
        loc, err = specific[0]
        expect = _expectation(err)
    else:
        loc, err = loc0, items[0][1]
        expects: list[str] = []
        for x in (_expectation(e) for where, e in group if where == loc0):
            if x not in expects:
                expects.append(x)
        expect = expects[0] + "".join(" or " + x.removeprefix("must be ") for x in expects[1:])
    path = _field_path(loc)
    if prefix:
        path = f"{prefix}.{path}" if path else prefix
    if err.get("type") == "missing" or _rule_field(err):   # a rule's message says what it got
        return ConfigError(expect, source=source, field=path or None)
    return ConfigError(f"{expect}, got {_short(err.get('input'))}", source=source, field=path or None)


def validate(model: type[M], data: Any, *, source: str | None, prefix: str = "") -> M:
    """Validate ``data`` against ``model``; bad data raise a one-line ``ConfigError``."""
    try:
        return model.model_validate(data)
    except pydantic.ValidationError as exc:
        raise from_pydantic(exc, source=source, prefix=prefix, data=data) from None


def check_plain(data: Any, *, source: str | None, max_depth: int = MAX_DEPTH) -> None:
    """Refuse data that cannot be validated, resolved and written back as YAML.

    YAML aliases can build a list that contains itself, nesting can be deep enough to overflow
    the validators and serialisers, and integers can be too large to print: each is a
    ``ConfigError`` naming the field.
    """
    done: dict[int, int] = {}   # id of a container checked -> depth it was checked at
    on_path: set[int] = set()

    def walk(node: Any, path: str, depth: int) -> None:
        if isinstance(node, int) and not isinstance(node, bool) and node.bit_length() > MAX_INT_BITS:
            raise ConfigError(f"must be an integer of at most {MAX_INT_BITS} bits, got {_short(node)}",
                              source=source, field=path or None)
        if not isinstance(node, (dict, list, tuple, set, frozenset)):
            return
        key = id(node)
        if key in on_path:
            raise ConfigError(f"must not contain itself (a cyclic YAML alias), got {_short(node)}", source=source,
                              field=path or None)
        if depth > max_depth:
            raise ConfigError(f"must be nested at most {max_depth} levels deep, got more", source=source,
                              field=path or None)
        if done.get(key, -1) >= depth:
            return  # a shared (aliased) container already checked at this depth or deeper
        on_path.add(key)
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, f"{path}.{k}" if path else str(k), depth + 1)
        else:
            for i, v in enumerate(node):
                walk(v, f"{path}[{i}]", depth + 1)
        on_path.discard(key)
        done[key] = depth

    walk(data, "", 0)


class _UniqueKeyLoader(yaml.SafeLoader):
    """The safe loader, refusing a key that appears twice in one mapping (YAML forbids it; the
    plain loader silently keeps the last one, so a second ``sim:`` section would replace the first)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:  # type: ignore[override]
        if isinstance(node, yaml.MappingNode):
            seen: set[Any] = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=deep)
                try:
                    duplicate = key in seen
                except TypeError:
                    continue  # unhashable: the base class reports it
                if duplicate:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping", node.start_mark, f"found duplicate key {key!r}",
                        key_node.start_mark)
                seen.add(key)
        return super().construct_mapping(node, deep=deep)


def parse_yaml(text: str, *, source: str | None) -> Any:
    """Parse YAML text; syntax errors, duplicate keys and unconstructible values (``2020-13-45``,
    ``!!int abc``) become one-line ``ConfigError``s naming ``source``."""
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "unknown position"
        problem = getattr(exc, "problem", None) or "syntax error"
        raise ConfigError(f"malformed YAML at {where}: {problem}", source=source) from None
    except RecursionError:
        raise ConfigError("malformed YAML: nested too deeply", source=source) from None
    except (ValueError, TypeError, OverflowError) as exc:
        raise ConfigError(f"malformed YAML: a value cannot be read ({exc})", source=source) from None


def read_yaml(path: Path) -> Any:
    """Parse a YAML file; syntax errors become one-line ``ConfigError``s naming the file."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError("file not found", source=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read file ({exc.__class__.__name__})", source=str(path)) from None
    return parse_yaml(text, source=path.name)
