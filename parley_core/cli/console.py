"""What the commands draw: progress bars on stderr, tables and JSON documents on stdout."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from rich.table import Table

from parley_core.model import Valued
from parley_core.plugin.casestudy import CaseStudy
from parley_core.plugin.options import options_as_dict
from parley_core.views.richprogress import RichReporter, progress_bars, stderr  # noqa: F401  (re-exported)

if TYPE_CHECKING:
    import numpy as np


def fmt(value: float) -> str:
    return f"{value:.6g}" if abs(value) >= 1e-3 or value == 0 else f"{value:.3e}"


WIDE = 4
"""More extra columns than this (a baseline's constants of a 16-hole family) are shown as one."""


def front_table(
    title: str,
    front: Valued,
    extra: dict[str, list[Any]] | None = None,
    limit: int = 40,
    points: Sequence[int] | np.ndarray | None = None,
) -> Table:
    """The set as a table of at most ``limit`` rows, evenly spaced; with ``points`` (each
    policy's tie point, :func:`parley_core.metrics.tie_points`) one row per point, naming its
    first policy and how many others tie with it."""
    table = Table(title=title, title_justify="left")
    table.add_column("policy")
    extra = _narrow(extra or {})
    for name in extra:
        table.add_column(name, justify="right")
    for objective in front.objectives:
        table.add_column(f"{objective.name} ({objective.direction.value})", justify="right")
    firsts = list(range(len(front)))
    ties: dict[int, int] = {}
    if points is not None:
        counts = Counter(int(p) for p in points)
        seen: dict[int, int] = {}
        for i, point in enumerate(points):
            seen.setdefault(int(point), i)
        firsts = sorted(seen.values())
        ties = {i: counts[int(points[i])] - 1 for i in firsts}
    rows = firsts
    if len(rows) > limit:
        step = (len(rows) - 1) / (limit - 1)
        rows = [firsts[j] for j in sorted({round(i * step) for i in range(limit)})]
    for i in rows:
        name = front.policies[i].name + (f" (+{ties[i]} tied)" if ties.get(i) else "")
        cells = [name, *(str(column[i]) for column in extra.values()), *(fmt(v) for v in front.values[i])]
        table.add_row(*cells)
    unit = "points" if points is not None else "policies"
    if len(rows) < len(firsts):
        table.caption = f"{len(rows)} of {len(firsts)} {unit} shown, evenly spaced; all are in front.csv"
    return table


def _narrow(extra: dict[str, list[Any]]) -> dict[str, list[Any]]:
    """The columns that vary; more than :data:`WIDE` of them as one column of their values."""
    varying = {name: column for name, column in extra.items() if len(set(map(str, column))) > 1} or extra
    if len(varying) <= WIDE:
        return varying
    names = list(varying)
    rows = len(next(iter(varying.values())))
    joined = [" ".join(str(varying[n][i]) for n in names) for i in range(rows)]
    return {f"{names[0]}..{names[-1]} ({len(names)} varying)": joined}


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
