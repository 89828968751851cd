"""Objective expressions over the flattened metrics of a run, and the score of a run.

An objective is an arithmetic expression whose names are metric columns of a run's row (see
``experiment.results.metrics_row``): ``completion_time_s + 20 * collisions.agent_agent``.
The text is parsed with ``ast`` and only a whitelist of nodes is accepted: numbers, metric names
(dotted: ``collisions.agent_agent``), ``+ - * / ** //``, unary ``-``/``+`` and the functions
``min``, ``max``, ``abs``, ``sqrt``, ``log``, ``exp``. Nothing is ever passed to ``eval``.

**Runs that do not complete.** A run whose ``exit_status`` is not ``completed`` (timeout, crash,
divergence) has no ``completion_time_s``; it is scored with ``completion_time_s`` taken as the
simulated time it reached (the time limit, for a timeout), and then ``penalty`` is added to
every objective in its worse direction (added when minimising, subtracted when maximising).
With the default penalty of 500 (in the objective's units) an incomplete run always scores
worse than a completed one of the construction task, whose time limit is 500 s. A run that
raised (``exit_status = error``) has no score: its trial is recorded as failed.
"""

from __future__ import annotations

import ast
import dataclasses
import difflib
import enum
import math
import operator
from typing import Any, Callable, Iterable, Mapping, Sequence

from pybullet_swarm.errors import ConfigError

DEFAULT_OBJECTIVE = "completion_time_s + 20 * collisions.agent_agent"
"""Default objective: seconds to finish the task, plus 20 s per agent-agent collision onset."""
DEFAULT_PENALTY = 500.0
"""Added (in the worse direction) to each objective of a run that does not complete."""
INCOMPLETE_FILL: Mapping[str, str] = {"completion_time_s": "sim_time_s"}
"""Metrics an incomplete run lacks, and the metric whose value stands in for them."""

_BINOPS: dict[type, Callable[[float, float], float]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
    ast.FloorDiv: operator.floordiv,
}
_UNARY: dict[type, Callable[[float], float]] = {ast.USub: operator.neg, ast.UAdd: operator.pos}
_FUNCTIONS: dict[str, tuple[Callable[..., float], int, int | None]] = {  # name: (function, min args, max args)
    "min": (min, 2, None),
    "max": (max, 2, None),
    "abs": (abs, 1, 1),
    "sqrt": (math.sqrt, 1, 1),
    "log": (math.log, 1, 1),
    "exp": (math.exp, 1, 1),
}

Evaluator = Callable[[Mapping[str, Any]], float]

MAX_CHARS = 2000  # longest objective expression
MAX_NODES = 500  # most syntax-tree nodes (numbers, names, operators) in one expression
MAX_DEPTH = 60  # deepest nesting of an expression (compiled and evaluated by recursion)


class Direction(str, enum.Enum):
    """Whether an objective is minimised or maximised."""

    MINIMIZE = "minimize"
    MAXIMIZE = "maximize"

    @classmethod
    def parse(cls, text: str, *, source: str = "--directions") -> Direction:
        """``minimize``/``min`` or ``maximize``/``max``."""
        if isinstance(text, Direction):
            return text
        t = str(text).strip().lower()
        aliases = {"min": cls.MINIMIZE, "max": cls.MAXIMIZE}
        if t in aliases:
            return aliases[t]
        try:
            return cls(t)
        except ValueError:
            raise ConfigError(f"must be minimize or maximize, got {text!r}", source=source) from None


class MissingMetric(ValueError):
    """A run has no value for a metric an objective needs."""


@dataclasses.dataclass(frozen=True)
class Objective:
    """One parsed objective expression.

    Attributes:
        text: the expression as given.
        direction: minimise or maximise.
        names: the metric names the expression reads, in order of appearance.
    """

    text: str
    direction: Direction
    names: tuple[str, ...]
    _fn: Evaluator = dataclasses.field(repr=False, compare=False)

    def evaluate(self, metrics: Mapping[str, Any]) -> float:
        """The expression's value on one run's flattened metrics.

        Raises:
            MissingMetric: a metric it reads is absent, empty or not a number.
        """
        try:
            value = float(self._fn(metrics))
        except (ZeroDivisionError, OverflowError, ValueError) as exc:
            if isinstance(exc, MissingMetric):
                raise
            return math.nan
        return value

    def worse_by(self, value: float, penalty: float) -> float:
        """``value`` moved by ``penalty`` in this objective's worse direction."""
        return value + penalty if self.direction is Direction.MINIMIZE else value - penalty


def parse_objective(
    text: str, direction: Direction | str = Direction.MINIMIZE, *, source: str = "--objective"
) -> Objective:
    """Parse one expression (whitelisted ``ast`` nodes only).

    Raises:
        ConfigError: one line naming ``source``, for syntax errors or anything not whitelisted.
    """
    if not isinstance(text, str) or not text.strip():
        raise ConfigError(f"expected an expression over metric names, got {text!r}", source=source)
    if len(text) > MAX_CHARS:
        raise ConfigError(f"expression too long: {len(text)} characters, at most {MAX_CHARS}", source=source)
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise ConfigError(f"not a valid expression ({exc.msg}), got {_clip(text)!r}", source=source) from None
    except (RecursionError, MemoryError):
        raise ConfigError(f"expression nested too deeply (at most {MAX_DEPTH} levels)", source=source) from None
    nodes, depth = _size(tree.body)
    if nodes > MAX_NODES or depth > MAX_DEPTH:
        raise ConfigError(
            f"expression too large: {nodes} terms nested {depth} levels deep, at most {MAX_NODES} "
            f"terms and {MAX_DEPTH} levels",
            source=source,
        )
    names: list[str] = []
    fn = _compile(tree.body, names, source, text)
    return Objective(text=text.strip(), direction=Direction.parse(direction), names=tuple(dict.fromkeys(names)), _fn=fn)


def _size(root: ast.AST) -> tuple[int, int]:
    """(number of nodes, depth) of an expression tree, walked without recursion."""
    count, deepest = 0, 0
    stack = [(root, 1)]
    while stack:
        node, depth = stack.pop()
        count += 1
        deepest = max(deepest, depth)
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))
    return count, deepest


def _clip(text: str, limit: int = 80) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _dotted(node: ast.AST) -> str | None:
    """``a.b.c`` of a Name/Attribute chain, else None."""
    parts: list[str] = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
        return ".".join(reversed(parts))
    return None


def _compile(node: ast.AST, names: list[str], source: str, text: str) -> Evaluator:
    if isinstance(node, ast.Constant):
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"only numbers and metric names are allowed, got {value!r} in {text!r}", source=source)
        constant = float(value)

        def const(m: Mapping[str, Any]) -> float:
            return constant

        return const
    if isinstance(node, (ast.Name, ast.Attribute)):
        name = _dotted(node)
        if name is None:
            raise ConfigError(f"not a metric name: {ast.unparse(node)!r} in {text!r}", source=source)
        names.append(name)
        key = name

        def metric(m: Mapping[str, Any]) -> float:
            return _metric(m, key)

        return metric
    if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
        op = _BINOPS[type(node.op)]
        left, right = _compile(node.left, names, source, text), _compile(node.right, names, source, text)
        return lambda m: op(left(m), right(m))
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        uop = _UNARY[type(node.op)]
        operand = _compile(node.operand, names, source, text)
        return lambda m: uop(operand(m))
    if (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id in _FUNCTIONS
        and not node.keywords
    ):
        func, lo, hi = _FUNCTIONS[node.func.id]
        if len(node.args) < lo or (hi is not None and len(node.args) > hi):
            want = str(lo) if hi == lo else f"at least {lo}"
            raise ConfigError(
                f"{node.func.id}() takes {want} argument(s), got {len(node.args)} in {text!r}", source=source
            )
        args = [_compile(a, names, source, text) for a in node.args]
        return lambda m: func(*(a(m) for a in args))
    what = ast.unparse(node) if isinstance(node, ast.expr) else type(node).__name__
    raise ConfigError(
        f"not allowed in an objective: {what!r} (use numbers, metric names, + - * / ** and "
        f"{', '.join(_FUNCTIONS)}) in {text!r}",
        source=source,
    )


def _metric(metrics: Mapping[str, Any], name: str) -> float:
    value = metrics.get(name)
    if value is None or isinstance(value, (bool, str)) or not isinstance(value, (int, float)):
        raise MissingMetric(f"metric {name} has no numeric value (got {value!r})")
    return float(value)


def split_expressions(text: str) -> list[str]:
    """Split ``EXPR1,EXPR2`` at the commas that are not inside parentheses (``max(a, b)`` stays whole)."""
    parts: list[str] = []
    cur: list[str] = []
    depth = 0
    for ch in text:
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        if ch == "," and depth == 0:
            parts.append("".join(cur))
            cur = []
        else:
            cur.append(ch)
    parts.append("".join(cur))
    return [p.strip() for p in parts]


def parse_objectives(
    exprs: str | Sequence[str],
    directions: str | Sequence[Direction | str] | None = None,
    *,
    source: str = "--objectives",
) -> tuple[Objective, ...]:
    """Parse one or more objectives (a comma-separated text or a list) with their directions.

    Args:
        exprs: ``"EXPR1,EXPR2"`` or ``["EXPR1", "EXPR2"]``.
        directions: one per objective (``"minimize,maximize"`` or a list); None: all minimised.

    Raises:
        ConfigError: a bad expression, an empty one, repeated ones, or directions that do not match.
    """
    texts = split_expressions(exprs) if isinstance(exprs, str) else [str(e).strip() for e in exprs]
    if not texts or any(not t for t in texts):
        raise ConfigError(f"expected EXPR or EXPR1,EXPR2,..., got {exprs!r}", source=source)
    if len(set(texts)) != len(texts):
        raise ConfigError(f"must not repeat an objective, got {exprs!r}", source=source)
    if directions is None:
        dirs: list[Direction | str] = [Direction.MINIMIZE] * len(texts)
    else:
        dirs = list(directions.split(",")) if isinstance(directions, str) else list(directions)
        if len(dirs) != len(texts):
            raise ConfigError(
                f"needs one direction per objective ({len(texts)}), got {len(dirs)}", source="--directions"
            )
    return tuple(parse_objective(t, Direction.parse(d), source=source) for t, d in zip(texts, dirs))


def check_names(objectives: Sequence[Objective], known: Iterable[str], *, source: str = "--objective") -> None:
    """Refuse objectives that read metrics a run does not have.

    Raises:
        ConfigError: one line naming the unknown metric, the closest known names and where to look.
    """
    known = sorted(set(known))
    for obj in objectives:
        for name in obj.names:
            if name not in known:
                close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
                hint = (
                    f"; did you mean {', '.join(close)}?"
                    if close
                    else f"; metrics of this run: {', '.join(known[:40])}{' ...' if len(known) > 40 else ''}"
                )
                raise ConfigError(f"unknown metric {name!r} in {obj.text!r}{hint}", source=source)


def is_completed(row: Mapping[str, Any]) -> bool:
    """True when a run's row says it completed its task."""
    return row.get("exit_status") == "completed"


def score_run(
    objectives: Sequence[Objective], row: Mapping[str, Any], penalty: float = DEFAULT_PENALTY
) -> tuple[float, ...]:
    """The objective values of one run (see the module docstring for incomplete runs).

    Args:
        objectives: parsed objectives.
        row: the run's flattened row (``exit_status`` and metrics).
        penalty: added in each objective's worse direction when the run did not complete (>= 0).

    Raises:
        MissingMetric: the run raised, or lacks a metric an objective reads.
    """
    if row.get("exit_status") in (None, "error"):
        raise MissingMetric(f"the run failed: {row.get('error') or 'no result'}")
    if is_completed(row):
        return tuple(o.evaluate(row) for o in objectives)
    filled = dict(row)
    for name, stand_in in INCOMPLETE_FILL.items():
        if filled.get(name) is None:
            filled[name] = row.get(stand_in)
    return tuple(o.worse_by(o.evaluate(filled), penalty) for o in objectives)


__all__ = [
    "DEFAULT_OBJECTIVE",
    "DEFAULT_PENALTY",
    "Direction",
    "INCOMPLETE_FILL",
    "MissingMetric",
    "Objective",
    "check_names",
    "is_completed",
    "parse_objective",
    "parse_objectives",
    "score_run",
    "split_expressions",
]
