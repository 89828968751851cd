#!/usr/bin/env python3
"""Render the README's result tables again from the committed benchmark JSON they name.

    python scripts/readme_results.py [--check]

Each table sits between ``<!-- benchmark-table: PATH -->`` and ``<!-- /benchmark-table -->``;
PATH is a ``pybullet-swarm benchmark`` JSON file relative to the repository. ``--check`` writes
nothing and fails when the README is not current (``tests/test_readme.py`` does the same).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pybullet_swarm.cli.docgen import refresh_readme

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="fail when the README's tables are not current")
    args = ap.parse_args()
    path = ROOT / "README.md"
    text = path.read_text(encoding="utf-8")
    new = refresh_readme(text, ROOT)
    if args.check:
        if new != text:
            print("README.md: a result table differs from its benchmark JSON; run scripts/readme_results.py")
            return 1
        return 0
    if new != text:
        path.write_text(new, encoding="utf-8")
        print(f"{path}: tables rendered again")
    return 0


if __name__ == "__main__":
    sys.exit(main())
