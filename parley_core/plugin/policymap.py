"""What a case study's map looks like, for the interactive report's policy view: the two
observation variables that are its axes, the cells nobody can be in (walls, obstacles),
and labelled cells (start, target). A plugin gives one through ``CaseStudy.policy_map``;
the run directory keeps it as ``map.json`` so the page can be made again from the files."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from attrs import field, frozen

from parley_core.docstrings import fields_in_help


def _cells(rows) -> tuple[tuple[int, int], ...]:
    return tuple((int(x), int(y)) for x, y in rows)


def _marks(rows) -> tuple[tuple[str, int, int], ...]:
    return tuple((str(label), int(x), int(y)) for label, x, y in rows)


@fields_in_help
@frozen(kw_only=True)
class PolicyMap:
    x: str
    """The observation variable along the horizontal axis (robot_grid: ``xhat``)."""
    y: str
    """... and along the vertical axis, drawn upwards (robot_grid: ``yhat``)."""
    width: int
    height: int
    blocked: tuple[tuple[int, int], ...] = field(default=(), converter=_cells)
    """Cells drawn dark: obstacles, walls."""
    marks: tuple[tuple[str, int, int], ...] = field(default=(), converter=_marks)
    """(label, x, y): cells drawn with a label, such as the start ``S`` and the target ``T``."""

    def to_json(self) -> dict[str, Any]:
        return {
            "x": self.x,
            "y": self.y,
            "width": self.width,
            "height": self.height,
            "blocked": [list(c) for c in self.blocked],
            "marks": [list(m) for m in self.marks],
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> PolicyMap:
        return cls(
            x=data["x"],
            y=data["y"],
            width=int(data["width"]),
            height=int(data["height"]),
            blocked=data.get("blocked", ()),
            marks=data.get("marks", ()),
        )
