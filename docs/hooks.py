"""MkDocs hook: fills the generated parts of the pages when the site is built.

A page holds a marker line where generated Markdown goes (see ``pybullet_swarm.cli.docgen``):
``<!-- reference: cli | scenario | parameters | presets -->``, ``<!-- results-table: NAME -->`` (from
``docs/results/data/NAME.json``), ``<!-- benchmark-table: PATH -->`` and ``<!-- benchmark-compare: PATH -->``
(JSON written by ``pybullet-swarm benchmark`` and ``benchmark compare --out``, PATH relative to the
repository's root). A marker that cannot be filled (a missing or
malformed file) fails the build with one line naming the page and the file.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from mkdocs.exceptions import PluginError

ROOT = Path(__file__).resolve().parent.parent


def on_config(config: Any) -> Any:
    """Put the checkout first on ``sys.path``: its package is documented, also when another copy is installed."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    return config


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """Replace the page's marker lines with the Markdown they name."""
    from pybullet_swarm.cli.docgen import MARKER, render_markers
    from pybullet_swarm.errors import ConfigError

    if not MARKER.search(markdown):
        return markdown
    docs_dir = Path(config["docs_dir"]).resolve()
    try:
        return render_markers(markdown, root=ROOT, data_dir=docs_dir / "results" / "data")
    except ConfigError as exc:
        raise PluginError(f"{page.file.src_uri}: {exc}") from None
