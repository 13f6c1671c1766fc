"""``report.html`` of a run directory: the front against the baseline and the bound, with
hover, a click that shows the policy, and requirement sliders that filter the front.

Bokeh's standalone documents (:func:`bokeh.embed.file_html` with the inline resources) make
one self-contained, offline file: the views are linked by shared data sources and small
CustomJS callbacks, without a server. The page is built from the run directory's files
(a :class:`~parley_core.rundir.read.RunDirectory`, which :mod:`parley_core.rundir.write`
reads back from the directory it has just written), so any run directory, old or new, gets the same page.

The policy view: where the URC observes two variables or more, a grid over two of them
coloured by each service's decision, on the plugin's map where it gives one
(:mod:`parley_core.rundir.policy_grid`); for any case study, the decision table.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from parley_core.model import Direction
from parley_core.rundir.read import RunDirectory
from parley_core.views.bokeh_scripts import FILTER, NEAREST, SHOW_POLICY
from parley_core.views.stable import stable_ids

REPORT = "report.html"


def _axes(run: RunDirectory) -> tuple[int, int]:
    """(x, y) objective indices as ``front.png`` lays them out."""
    if len(run.objectives) == 1:
        return 0, 0
    return (1, 0) if run.objectives[0].direction is Direction.MAX else (0, 1)


def _finite(values: np.ndarray) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in values]


def policy_table(run: RunDirectory) -> tuple[dict[str, list[Any]], list[int], list[str]]:
    """The decision table's columns (observation variables, then one per service constant,
    one row per consulted valuation) and, per decision, its row and constant."""
    constants = [s.constant for s in run.services]
    rows: dict[tuple[int, ...], int] = {}
    row_of, constant_of = [], []
    for decision in run.decisions:
        row_of.append(rows.setdefault(decision.valuation, len(rows)))
        constant_of.append(decision.service.constant)
    columns: dict[str, list[Any]] = {name: [v[k] for v in rows] for k, name in enumerate(run.observation)}
    for constant in constants:
        columns[constant] = [float("nan")] * len(rows)
    return columns, row_of, constant_of


def _front_source(
    run: RunDirectory, front: np.ndarray, i: int, j: int
) -> tuple[dict[str, list[Any]], list[int], np.ndarray]:
    """The plot's points, one per tie (:func:`parley_core.metrics.tie_points`): the first
    policy of each, how many others tie with it and their names; each point's first row;
    and each row's point (1, 2, ...)."""
    from parley_core import metrics

    names = [o.name for o in run.objectives]
    ties = metrics.tie_points(front, [o.direction for o in run.objectives])
    firsts = [int(np.flatnonzero(ties == t)[0]) for t in range(1, int(ties.max(initial=0)) + 1)]
    policies = [p.name for p in run.front.policies]
    members = [[policies[r] for r in np.flatnonzero(ties == ties[f])] for f in firsts]
    shown = front[firsts] if firsts else front[:0]
    data: dict[str, list[Any]] = {
        "policy": [policies[f] for f in firsts],
        "ties": [len(m) - 1 for m in members],
        "others": [", ".join(m[1:6]) + (" ..." if len(m) > 6 else "") for m in members],
        "x": _finite(shown[:, i]),
        "y": _finite(shown[:, j]) if len(names) > 1 else [0.0] * len(shown),
        "alpha": [1.0] * len(shown),
    }
    for k, name in enumerate(names):
        data[name] = _finite(shown[:, k])
    return data, firsts, ties


def _notes(run: RunDirectory, i: int, j: int, coloured: int | None) -> str:
    """What the plot leaves out: objectives beyond its axes and colour, and the bound's form."""
    from parley_core.views.frontplot import left_out

    if coloured is None:
        return ""
    bound = None if run.optimality is None else np.asarray(run.optimality.points, dtype=float)
    parts = [f"colour: {run.objectives[coloured].name}", left_out(run.objectives, (i, j, coloured), bound)]
    return "; ".join(part for part in parts if part)


STACKED_WIDTH = 620
"""The width of a stacked page (a notebook's or a documentation page's output)."""


def render(run: RunDirectory, stacked: bool = False) -> str:
    """The page's HTML (self-contained): the front beside the policy view, 1,040 px wide, or
    ``stacked``, the policy view below the front, :data:`STACKED_WIDTH` px wide, for a
    notebook's output or a documentation page, where the wide page would be cut off."""
    from bokeh.embed import file_html
    from bokeh.layouts import column, row
    from bokeh.models import (
        BoxAnnotation,
        ColorBar,
        ColumnDataSource,
        CustomJS,
        DataTable,
        Div,
        HoverTool,
        LinearColorMapper,
        Scatter,
        Slider,
        TableColumn,
        TapTool,
    )
    from bokeh.palettes import Viridis256
    from bokeh.plotting import figure
    from bokeh.resources import INLINE

    objectives = run.objectives
    names = [o.name for o in objectives]
    i, j = _axes(run)
    all_values = np.array(run.front.values, dtype=float).reshape(-1, len(names))
    base = np.array(run.baseline.values, dtype=float).reshape(-1, len(names))
    data, firsts, ties = _front_source(run, all_values, i, j)
    front = all_values[firsts] if firsts else all_values[:0]
    source = ColumnDataSource(data, name="front-source")
    tooltips = [("policy", "@policy")] + [(n, f"@{{{n}}}{{0.[0000]}}") for n in names]
    title = f"{run.case_study}: {len(front)} points of {len(all_values)} Storm-verified policies"
    width, height = 600, 440
    plot = figure(
        width=width,
        height=height,
        title=title,
        tools="pan,wheel_zoom,box_zoom,reset,save",
        x_axis_label=f"{names[i]} ({objectives[i].direction.value})",
        y_axis_label=f"{names[j]} ({objectives[j].direction.value})" if len(names) > 1 else "",
        name="front-plot",
    )
    coloured = next((k for k in range(len(names)) if k not in (i, j)), None)
    colour: Any = "#1f77b4"
    if coloured is not None:
        finite = front[:, coloured][np.isfinite(front[:, coloured])]
        low, high = (float(finite.min()), float(finite.max())) if len(finite) else (0.0, 1.0)
        palette = Viridis256 if objectives[coloured].direction is Direction.MAX else Viridis256[::-1]
        mapper = LinearColorMapper(palette=palette, low=low, high=high if high > low else low + 1e-9)
        colour = {"field": names[coloured], "transform": mapper}
        plot.add_layout(ColorBar(color_mapper=mapper, title=names[coloured], width=10), "right")
    points = plot.scatter(
        "x",
        "y",
        source=source,
        size=8,
        fill_alpha="alpha",
        line_alpha="alpha",
        color=colour,
        name="front-points",
        legend_label=f"parley front ({len(front)} points)",
    )
    # a click marks the chosen point and leaves the others as they are (faded or not by the
    # requirements), instead of fading everything else as well
    points.selection_glyph = Scatter(size=13, fill_color=colour, line_color="black", line_width=2)
    points.nonselection_glyph = None
    ring = ColumnDataSource({"x": [], "y": []}, name="nearest-source")
    plot.scatter("x", "y", source=ring, size=15, fill_color=None, line_color="black", line_width=1.5, name="nearest")
    readout = Div(
        text="hover: the nearest point's values appear here; click: its decisions on the right",
        name="hover-readout",
        width=width,
    )
    nearest = CustomJS(
        args={
            "source": source,
            "ring": ring,
            "readout": readout,
            "names": names,
            "xr": plot.x_range,
            "yr": plot.y_range,
            "width": width,
            "height": height,
        },
        code=NEAREST,
    )
    plot.add_tools(HoverTool(renderers=[points], tooltips=None, callback=nearest), TapTool(renderers=[points]))
    knee = run.policy(run.summary.selected)
    at = int(ties[[q.name for q in run.front.policies].index(knee.name)]) - 1  # the knee's point
    if len(firsts):
        plot.scatter(
            [data["x"][at]],
            [data["y"][at]],
            marker="star",
            size=17,
            fill_color="#ff7f0e",
            line_color="black",
            name="knee-point",
            legend_label=f"knee ({knee.name}, the selected policy)",
        )
    if len(base):
        baseline = ColumnDataSource(
            {
                "policy": [p.name for p in run.baseline.policies],
                "x": _finite(base[:, i]),
                "y": _finite(base[:, j]) if len(names) > 1 else [0.0] * len(base),
                **{n: _finite(base[:, k]) for k, n in enumerate(names)},
            }
        )
        marks = plot.scatter(
            "x",
            "y",
            source=baseline,
            marker="x",
            size=10,
            color="#d62728",
            name="baseline-points",
            legend_label=f"baseline ({len(base)})",
        )
        plot.add_tools(HoverTool(renderers=[marks], tooltips=[("baseline", "@policy")] + tooltips[1:]))
    if run.optimality is not None and len(names) > 1:
        bound = np.array(run.optimality.points, dtype=float).reshape(-1, len(names))
        if len(bound) and np.isfinite(bound).all():
            from parley_core.views.frontplot import staircase

            signs = -np.array([objectives[i].direction.sign, objectives[j].direction.sign])
            reference = np.array([run.summary.hypervolume_reference[i], run.summary.hypervolume_reference[j]])
            outline = staircase(bound[:, [i, j]], signs, reference)[:-1]
            plot.line(
                outline[:, 0],
                outline[:, 1],
                color="#2ca02c",
                line_width=1.5,
                name="bound-line",
                legend_label="certified bound: no policy beyond",
            )
    plot.legend.location = "bottom_right"
    plot.legend.click_policy = "hide"

    box = BoxAnnotation(
        fill_alpha=0.08, fill_color="#ff7f0e", line_color="#ff7f0e", level="underlay", name="requirement-box"
    )
    plot.add_layout(box)
    counter = Div(text=f"{len(front)} of {len(front)} points meet the requirements", name="requirement-count")
    sliders = []
    for k, objective in enumerate(objectives):
        column_values = front[:, k][np.isfinite(front[:, k])]
        if not len(column_values):
            continue
        low, high = float(column_values.min()), float(column_values.max())
        if high <= low:
            high = low + (abs(low) or 1.0) * 1e-6
        start = low if objective.direction is Direction.MAX else high
        sliders.append(
            Slider(
                start=low,
                end=high,
                value=start,
                step=(high - low) / 200,
                title=f"{objective.name} {'>=' if objective.direction is Direction.MAX else '<='}",
                name=f"requirement-{objective.name}",
            )
        )
    filter_code = CustomJS(
        args={
            "source": source,
            "sliders": sliders,
            "keys": [objectives[k].name for k in range(len(objectives)) if front[:, k][np.isfinite(front[:, k])].size],
            "maximise": [o.direction is Direction.MAX for o in objectives],
            "names": names,
            "axes": [names[i], names[j]],
            "box": box,
            "counter": counter,
        },
        code=FILTER,
    )
    for slider in sliders:
        slider.js_on_change("value", filter_code)

    columns, row_of, constant_of = policy_table(run)
    for d, value in enumerate(knee.values):  # the page opens on the knee policy
        columns[constant_of[d]][row_of[d]] = int(value)
    table_source = ColumnDataSource(columns, name="policy-table")
    table = DataTable(
        source=table_source,
        columns=[TableColumn(field=c, title=c) for c in columns],
        width=420,
        height=300,
        index_position=None,
        reorderable=False,
        name="decision-table",
    )
    heading = Div(
        text=f"<b>policy {knee.name}</b> (the knee; click a policy of the front to see its decisions)",
        name="policy-heading",
        width=420,
    )
    views: list[Any] = [heading]
    from parley_core.rundir.policy_grid import grids

    views += grids(run, table_source, columns)
    views.append(table)
    show = CustomJS(
        args={
            "source": source,
            "table": table_source,
            "grid_table": table,
            "decisions": [list(map(int, run.front.policies[f].values)) for f in firsts],
            "row_of": row_of,
            "constant_of": constant_of,
            "heading": heading,
            "names": names,
            "xr": plot.x_range,
            "yr": plot.y_range,
            "width": width,
            "height": height,
        },
        code=SHOW_POLICY,
    )
    plot.select_one(TapTool).callback = show
    summary = run.summary
    facts = [
        f"hypervolume {summary.front.hypervolume:.6g} against the baseline's {summary.baseline.hypervolume:.6g}",
        f"values verified by {summary.verification.by.value}",
        f"{summary.search.evaluations} policies evaluated ({summary.search.algorithm}, seed {summary.seed})",
    ]
    if run.optimality is not None and run.optimality.gap is not None:
        facts.append(f"gap to the certified bound {100 * run.optimality.gap:.1f} %")
    header = Div(
        text=f"<h2>parley: {run.case_study}</h2><p>{'; '.join(facts)}. Knee policy: {summary.selected}.</p>",
        width=STACKED_WIDTH if stacked else 1040,
    )
    notes = Div(text=_notes(run, i, j, coloured), name="plot-notes", width=width)
    front_views = column(plot, readout, notes, counter, *sliders)
    layout = (
        column(header, front_views, column(*views)) if stacked else column(header, row(front_views, column(*views)))
    )
    return stable_ids(file_html(layout, INLINE, title=f"parley report: {run.case_study}"))
