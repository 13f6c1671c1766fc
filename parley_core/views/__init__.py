"""Pictures, with no file format and no domain logic: matplotlib figures on the Agg canvas
(:mod:`.plotting`, :mod:`.frontplot`), the helpers of the self-contained Bokeh pages
(:mod:`.bokeh_scripts`, :mod:`.stable`; the pages themselves are :mod:`parley_core.rundir.page`
and :mod:`parley_core.experiment.page`) and progress bars on stderr (:mod:`.richprogress`)."""

from __future__ import annotations

import html


def inline(page: str, height: int) -> str:
    """A whole page as Jupyter's HTML output: an iframe holding it (``srcdoc``), so its
    scripts run apart from the notebook's."""
    return f'<iframe srcdoc="{html.escape(page, quote=True)}" style="width:100%;height:{height}px;border:0"></iframe>'
