"""Find bundled data (URDFs with their parameter files, scenarios) from any working directory.

In a source checkout the data live in the top-level ``urdf/`` and ``scenarios/`` folders; an
installed package carries them as ``pybullet_swarm._urdf`` and ``pybullet_swarm._scenarios``
(mapped in ``setup.cfg``), so ``pip install .`` works without the checkout.
"""
from __future__ import annotations

import functools
import importlib.resources
from pathlib import Path

_MARKERS = {"urdf": "quad150.yaml", "scenarios": "hover.yaml"}


@functools.cache
def data_dir(kind: str) -> Path:
    """Directory of bundled data of ``kind`` ('urdf' or 'scenarios')."""
    marker = _MARKERS[kind]
    try:
        root = importlib.resources.files(f"pybullet_swarm._{kind}")
        candidate = Path(str(root))
        if (candidate / marker).is_file():
            return candidate
    except (ModuleNotFoundError, NotADirectoryError, TypeError):
        pass  # not installed as a package (source checkout or editable install)
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
