"""Verification: every value on a front is Storm's.

A front found with the quotient evaluator is re-checked policy by policy by the Storm
evaluator (sound value iteration at 1e-12); the result records the largest difference
between the two, and Storm's values replace the search's. A front found with the Storm
evaluator is Storm's already. Campaigns may skip the re-check for time and say so
(:attr:`Verified.NOT_CHECKED`), and re-check later (``parley experiment verify``).
"""

from __future__ import annotations

import enum
import time

import numpy as np
from attrs import frozen

from parley_core.model import Family
from parley_core.progress import NullReporter, Reporter


class Verified(enum.Enum):
    """Who vouches for a front's values (the value is what run files and stores record)."""

    STORM_SEARCH = "storm (the search's own evaluator)"
    STORM_RECHECK = "storm"
    NOT_CHECKED = "none (values of the quotient evaluator)"

    @property
    def by_storm(self) -> bool:
        return self is not Verified.NOT_CHECKED


@frozen(kw_only=True)
class Verification:
    by: Verified
    policies: int
    max_difference: float
    seconds: float

    def to_json(self) -> dict[str, object]:
        return {
            "by": self.by.value,
            "policies": self.policies,
            "max_difference": self.max_difference,
            "seconds": self.seconds,
        }

    @classmethod
    def from_json(cls, data: dict) -> Verification:
        return cls(
            by=Verified(data["by"]),
            policies=int(data.get("policies", 0)),
            max_difference=float(data.get("max_difference", float("nan"))),
            seconds=float(data.get("seconds", 0.0)),
        )


def by_search() -> Verification:
    """The front was found with Storm: its values are Storm's."""
    return Verification(by=Verified.STORM_SEARCH, policies=0, max_difference=0.0, seconds=0.0)


def not_checked() -> Verification:
    return Verification(by=Verified.NOT_CHECKED, policies=0, max_difference=float("nan"), seconds=0.0)


def check_with_storm(
    family: Family,
    policies: np.ndarray,
    values: np.ndarray,
    workers: int | None = None,
    reporter: Reporter | None = None,
) -> tuple[Verification, np.ndarray]:
    """Storm's values of ``policies``, and how far they are from ``values`` (the search's)."""
    from parley_core.evaluate.storm import StormEvaluator

    reporter = reporter or NullReporter()
    start = time.perf_counter()
    with StormEvaluator(family, workers=workers) as storm:
        reporter.stage("verify with Storm", len(policies))
        checked = storm.evaluate(policies, progress=reporter.advance)
    difference = float(np.abs(checked - values).max()) if len(values) else 0.0
    verification = Verification(
        by=Verified.STORM_RECHECK,
        policies=len(policies),
        max_difference=difference,
        seconds=time.perf_counter() - start,
    )
    return verification, checked
