"""What the commands draw: progress bars on stderr, tables and JSON documents on stdout."""

from __future__ import annotations

from typing import Any

from rich.table import Table

from parley_core.model import Valued
from parley_core.plugin.casestudy import CaseStudy
from parley_core.plugin.options import options_as_dict
from parley_core.views.richprogress import RichReporter, progress_bars, stderr  # noqa: F401  (re-exported)


def fmt(value: float) -> str:
    return f"{value:.6g}" if abs(value) >= 1e-3 or value == 0 else f"{value:.3e}"


def front_table(title: str, front: Valued, extra: dict[str, list[Any]] | None = None, limit: int = 40) -> Table:
    table = Table(title=title, title_justify="left")
    table.add_column("policy")
    for name in extra or {}:
        table.add_column(name, justify="right")
    for objective in front.objectives:
        table.add_column(f"{objective.name} ({objective.direction.value})", justify="right")
    rows = list(range(len(front)))
    if len(rows) > limit:
        step = (len(rows) - 1) / (limit - 1)
        rows = sorted({round(i * step) for i in range(limit)})
    for i in rows:
        cells = [front.policies[i].name]
        cells += [str(column[i]) for column in (extra or {}).values()]
        cells += [fmt(v) for v in front.values[i]]
        table.add_row(*cells)
    if len(rows) < len(front):
        table.caption = f"{len(rows)} of {len(front)} policies shown, evenly spaced; all are in front.csv"
    return table


def values_json(
    case: CaseStudy, options: Any, front: Valued, decisions: list[dict[str, int]] | None = None
) -> dict[str, Any]:
    policies = []
    for i, (policy, row) in enumerate(zip(front.policies, front.values)):
        entry: dict[str, Any] = {"policy": policy.name, "values": {o.name: v for o, v in zip(front.objectives, row)}}
        if decisions is not None:
            entry["decisions"] = decisions[i]
        policies.append(entry)
    return {
        "case_study": case.name,
        "options": options_as_dict(options),
        "objectives": [o.to_json() for o in front.objectives],
        "policies": policies,
    }
