"""Write docs/results/data/controller_design.json: the designed loops of every bundled vehicle.

Runs the same design as ``pybullet-swarm design --vehicle NAME --json`` (240 Hz physics, 48 Hz
position loop, g = 9.81 m/s^2) and keeps, per vehicle and loop, the natural frequency of the
placed pair, the gain and phase margins, the bandwidth, and the placed and achieved closed-loop
poles (rad/s). The docs include the file with ``<!-- results-table: controller_design -->``.

    python scripts/controller_design_table.py [--out docs/results/data/controller_design.json]
"""

from __future__ import annotations

import argparse
import datetime
import json
import subprocess
from pathlib import Path
from typing import Any

from pybullet_swarm.control.design import design_controller
from pybullet_swarm.resources import bundled_vehicles
from pybullet_swarm.vehicle import load_vehicle

ROOT = Path(__file__).resolve().parent.parent
COMMAND = "python scripts/controller_design_table.py"


def _poles(poles: list[list[float]]) -> str:
    """Poles as ``-8.43 +- 6.32j, -4.21`` (a conjugate pair once)."""
    out = []
    for re, im in sorted(poles, key=lambda p: (-p[0], -abs(p[1]))):
        if im < 0:
            continue
        out.append(f"{re:.3g} +- {im:.3g}j" if im > 0 else f"{re:.3g}")
    return ", ".join(out)


def rows(vehicle: str) -> list[list[Any]]:
    """One row per loop of the vehicle's design."""
    design: dict[str, Any] = design_controller(
        load_vehicle(vehicle), physics_hz=240.0, position_hz=48.0, gravity=9.81
    ).to_json_dict()
    out = []
    for group in ("attitude", "position"):
        for loop, d in design[group].items():
            out.append(
                [
                    vehicle,
                    loop,
                    round(d["natural_frequency_rad_s"], 3),
                    round(d["gain_margin_db"], 2),
                    round(d["phase_margin_deg"], 2),
                    round(d["bandwidth_rad_s"], 3),
                    _poles(d["placed_poles"]),
                    _poles(d["achieved_poles"]),
                ]
            )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "data" / "controller_design.json")
    args = parser.parse_args()
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.strip()
    data = {
        "title": "Designed loops: placed and achieved closed-loop poles, margins and bandwidths",
        "command": COMMAND,
        "commit": commit,
        "date": datetime.date.today().isoformat(),
        "columns": [
            "vehicle",
            "loop",
            "w_n [rad/s]",
            "gain margin [dB]",
            "phase margin [deg]",
            "bandwidth [rad/s]",
            "placed poles [rad/s]",
            "achieved poles [rad/s]",
        ],
        "rows": [row for vehicle in bundled_vehicles() for row in rows(vehicle)],
        "notes": [
            "The design of `pybullet-swarm design --vehicle NAME` at 240 Hz physics and a 48 Hz position loop.",
            "Poles are s = ln(z) / T, T the loop's period; a conjugate pair is written once as re +- im j.",
        ],
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    tmp.replace(args.out)
    print(args.out)


if __name__ == "__main__":
    main()
