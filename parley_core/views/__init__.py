"""Interactive, self-contained HTML reports (Bokeh standalone documents): a run's
``report.html`` (:mod:`.run_page`) and a campaign's (:mod:`.campaign_page`)."""

from __future__ import annotations

import html


def inline(page: str, height: int) -> str:
    """A whole page as Jupyter's HTML output: an iframe holding it (``srcdoc``), so its
    scripts run apart from the notebook's."""
    return f'<iframe srcdoc="{html.escape(page, quote=True)}" style="width:100%;height:{height}px;border:0"></iframe>'
