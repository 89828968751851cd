"""Turn pydantic validation errors and YAML syntax errors into one-line ``ConfigError``s."""
from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

import pydantic
import yaml

from pybullet_swarm.errors import ConfigError

M = TypeVar("M", bound=pydantic.BaseModel)


def _short(value: Any, limit: int = 60) -> str:
    text = " ".join(repr(value).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _field_path(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "<root>"


def _expectation(err: dict[str, Any]) -> str:
    kind = err.get("type", "")
    ctx = err.get("ctx") or {}
    if kind == "missing":
        return "is required"
    if kind == "extra_forbidden":
        return "unknown field"
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
    return msg[0].lower() + msg[1:] if msg else "invalid value"


def from_pydantic(exc: pydantic.ValidationError, *, source: str | None, prefix: str = "") -> ConfigError:
    """The first error of ``exc`` as a one-line ``ConfigError``."""
    err = exc.errors(include_url=False)[0]
    loc = tuple(x for x in err.get("loc", ()) if not (isinstance(x, str) and x.startswith("function-")))
    path = _field_path(loc)
    if prefix:
        path = f"{prefix}.{path}" if path != "<root>" else prefix
    expect = _expectation(err)
    if err.get("type") == "missing":
        return ConfigError(expect, source=source, field=path)
    return ConfigError(f"{expect}, got {_short(err.get('input'))}", source=source, field=path)


def validate(model: type[M], data: Any, *, source: str | None, prefix: str = "") -> M:
    """Validate ``data`` against ``model``; bad data raise a one-line ``ConfigError``."""
    try:
        return model.model_validate(data)
    except pydantic.ValidationError as exc:
        raise from_pydantic(exc, source=source, prefix=prefix) from None


def read_yaml(path: Path) -> Any:
    """Parse a YAML file; syntax errors become one-line ``ConfigError``s naming the file."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError("file not found", source=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read file ({exc.__class__.__name__})", source=str(path)) from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "unknown position"
        problem = getattr(exc, "problem", None) or "syntax error"
        raise ConfigError(f"malformed YAML at {where}: {problem}", source=path.name) from None
