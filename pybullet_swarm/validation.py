"""Turn pydantic validation errors and YAML syntax errors into one-line ``ConfigError``s."""

from __future__ import annotations

import math
import re
import unicodedata
from pathlib import Path
from collections.abc import Mapping
from typing import Any, TypeVar

import pydantic
import yaml

from pybullet_swarm.errors import ConfigError

M = TypeVar("M", bound=pydantic.BaseModel)


MAX_DEPTH = 32  # deepest nesting of mappings and lists accepted in a configuration file
MAX_INT_BITS = 64  # largest integer of a configuration: 64 bits (a seed takes 63)
MAX_FLOAT = 1e12  # largest magnitude of a real number of a configuration (beyond, geometry overflows)
MIN_FLOAT = 1e-12  # smallest magnitude of a non-zero real number (below, its inverse overflows)
MAX_BYTES = 1 << 20  # largest configuration file read, bytes (a 10,000-point tour takes about 300 KB)
MAX_NODES = 250_000  # most values a document may hold with its aliases expanded


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


def _is_type_mismatch(err: Mapping[str, Any]) -> bool:
    kind = str(err.get("type", ""))
    return kind.endswith("_type") or kind in ("none_required", "is_instance_of")


def _expectation(err: Mapping[str, Any]) -> str:
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


def from_pydantic(
    exc: pydantic.ValidationError, *, source: str | None, prefix: str = "", data: Any = None
) -> ConfigError:
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
    if err.get("type") == "missing" or _rule_field(err):  # a rule's message says what it got
        return ConfigError(expect, source=source, field=path or None)
    return ConfigError(f"{expect}, got {_short(err.get('input'))}", source=source, field=path or None)


def validate(model: type[M], data: Any, *, source: str | None, prefix: str = "") -> M:
    """Validate ``data`` against ``model``; bad data raise a one-line ``ConfigError``."""
    try:
        return model.model_validate(data)
    except pydantic.ValidationError as exc:
        raise from_pydantic(exc, source=source, prefix=prefix, data=data) from None


#: characters that change the direction of the text around them (bidirectional embeddings, overrides,
#: isolates and marks): a name holding them is drawn in another order than it reads in the file
BIDI_CONTROLS = frozenset("\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")


def check_drawable_text(value: str, *, source: str | None, field: str) -> None:
    """Refuse text that figures, titles and terminals cannot show as written: control characters
    (Unicode category Cc, line and paragraph separators, surrogates) and bidirectional controls.

    Raises:
        ConfigError: naming ``field`` and the first such character (as ``U+XXXX``) and where it is.
    """
    for i, ch in enumerate(value):
        if ch in BIDI_CONTROLS:
            what = "a bidirectional control character"
        elif unicodedata.category(ch) in ("Cc", "Cs", "Zl", "Zp"):
            what = "a control character"
        else:
            continue
        raise ConfigError(
            f"must be text without control or bidirectional-override characters, got {what} "
            f"U+{ord(ch):04X} at position {i}",
            source=source,
            field=field,
        )


def check_plain(data: Any, *, source: str | None, max_depth: int = MAX_DEPTH, finite: bool = True) -> None:
    """Refuse data that cannot be validated, resolved and written back as YAML.

    YAML aliases can build a list that contains itself, nesting can be deep enough to overflow
    the validators and serialisers, integers can be too large to print, and (with ``finite``) a
    ``.nan``, an ``.inf``, a real number beyond ``MAX_FLOAT`` (whose squares overflow in the
    geometry) or a non-zero one below ``MIN_FLOAT`` (whose inverse overflows) means nothing anywhere
    in a configuration: each is a ``ConfigError``
    naming the field. Checking every number here also covers sections whose models are written
    elsewhere (task and planner models).
    """
    done: dict[int, int] = {}  # id of a container checked -> depth it was checked at
    on_path: set[int] = set()

    def walk(node: Any, path: str, depth: int) -> None:
        if finite and isinstance(node, float) and not math.isfinite(node):
            raise ConfigError(f"must be a finite number, got {node!r}", source=source, field=path or None)
        if finite and isinstance(node, float) and abs(node) > MAX_FLOAT:
            raise ConfigError(
                f"must be a number of magnitude at most {MAX_FLOAT:g}, got {node!r}", source=source, field=path or None
            )
        if finite and isinstance(node, float) and node != 0.0 and abs(node) < MIN_FLOAT:
            raise ConfigError(
                f"must be 0 or a number of magnitude at least {MIN_FLOAT:g}, got {node!r}",
                source=source,
                field=path or None,
            )
        if isinstance(node, int) and not isinstance(node, bool) and node.bit_length() > MAX_INT_BITS:
            raise ConfigError(
                f"must be an integer of at most {MAX_INT_BITS} bits, got {_short(node)}",
                source=source,
                field=path or None,
            )
        if not isinstance(node, (dict, list, tuple, set, frozenset)):
            return
        key = id(node)
        if key in on_path:
            raise ConfigError(
                f"must not contain itself (a cyclic YAML alias), got {_short(node)}", source=source, field=path or None
            )
        if depth > max_depth:
            raise ConfigError(
                f"must be nested at most {max_depth} levels deep, got more", source=source, field=path or None
            )
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
    """The safe loader with limits, refusing a key that appears twice in one mapping.

    YAML forbids duplicate keys; the plain loader silently keeps the last one, so a second
    ``sim:`` section would replace the first. Before anything is constructed, the composed
    document is measured with every alias expanded (``_check_expansion``): a few hundred bytes of
    nested anchors ("billion laughs") would otherwise expand to billions of values in the
    validators. Floats are also read the way a person writes them (``1e6``, not only YAML 1.1's
    ``1.0e+6``).
    """

    def get_single_node(self) -> yaml.Node | None:
        node = super().get_single_node()
        if node is not None:
            _check_expansion(node)
        self._root = node
        return node

    def construct_object(self, node: yaml.Node, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep=deep)
        except (ValueError, TypeError, OverflowError, KeyError, AttributeError, IndexError) as exc:
            # an explicit tag on a value it does not fit (`!!int abc`, `!!bool maybe`) fails inside
            # PyYAML's constructors: report the value and where it is
            tag = str(node.tag).replace("tag:yaml.org,2002:", "!!")
            value = node.value if isinstance(node, yaml.ScalarNode) else f"<{type(node).__name__}>"
            reason = (
                "not a value of this type"
                if isinstance(exc, (KeyError, AttributeError, IndexError))
                else " ".join(str(exc).split(";")[0].split()) or exc.__class__.__name__
            )
            raise YamlValueError(
                f"cannot read {tag} {_short(value, 30)} ({reason[:100]})",
                node.start_mark,
                _node_path(getattr(self, "_root", None), node),
            ) from None

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
                        "while constructing a mapping",
                        node.start_mark,
                        f"found duplicate key {key!r}",
                        key_node.start_mark,
                    )
                seen.add(key)
        return super().construct_mapping(node, deep=deep)


# YAML 1.1 reads `1e6` and `1.5e3` as strings (its floats need a dot and a signed exponent:
# `1.0e+6`); a person writing a number means a number. Floats YAML 1.1 already reads keep their
# resolver; this one, consulted after the int resolver, adds exponents without a dot or a sign.
_EXPONENT_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9][0-9_]*)[eE][-+]?[0-9]+$")
_UniqueKeyLoader.add_implicit_resolver("tag:yaml.org,2002:float", _EXPONENT_FLOAT, list("-+0123456789."))


class YamlValueError(yaml.YAMLError):
    """A scalar that its tag's constructor cannot read, with the field path where it is."""

    def __init__(self, message: str, mark: Any, field: str | None) -> None:
        super().__init__(message)
        self.problem = message
        self.problem_mark = mark
        self.field = field


def _node_path(root: yaml.Node | None, target: yaml.Node) -> str | None:
    """The field path (``task.waypoints[1].t_s``) of ``target`` in the composed document, if found."""
    if root is None:
        return None
    seen: set[int] = set()
    stack: list[tuple[yaml.Node, str]] = [(root, "")]
    while stack:
        node, path = stack.pop()
        if node is target:
            return path or None
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.SequenceNode):
            stack.extend((child, f"{path}[{i}]") for i, child in enumerate(node.value))
        elif isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                name = str(key.value) if isinstance(key, yaml.ScalarNode) else "?"
                stack.append((value, f"{path}.{name}" if path else name))
                stack.append((key, f"{path}.{name}" if path else name))
    return None


class YamlTooLarge(yaml.YAMLError):
    """A YAML document that expands (aliases included) to more values than ``MAX_NODES``."""

    def __init__(self, message: str, mark: Any) -> None:
        super().__init__(message)
        self.problem = message
        self.problem_mark = mark


def _check_expansion(root: yaml.Node, limit: int | None = None) -> int:
    """Number of values the document holds with every alias expanded; refuse more than ``limit``.

    Counted on the composed node graph, where an alias is the anchored node itself: each node's
    expanded size is computed once (memoised), so a billion-laughs document is measured in time
    proportional to its text. An alias to a node still being composed (a recursive structure)
    is counted once and left to ``check_plain``, which names its field.

    Raises:
        YamlTooLarge: more than ``limit`` (default ``MAX_NODES``) values.
    """
    limit = MAX_NODES if limit is None else limit
    size: dict[int, int] = {}
    on_path: set[int] = set()
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        children: list[yaml.Node] = []
        if isinstance(node, yaml.SequenceNode):
            children = list(node.value)
        elif isinstance(node, yaml.MappingNode):
            children = [n for pair in node.value for n in pair]
        if done:
            on_path.discard(key)
            total = 1 + sum(size.get(id(c), 1) for c in children)
            size[key] = total
            if total > limit:
                raise YamlTooLarge(
                    f"the document expands to more than {limit} values (YAML aliases or anchors "
                    f"repeated); at most {limit} are accepted",
                    node.start_mark,
                )
            continue
        if key in size or key in on_path:
            continue  # measured already, or a recursive alias (counted as one value)
        on_path.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in children if id(c) not in size and id(c) not in on_path)
    return size.get(id(root), 1)


def parse_yaml(text: str, *, source: str | None) -> Any:
    """Parse YAML text; syntax errors, duplicate keys, unconstructible values (``2020-13-45``,
    ``!!int abc``) and documents too large (``MAX_BYTES``, ``MAX_NODES`` with aliases expanded)
    become one-line ``ConfigError``s naming ``source``."""
    if len(text) > MAX_BYTES:
        raise ConfigError(
            f"too large: more than {MAX_BYTES} characters (a configuration file holds at most {MAX_BYTES // 1024} KiB)",
            source=source,
        )
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except YamlTooLarge as exc:
        raise ConfigError(f"too large: {exc.problem}", source=source) from None
    except YamlValueError as exc:
        mark = exc.problem_mark
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        raise ConfigError(f"{exc.problem}{where}", source=source, field=exc.field) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "unknown position"
        problem = getattr(exc, "problem", None) or "syntax error"
        raise ConfigError(f"malformed YAML at {where}: {problem}", source=source) from None
    except RecursionError:
        raise ConfigError("malformed YAML: nested too deeply", source=source) from None
    except (ValueError, TypeError, OverflowError, KeyError, AttributeError, IndexError) as exc:
        # an explicit tag on a value it does not fit (`!!bool maybe`, `!!timestamp 1`) fails inside PyYAML
        reason = " ".join(str(exc).split()) or exc.__class__.__name__
        raise ConfigError(f"malformed YAML: a value cannot be read ({reason[:120]})", source=source) from None


def read_yaml(path: Path) -> Any:
    """Parse a YAML file of at most ``MAX_BYTES``; every problem is a one-line ``ConfigError`` naming the file."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_BYTES + 1)
    except FileNotFoundError:
        raise ConfigError("file not found", source=str(path)) from None
    except OSError as exc:
        raise ConfigError(f"cannot read file ({exc.__class__.__name__})", source=str(path)) from None
    if len(raw) > MAX_BYTES:
        raise ConfigError(
            f"too large: more than {MAX_BYTES} bytes (a configuration file holds at most {MAX_BYTES // 1024} KiB)",
            source=path.name,
        )
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"cannot read file ({exc.__class__.__name__}: not UTF-8 text)", source=str(path)) from None
    if "\x00" in text:
        raise ConfigError("cannot read file (binary data: NUL characters)", source=str(path))
    return parse_yaml(text, source=path.name)
