"""Find bundled data (URDFs with their parameter files, scenarios) from any working directory.

The data live in the checkout's top-level ``urdf/`` and ``scenarios/`` folders, which the package
links as ``pybullet_swarm/urdf`` and ``pybullet_swarm/scenarios``; an installed package carries
copies of them at the same place. Both are found the same way, with ``importlib.resources``.
"""

from __future__ import annotations

import functools
from importlib import resources
from pathlib import Path

_MARKERS = {"urdf": "quad150.yaml", "scenarios": "hover.yaml"}


@functools.cache
def data_dir(kind: str) -> Path:
    """Directory of bundled data of ``kind`` ('urdf' or 'scenarios')."""
    candidate = Path(str(resources.files("pybullet_swarm") / kind))
    if not (candidate / _MARKERS[kind]).is_file():
        raise FileNotFoundError(f"bundled {kind} data not found in {candidate} (looked for {_MARKERS[kind]})")
    return candidate


def urdf_dir() -> Path:
    """Directory holding the bundled URDFs and their parameter files."""
    return data_dir("urdf")


def scenarios_dir() -> Path:
    """Directory holding the bundled scenarios."""
    return data_dir("scenarios")


def bundled_vehicles() -> list[str]:
    """Names of the bundled vehicles (a URDF with a parameter file beside it)."""
    d = urdf_dir()
    return sorted(p.stem for p in d.glob("*.yaml") if (d / f"{p.stem}.urdf").is_file())


def bundled_scenarios() -> list[str]:
    """Names of the bundled scenarios."""
    return sorted(p.stem for p in scenarios_dir().glob("*.yaml"))
