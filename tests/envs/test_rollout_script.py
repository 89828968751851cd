"""The example script: a scripted rollout of the swarm environment prints and writes the episode metrics."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "rl_rollout.py"


def _load():
    spec = importlib.util.spec_from_file_location("rl_rollout", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(mod)
    return mod


def test_scripted_rollout_completes_and_writes_metrics(tmp_path: Path, capsys) -> None:
    out = tmp_path / "episodes.json"
    rc = _load().main(["--set", "agents.count=2", "--json", str(out)])
    assert rc == 0
    assert "episode 0 seed 0: completed" in capsys.readouterr().out
    episodes = json.loads(out.read_text())
    m = episodes[0]["metrics"]
    assert m["exit_status"] == "completed" and m["agents"] == 2 and sum(m["collisions"].values()) == 0
    assert all(r > 0 for r in episodes[0]["returns"].values())


def test_bad_scenario_is_exit_code_2(capsys) -> None:
    assert _load().main(["--set", "agents.count=0"]) == 2
    assert capsys.readouterr().err.strip() == "rl_rollout: error: hover_swarm.yaml: agents.count: must be >= 1, got 0"
