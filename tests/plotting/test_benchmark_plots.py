"""The benchmark figure is drawn from benchmark JSON alone, also with configurations that never completed."""

from __future__ import annotations

from pybullet_swarm.plotting.benchmark_plots import benchmark_figure


def test_figure_of_a_benchmark_json(tmp_path):
    def config(planner: str, completed: int, median: float | None, ci: list[float] | None) -> dict:
        return {"planner": planner, "avoidance": "orca", "runs": 4, "completed": completed,
                "completion_rate": completed / 4, "median_time_s": median, "median_time_ci": ci,
                "contact_runs": {"agent_agent": 1, "agent_structure": 0},
                "layouts": [{"layout": "a", "completion_rate": completed / 4}, {"layout": "b", "completion_rate": None}]}  # fmt: skip

    data = {"suite": "s", "suite_version": 1, "split": "holdout", "commit": "abc", "recorded_runs": 8,
            "layouts": ["a", "b"], "contact_classes": ["agent_agent", "agent_structure"],
            "configurations": [config("stigmergy", 4, 100.0, [95.0, 110.0]), config("shortest_path", 0, None, None)]}  # fmt: skip
    path = benchmark_figure(data, tmp_path / "b.png")
    assert path == tmp_path / "b.png" and path.stat().st_size > 5000
