"""The report's policy view on a map: a grid over two observation variables, each cell
coloured by the decision there, for the policy shown (the data source it shares with the
decision table). With the plugin's map (``map.json``, :class:`parley_core.plugin.policymap.PolicyMap`)
the axes are the map's, obstacles are dark and the start and target are labelled; any other
observation variable (turtlebot's heading) gets a menu that picks the slice shown."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from parley_core.plugin.policymap import PolicyMap
from parley_core.rundir.read import RunDirectory
from parley_core.views.bokeh_scripts import SLICE


def read_map(directory: Path) -> PolicyMap | None:
    path = directory / "map.json"
    return PolicyMap.from_json(json.loads(path.read_text())) if path.is_file() else None


DISCRETE = 16
"""Decisions with at most this many values get one colour band per value."""


def decision_colours(low: int, high: int) -> Any:
    """The colour scale of a decision's values, as the plugins' policy.png draw them
    (viridis reversed: small values yellow, large ones purple), with one band per integer
    value where there are at most :data:`DISCRETE` of them."""
    from bokeh.models import LinearColorMapper
    from bokeh.palettes import Viridis256, viridis

    count = high - low + 1
    if count <= DISCRETE:
        palette = tuple(reversed(viridis(count)))
        return LinearColorMapper(palette=palette, low=low - 0.5, high=high + 0.5, nan_color="white")
    return LinearColorMapper(palette=tuple(reversed(Viridis256)), low=low, high=high, nan_color="white")


def grids(run: RunDirectory, table_source: Any, columns: dict[str, list[Any]]) -> list[Any]:
    """The grid figures (one per service, at most three) and the slice menus, or nothing
    when the URC observes fewer than two variables."""
    from bokeh.models import BooleanFilter, CDSView, ColorBar, CustomJS, Range1d, Select
    from bokeh.plotting import figure

    observation = list(run.observation)
    found = read_map(run.path)
    if found is not None and {found.x, found.y} <= set(observation):
        x, y = found.x, found.y
    elif len(observation) >= 2:
        x, y = observation[0], observation[1]
    else:
        return []
    others = [v for v in observation if v not in (x, y)]
    rows = len(columns[x])
    chosen = {v: min(columns[v]) for v in others}
    shown = BooleanFilter(booleans=[all(columns[v][r] == chosen[v] for v in others) for r in range(rows)])
    view = CDSView(filter=shown)
    menus = []
    for variable in others:
        values = sorted(set(columns[variable]))
        menu = Select(
            title=f"{variable} (the grid shows one value)",
            value=str(chosen[variable]),
            options=[str(v) for v in values],
            name=f"slice-{variable}",
            width=200,
        )
        menus.append(menu)
    if menus:
        callback = CustomJS(
            args={"source": table_source, "filter": shown, "menus": menus, "variables": others}, code=SLICE
        )
        for menu in menus:
            menu.js_on_change("value", callback)
    views: list[Any] = []
    if found is not None:
        x_span, y_span = (-0.5, found.width - 0.5), (-0.5, found.height - 0.5)
    else:
        x_span = (min(columns[x]) - 0.5, max(columns[x]) + 0.5)
        y_span = (min(columns[y]) - 0.5, max(columns[y]) + 0.5)
    for service in run.services[:3]:
        mapper = decision_colours(service.low, service.high)
        grid = figure(
            width=420,
            height=380,
            title=f"{service.name} ({service.constant}) per observation of the URC",
            x_axis_label=x,
            y_axis_label=y,
            x_range=Range1d(*x_span, bounds=x_span),
            y_range=Range1d(*y_span, bounds=y_span),
            tools="hover,pan,wheel_zoom,reset",
            tooltips=[(v, f"@{v}") for v in observation] + [(service.constant, f"@{service.constant}")],
            name=f"policy-map-{service.constant}",
        )
        grid.rect(
            x,
            y,
            0.95,
            0.95,
            source=table_source,
            view=view,
            fill_color={"field": service.constant, "transform": mapper},
            line_color=None,
            name=f"policy-cells-{service.constant}",
        )
        if found is not None and found.blocked:  # over the cells: an obstacle is never hidden
            grid.rect(
                [c[0] for c in found.blocked],
                [c[1] for c in found.blocked],
                1.0,
                1.0,
                color="#262626",
                name="map-blocked",
            )
        if found is not None and found.marks:
            grid.text(
                [m[1] - 0.3 for m in found.marks],
                [m[2] + 0.3 for m in found.marks],
                text=[m[0] for m in found.marks],
                text_color="crimson",
                text_font_style="bold",
                text_font_size="11px",
                text_baseline="middle",
                text_align="center",
                name="map-marks",
            )
        grid.add_layout(
            ColorBar(color_mapper=mapper, title=service.constant, name=f"colours-{service.constant}"), "right"
        )
        views.append(grid)
    return menus + views
