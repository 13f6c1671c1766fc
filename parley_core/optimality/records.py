"""What the certified bounds report, as value objects: the bound methods a run may ask for,
how branch and bound stopped and what it counted, and the belief bound's values per
objective. The run directory's ``summary.json`` carries them (:mod:`parley_core.rundir.summary`).
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from typing import Any

from attrs import frozen

from parley_core.errors import OptionError


class BoundMethod(enum.Enum):
    """The certified bound a run computes after its search (``--bound``)."""

    PARETO = "pareto"
    """The relaxation's ideal box cut by weighted sums: an outer approximation of its Pareto curve."""
    IDEAL = "ideal"
    """The best per objective over all schedulers of the relaxation."""
    BELIEF = "belief"
    """``pareto`` on an ideal point tightened by Storm's belief exploration (the relaxation as a POMDP)."""
    REFINE = "refine"
    """Branch and bound over the decisions' ranges after the search (exact when it finishes)."""
    NONE = "none"
    """No bound."""

    @classmethod
    def of(cls, method: BoundMethod | str, *, cheap: bool = False) -> BoundMethod:
        """The method named ``method``; with ``cheap``, one of the bounds computed from the
        relaxation alone (what a campaign stores per instance)."""
        valid = [m for m in cls if m.cheap or not cheap]
        try:
            found = method if isinstance(method, BoundMethod) else cls(method)
        except ValueError:
            found = None
        if found not in valid:
            raise OptionError(f"unknown --bound {method!r}; valid: {', '.join(m.value for m in valid)}")
        return found

    @property
    def cheap(self) -> bool:
        """One of the bounds computed from the relaxation alone (no branch and bound)."""
        return self in (BoundMethod.PARETO, BoundMethod.IDEAL, BoundMethod.BELIEF)


class Stopped(enum.Enum):
    """Why branch and bound stopped."""

    COMPLETE = "complete"
    """Every sub-family pruned or evaluated: the front is exact."""
    TIME = "time"
    """Its time limit."""
    INTERRUPTED = "interrupted"
    """Ctrl-C."""
    FOUND = "found"
    """A policy inside the requirement's box (``parley check``): nothing more is asked."""


@frozen(kw_only=True)
class SearchCounts:
    """What branch and bound did: sub-families (nodes) bounded and pruned, policies evaluated,
    policies without a value, sub-families left open, and why it stopped."""

    nodes: int
    pruned: int
    evaluated: int
    open: int
    unknown: int
    stopped_by: Stopped

    def to_json(self) -> dict[str, Any]:
        return {
            "nodes": self.nodes,
            "pruned": self.pruned,
            "evaluated": self.evaluated,
            "open": self.open,
            "unknown": self.unknown,
            "stopped_by": self.stopped_by.value,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> SearchCounts:
        return cls(
            nodes=int(data["nodes"]),
            pruned=int(data["pruned"]),
            evaluated=int(data["evaluated"]),
            open=int(data.get("open", 0)),
            unknown=int(data.get("unknown", 0)),
            stopped_by=Stopped(data.get("stopped_by", Stopped.COMPLETE.value)),
        )


@frozen(kw_only=True)
class BeliefValue:
    """One objective's ideal value on the relaxation as an MDP and, where Storm's belief
    exploration answered, as a POMDP (else why it did not)."""

    mdp: float
    pomdp: float | None = None
    error: str | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"mdp": self.mdp}
        if self.pomdp is not None:
            out["pomdp"] = self.pomdp
        if self.error is not None:
            out["error"] = self.error
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> BeliefValue:
        pomdp, error = data.get("pomdp"), data.get("error")
        return cls(
            mdp=float(data["mdp"]),
            pomdp=None if pomdp is None else float(pomdp),
            error=None if error is None else str(error),
        )
