"""The construction suite's figure: completion rate, efficiency and contacts per layout and configuration.

Drawn from the suite's table only (one record per layout and configuration, plain numbers): a
heat map of the completion rate (runs completed / runs), a heat map of the median efficiency
(the task's lower bound / completion time, over completed runs), and the contacts per run by
class, stacked per configuration over every layout.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from pybullet_swarm.plotting.common import save_figure

CONTACTS = ("agent_agent", "agent_structure", "agent_box", "agent_ground", "agent_obstacle")


def _grid(table: Sequence[Mapping[str, Any]], key: str, layouts: list[str], configs: list[str]) -> np.ndarray:
    out = np.full((len(layouts), len(configs)), np.nan)
    for r in table:
        v = r.get(key)
        if isinstance(v, (int, float)) and math.isfinite(v):
            out[layouts.index(r["layout"]), configs.index(r["configuration"])] = float(v)
    return out


def _heat(ax: Any, values: np.ndarray, layouts: list[str], configs: list[str], title: str, fmt: str) -> None:
    im = ax.imshow(values, vmin=0.0, vmax=1.0, cmap="RdYlGn", aspect="auto")
    ax.set_xticks(range(len(configs)), configs, rotation=40, ha="right", fontsize=8)
    ax.set_yticks(range(len(layouts)), layouts, fontsize=8)
    ax.set_title(title, fontsize=10)
    for (i, j), v in np.ndenumerate(values):
        ax.text(j, i, "-" if not math.isfinite(v) else format(v, fmt), ha="center", va="center", fontsize=7)
    ax.figure.colorbar(im, ax=ax, fraction=0.04)


def suite_figure(table: Sequence[Mapping[str, Any]], path: Path) -> Path:
    """Completion rate, median efficiency and contacts per run of every layout x configuration (``path``: png).

    Args:
        table: records with ``layout``, ``configuration``, ``completion_rate``, ``efficiency_median`` and
            ``contacts_<class>_per_run`` (plain numbers).
        path: the figure file.
    """
    layouts = list(dict.fromkeys(str(r["layout"]) for r in table))
    configs = list(dict.fromkeys(str(r["configuration"]) for r in table))
    fig = Figure(figsize=(6.0 + 1.6 * len(configs), 1.2 + 0.38 * len(layouts)), layout="constrained")
    a, b, c = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.0, 1.0, 0.8]})
    _heat(a, _grid(table, "completion_rate", layouts, configs), layouts, configs, "completed / runs", ".2f")
    _heat(b, _grid(table, "efficiency_median", layouts, configs), layouts, configs, "median efficiency", ".2f")
    b.set_yticks([])
    bottom = np.zeros(len(configs))
    for cls in CONTACTS:
        per = np.nan_to_num(_grid(table, f"contacts_{cls}_per_run", layouts, configs))
        total = per.sum(axis=0) / max(1, len(layouts))
        if total.any():
            c.bar(range(len(configs)), total, bottom=bottom, label=cls.replace("_", "-"))
            bottom += total
    c.set_xticks(range(len(configs)), configs, rotation=40, ha="right", fontsize=8)
    c.set_title("contacts per run (mean)", fontsize=10)
    if bottom.any():
        c.legend(fontsize=7)
    return save_figure(fig, path)
