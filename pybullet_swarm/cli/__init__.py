"""The ``pybullet-swarm`` command."""

from __future__ import annotations


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``pybullet-swarm`` console script."""
    from pybullet_swarm.cli.main import main as _main

    return _main(argv)
