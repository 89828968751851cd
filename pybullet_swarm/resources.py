"""Find bundled data (URDFs with their parameter files, scenarios) from any working directory.

In a source checkout the data live in the top-level ``urdf/`` and ``scenarios/`` folders; an
installed package carries them as ``pybullet_swarm._urdf`` and ``pybullet_swarm._scenarios``
(mapped in ``setup.cfg``), so ``pip install .`` works without the checkout.
"""
from __future__ import annotations

import functools
import importlib.util
from pathlib import Path

_MARKERS = {"urdf": "quad150.yaml", "scenarios": "hover.yaml"}


@functools.cache
def data_dir(kind: str) -> Path:
    """Directory of bundled data of ``kind`` ('urdf' or 'scenarios')."""
    marker = _MARKERS[kind]
    try:
        spec = importlib.util.find_spec(f"pybullet_swarm._{kind}")
    except (ModuleNotFoundError, ValueError):
        spec = None
    # a data-only (namespace) package: its directories are the search locations
    for location in (spec.submodule_search_locations or []) if spec is not None else []:
        candidate = Path(location)
        if (candidate / marker).is_file():
            return candidate
    candidate = Path(__file__).resolve().parent.parent / kind
    if (candidate / marker).is_file():
        return candidate
    raise FileNotFoundError(f"bundled {kind} data not found (looked for {marker})")


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
