"""The ``pybullet-swarm`` command."""

from __future__ import annotations

from typing import Any


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``pybullet-swarm`` console script."""
    from pybullet_swarm.cli.main import main as _main

    return _main(argv)


def add_overrides_option(parser: Any, help: str | None = None) -> None:
    """Add ``--set KEY.PATH=VALUE`` (repeatable, into ``overrides``) to a command's parser."""
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE", help=help)
