"""Sets of valued policies as tables for notebooks: a pandas DataFrame (pandas is optional,
``pip install 'parley[notebook]'``) and the HTML Jupyter shows for a front or a baseline.
:class:`Tabular` is the mixin that gives :class:`~parley_core.model.Valued` both."""

from __future__ import annotations

import html
import math
from typing import Any

from parley_core.errors import OptionError

SHOWN = 12
"""Rows of a long set shown in HTML: the first and the last ``SHOWN // 2``."""


class Tabular:
    """``to_pandas()`` and ``_repr_html_()`` for a class with ``objectives``, ``policies``
    and ``values`` (one row per policy)."""

    __slots__ = ()

    def to_pandas(self) -> Any:
        """One row per policy (indexed by its name), one column per objective."""
        try:
            import pandas
        except ImportError:
            raise OptionError("to_pandas needs pandas; install it with `pip install 'parley[notebook]'`") from None
        this: Any = self
        frame = pandas.DataFrame(
            [list(row) for row in this.values],
            columns=[o.name for o in this.objectives],
            index=pandas.Index([p.name for p in this.policies], name="policy"),
        )
        return frame

    def _repr_html_(self) -> str:
        this: Any = self
        count = len(this.policies)
        rows = list(range(count))
        if count > SHOWN:
            rows = rows[: SHOWN // 2] + [-1] + rows[count - SHOWN // 2 :]
        head = "".join(f"<th>{html.escape(o.name)} ({o.direction.value})</th>" for o in this.objectives)
        body = []
        for i in rows:
            if i < 0:
                body.append(f"<tr><td colspan='{len(this.objectives) + 1}'>... {count - SHOWN} more ...</td></tr>")
                continue
            cells = "".join(f"<td>{_number(v)}</td>" for v in this.values[i])
            body.append(f"<tr><th>{html.escape(this.policies[i].name)}</th>{cells}</tr>")
        kind = type(self).__name__
        return (
            f"<table><caption>{kind}: {count} polic{'y' if count == 1 else 'ies'}</caption>"
            f"<thead><tr><th>policy</th>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"
        )


def _number(value: float) -> str:
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return f"{value:.6g}"
