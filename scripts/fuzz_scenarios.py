"""Fuzz the bundled scenarios with many more mutations than the test suite, and count the outcomes.

Uses the mutations and the property of ``tests/experiment/test_fuzz_scenarios.py``: ``check``
exits 0 or 2 with one line; an accepted mutant runs for a fraction of a second without being
refused and without an exception. Prints, per kind of mutation, how many mutants ``check``
refused, how many it accepted and how their runs ended, and every violation of the property
(with the mutant's text saved in ``--keep``).

    python scripts/fuzz_scenarios.py --examples 500 [--seed 1] [--mutations 3] [--plots] [--seconds 2]
                                     [--keep DIR]

Needs the test extra (hypothesis).
"""

from __future__ import annotations

import argparse
import collections
import importlib.util
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent


def _load_fuzz_module() -> Any:
    path = ROOT / "tests" / "experiment" / "test_fuzz_scenarios.py"
    spec = importlib.util.spec_from_file_location("fuzz_scenarios_module", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def classify(fz: Any, what: str, o: Any) -> str:
    """One word for an outcome; ``VIOLATION ...`` when the property does not hold."""
    try:
        fz.assert_property(what, o)
    except AssertionError as exc:
        detail = " ".join(str(exc).split())[:300]
        return f"VIOLATION {detail}"
    if o.code == 2:
        return "refused"
    return f"ran:{o.run}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=500, help="mutants to try (default 500)")
    parser.add_argument("--seed", type=int, default=None, help="seed of the mutations (default: random)")
    parser.add_argument("--plots", action="store_true", help="draw each accepted run's figures too (slower)")
    parser.add_argument(
        "--seconds",
        type=float,
        default=None,
        help="simulated seconds of each accepted run (default: the test's RUN_SECONDS, 0.3)",
    )
    parser.add_argument("--mutations", type=int, default=3, help="at most this many mutations per mutant (default 3)")
    parser.add_argument("--keep", type=Path, default=None, help="save the text of each violating mutant here")
    args = parser.parse_args()

    from hypothesis import HealthCheck, given, seed, settings

    fz = _load_fuzz_module()
    if args.seconds is not None:
        fz.RUN_SECONDS = args.seconds
    counts: dict[str, collections.Counter[str]] = collections.defaultdict(collections.Counter)
    violations: list[tuple[str, str, str]] = []
    t0 = time.perf_counter()
    work = Path(tempfile.mkdtemp(prefix="fuzz-scenarios-"))
    n = 0

    @settings(max_examples=args.examples, deadline=None, database=None, suppress_health_check=list(HealthCheck))
    @given(case=fz.mutants(max_mutations=args.mutations))
    def explore(case: tuple[str, str, str]) -> None:
        nonlocal n
        _, what, text = case
        n += 1
        d = work / f"m{n}"
        d.mkdir()
        outcome = classify(fz, what, fz.try_mutant(text, d, plots=args.plots))
        kind = what.split(": ")[1]
        counts[kind][outcome.split(" ")[0]] += 1
        if outcome.startswith("VIOLATION"):
            violations.append((what, outcome, text))
            print(f"{what}\n  -> {outcome}", file=sys.stderr, flush=True)

    if args.seed is not None:
        explore = seed(args.seed)(explore)
    explore()
    wall = time.perf_counter() - t0
    outcomes = sorted({o for c in counts.values() for o in c})
    width = max(len(k) for k in counts) if counts else 4
    print(f"{'mutation'.ljust(width)}  " + "  ".join(o.rjust(max(len(o), 5)) for o in outcomes) + "  total")
    for kind in sorted(counts):
        c = counts[kind]
        print(
            f"{kind.ljust(width)}  "
            + "  ".join(str(c[o]).rjust(max(len(o), 5)) for o in outcomes)
            + f"  {sum(c.values()):5d}"
        )
    total = collections.Counter[str]()
    for c in counts.values():
        total.update(c)
    print(
        f"{'all'.ljust(width)}  "
        + "  ".join(str(total[o]).rjust(max(len(o), 5)) for o in outcomes)
        + f"  {sum(total.values()):5d}"
    )
    print(f"{n} mutants in {wall:.0f} s; {len(violations)} violation(s)")
    if args.keep is not None and violations:
        args.keep.mkdir(parents=True, exist_ok=True)
        for i, (what, outcome, text) in enumerate(violations):
            (args.keep / f"violation{i}.yaml").write_text(f"# {what}\n# {outcome}\n{text}", encoding="utf-8")
    return 1 if violations else 0


if __name__ == "__main__":
    sys.exit(main())
