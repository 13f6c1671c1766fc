"""A campaign's ``report.html``: Table 2 and, for a requirement setting chosen on the page,
the box plots of every instance's hypervolume and spread gains over the baseline (Fig. 4),
with hover showing the instance, the median gain and the verdict. One self-contained Bokeh
standalone document, as a run's page (:mod:`parley_core.rundir.page`)."""

from __future__ import annotations

import html
from collections.abc import Sequence
from typing import Any

import numpy as np

from parley_core.views.bokeh_scripts import CHOOSE_SETTING
from parley_core.views.stable import stable_ids

Row = Any
"""A :class:`parley_core.experiment.report.Row` (not imported: that module imports this one)."""
Setting = tuple[float, ...]

REPORT = "report.html"
GAINS = (
    ("hv", "baseline_hv", "hypervolume gain (higher is better)"),
    ("spread", "baseline_spread", "spread gain (lower is better)"),
)


def boxes(rows: Sequence[Row], setting: Setting, key: str, base: str) -> dict[str, list[Any]]:
    """Per instance of the setting: quartiles and whiskers (1.5 IQR, within the data) of the
    repetitions' gains, and the verdict against the baseline."""
    columns: dict[str, list[Any]] = {k: [] for k in ("instance", "q1", "q2", "q3", "low", "high", "verdict")}
    for row in rows:
        if row.setting != setting:
            continue
        gains = np.asarray(getattr(row, key), dtype=float) - getattr(row, base)
        gains = gains[np.isfinite(gains)]
        if not len(gains):
            continue
        q1, q2, q3 = np.percentile(gains, [25, 50, 75])
        reach = 1.5 * (q3 - q1)
        columns["instance"].append(row.instance)
        columns["q1"].append(float(q1))
        columns["q2"].append(float(q2))
        columns["q3"].append(float(q3))
        columns["low"].append(float(gains[gains >= q1 - reach].min()))
        columns["high"].append(float(gains[gains <= q3 + reach].max()))
        columns["verdict"].append(getattr(row, f"{key}_verdict"))
    return columns


def table2_html(head: Sequence[str], lines: Sequence[Sequence[str]]) -> str:
    """Table 2 as an HTML table, from :func:`parley_core.experiment.table2.table2_cells`
    (the last line, the total, in bold)."""
    header = "".join(f"<th>{html.escape(h)}</th>" for h in head)
    body = []
    for k, line in enumerate(lines):
        wrap = ("<b>", "</b>") if k == len(lines) - 1 else ("", "")
        body.append("<tr>" + "".join(f"<td>{wrap[0]}{html.escape(c)}{wrap[1]}</td>" for c in line) + "</tr>")
    return (
        "<table class='table2' border='1' cellpadding='4' style='border-collapse:collapse'>"
        f"<thead><tr>{header}</tr></thead><tbody>{''.join(body)}</tbody></table>"
    )


def render(
    rows: Sequence[Row],
    settings: Sequence[Setting],
    header: Sequence[str],
    *,
    table: tuple[Sequence[str], Sequence[Sequence[str]]],
    title: str,
    description: str,
    chosen: Setting,
) -> str:
    from bokeh.embed import file_html
    from bokeh.layouts import column
    from bokeh.models import ColumnDataSource, CustomJS, Div, HoverTool, Select, Span
    from bokeh.plotting import figure
    from bokeh.resources import INLINE

    names = [", ".join(f"{h} {b:g}" for h, b in zip(header, s)) for s in settings]
    current = names[list(settings).index(chosen)]
    plots, sources, every = [], {}, {}
    for key, base, label in GAINS:
        every[key] = {text: boxes(rows, s, key, base) for text, s in zip(names, settings)}
        source = ColumnDataSource(every[key][current], name=f"boxes-{key}")
        sources[key] = source
        instances = sorted({r.instance for r in rows}, key=lambda name: (len(name), name))
        plot = figure(
            width=max(640, 14 * len(instances) + 120),
            height=340,
            x_range=instances,
            title=f"{label.split(' (')[0]} per instance over the repetitions",
            y_axis_label=label,
            tools="pan,wheel_zoom,box_zoom,reset,save",
            name=f"gains-{key}",
        )
        plot.segment("instance", "low", "instance", "high", source=source, color="black")
        bars = plot.vbar(
            x="instance",
            width=0.7,
            bottom="q1",
            top="q3",
            source=source,
            fill_color="#9ecae1",
            line_color="black",
            name=f"gains-{key}-boxes",
        )
        plot.scatter("instance", "q2", source=source, size=6, color="black", marker="dash")
        plot.add_layout(Span(location=0.0, dimension="width", line_color="#d62728", line_width=1))
        plot.add_tools(
            HoverTool(
                renderers=[bars],
                tooltips=[("instance", "@instance"), ("median gain", "@q2{0.[0000]}"), ("vs baseline", "@verdict")],
            )
        )
        plot.xaxis.major_label_orientation = 1.2
        plots.append(plot)
    select = Select(title="requirement setting", value=current, options=names, name="setting")
    select.js_on_change(
        "value",
        CustomJS(
            args={"sources": [sources[k] for k, _, _ in GAINS], "every": [every[k] for k, _, _ in GAINS]},
            code=CHOOSE_SETTING,
        ),
    )
    header_div = Div(
        text=f"<h2>{html.escape(title)}</h2><p>{html.escape(description)}</p>" + table2_html(*table),
        width=1000,
        name="table2",
    )
    return stable_ids(file_html(column(header_div, select, *plots), INLINE, title=title))
