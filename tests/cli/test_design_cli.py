"""``pybullet-swarm design``: the report of every loop's placed and achieved poles, and the saturation checks."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from pybullet_swarm.cli.main import main
from pybullet_swarm.resources import scenarios_dir


def _run(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_json_reports_placed_and_achieved_poles_of_every_loop(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(capsys, ["design", "--vehicle", "cf2x", "--json"])
    assert code == 0
    data = json.loads(out)
    for group, loops in (("attitude", ("roll", "pitch", "yaw")), ("position", ("x", "y", "z"))):
        for loop in loops:
            rep = data[group][loop]
            assert len(rep["placed_poles"]) == 3
            assert len(rep["achieved_poles"]) == (7 if loop in ("x", "y") else 4)
            for placed in rep["placed_poles"]:  # every placed pole is among the achieved ones
                assert min(abs(complex(*placed) - complex(*a)) for a in rep["achieved_poles"]) < 1e-6
    assert data["saturation"]["ok"] is True and data["requirements_met"] is True


def test_text_lists_gains_and_poles_and_checks_a_scenario_step(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(capsys, ["design", "--scenario", "hover"])
    assert code == 0
    lines = out.splitlines()
    for loop in ("roll", "pitch", "yaw", "x", "y", "z"):
        assert any(line.startswith(f"{loop:<6}placed ") and " | achieved " in line for line in lines), loop
    assert any(line.startswith("scenario hover: step a = (1.0, 1.0, 1.0) m/s^2") for line in lines)
    assert "all met" in out


def test_a_scenario_step_the_rotors_cannot_follow_is_refused(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    raw = yaml.safe_load((scenarios_dir() / "hover.yaml").read_text(encoding="utf-8"))
    raw["limits"]["acceleration"] = 6.0  # m/s^2: 1.6 g of climb on a thrust-to-weight 2 vehicle
    path = tmp_path / "fast.yaml"
    path.write_text(yaml.safe_dump(raw))
    code, out, err = _run(capsys, ["design", "--scenario", str(path)])
    assert code == 2 and out == ""
    assert err.startswith("pybullet-swarm: error: fast.yaml: limits.acceleration: quad150.yaml: ")  # refused at load
    assert "cannot follow the reference step" in err and "% of max_rotor_speed" in err
