"""The README stays an introduction, and its set-up commands stay the ones CI runs."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SETUP_COMMANDS = (
    "pip install . && pybullet-swarm run construction",
    'pip install ".[test,ray,rl,tune]" && pytest -q',
)


def test_readme_is_at_most_300_lines() -> None:
    assert len((ROOT / "README.md").read_text(encoding="utf-8").splitlines()) <= 300


def test_readme_holds_the_two_setup_commands_that_ci_runs() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    for command in SETUP_COMMANDS:
        assert f"\n{command}\n" in readme, command
        assert f"\n{command}\n" in ci, command


def test_readme_links_point_at_files_that_exist() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = [t.split("#")[0] for t in re.findall(r"\]\(([^)\s]+)\)", readme) if "://" not in t]
    assert targets
    missing = [t for t in targets if t and not (ROOT / t).exists()]
    assert not missing


def test_readme_result_tables_are_rendered_from_their_benchmark_json() -> None:
    from pybullet_swarm.cli.docgen import README_BLOCK, refresh_readme

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = README_BLOCK.findall(readme)
    assert blocks, "the README shows at least one benchmark table"
    for _, path, table, _ in blocks:
        assert (ROOT / path).is_file(), path
        assert table.count("\n|") >= 2, path  # a header, a rule and rows
    assert refresh_readme(readme, ROOT) == readme, "run scripts/readme_results.py"
