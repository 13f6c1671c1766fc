"""Verification: every value on a front is Storm's.

A front found with the quotient evaluator is re-checked by Storm (sound value iteration at
1e-12); the result records the largest difference between the two, and Storm's values
replace the search's. Storm checks *policy programs* by default, many policies per build
(:mod:`parley_core.evaluate.batch`, :data:`VerifyPath.BATCH`), or the augmented program one
policy at a time (the reference, :data:`VerifyPath.REFERENCE`); the result says which.
A front found with the Storm evaluator is Storm's already. Campaigns may skip the re-check
for time and say so (:attr:`Verified.NOT_CHECKED`), and re-check later (``parley
experiment verify``).
"""

from __future__ import annotations

import enum
import time
from typing import Any

import numpy as np
from attrs import frozen

from parley_core.errors import EvaluatorDisagreement, ModelError, OptionError
from parley_core.metrics import TIE_TOLERANCE
from parley_core.model import Family
from parley_core.progress import NullReporter, Reporter

TOLERANCE = TIE_TOLERANCE
"""How far the search's evaluator may be from Storm: 1e-9 times the value's size (at least
1); values of a front this close are ties (:func:`parley_core.metrics.tie_points`)."""


class VerifyPath(enum.Enum):
    """How Storm was given the policies (the value is what run files record)."""

    BATCH = "policy programs"
    """The original model with each service constant a formula of the observation and the
    policy, several policies per program (:mod:`parley_core.evaluate.batch`)."""
    REFERENCE = "augmented program"
    """The augmented model with the decision constants defined, one policy per build."""

    @classmethod
    def of(cls, path: VerifyPath | str) -> VerifyPath:
        if isinstance(path, VerifyPath):
            return path
        names = {"batch": cls.BATCH, "reference": cls.REFERENCE}
        if path in names:
            return names[path]
        try:
            return cls(path)
        except ValueError:
            raise OptionError(f"unknown verification path {path!r}; valid: batch, reference") from None


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
    """Front policies re-checked."""
    max_difference: float
    seconds: float
    max_relative_difference: float = float("nan")
    """The largest difference relative to the value's size (at least 1): what :data:`TOLERANCE` bounds."""
    baselines: int = 0
    """Baselines re-checked besides the front's policies."""
    path: str = ""
    """How Storm was given the policies (a :class:`VerifyPath` value; empty when Storm did not re-check)."""
    scenarios: int = 1
    """Scenarios each policy was checked in (a robust run: :mod:`parley_core.robust`)."""

    def to_json(self) -> dict[str, object]:
        return {
            "by": self.by.value,
            "path": self.path,
            "policies": self.policies,
            "baselines": self.baselines,
            "max_difference": self.max_difference,
            "max_relative_difference": self.max_relative_difference,
            "tolerance": TOLERANCE,
            "seconds": self.seconds,
            "scenarios": self.scenarios,
        }

    @classmethod
    def from_json(cls, data: dict) -> Verification:
        return cls(
            by=Verified(data["by"]),
            policies=int(data.get("policies", 0)),
            max_difference=float(data.get("max_difference", float("nan"))),
            seconds=float(data.get("seconds", 0.0)),
            max_relative_difference=float(data.get("max_relative_difference", float("nan"))),
            baselines=int(data.get("baselines", 0)),
            path=str(data.get("path", "")),
            scenarios=int(data.get("scenarios", 1)),
        )


def by_search() -> Verification:
    """The front was found with Storm: its values are Storm's."""
    return Verification(by=Verified.STORM_SEARCH, policies=0, max_difference=0.0, seconds=0.0)


def not_checked() -> Verification:
    return Verification(by=Verified.NOT_CHECKED, policies=0, max_difference=float("nan"), seconds=0.0)


def differences(searched: np.ndarray, checked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Absolute differences and differences relative to the checked value's size (at least
    1); where both are the same infinity, both are 0, where only one is infinite, inf."""
    searched = np.asarray(searched, dtype=float)
    checked = np.asarray(checked, dtype=float)
    same = (searched == checked) | (np.isnan(searched) & np.isnan(checked))
    with np.errstate(invalid="ignore"):
        absolute = np.where(same, 0.0, np.abs(searched - checked))
    absolute = np.where(np.isnan(absolute), np.inf, absolute)
    scale = np.maximum(1.0, np.abs(np.where(np.isfinite(checked), checked, 0.0)))
    return absolute, absolute / scale


def _decisions(family: Family, row: np.ndarray, shown: int = 6) -> str:
    """A policy by its first decisions: ``c_0_0=3, c_0_1=10, ... (100 decisions)``."""
    parts = [f"{name}={int(value)}" for name, value in zip(family.names[:shown], row)]
    more = f", ... ({len(family.names)} decisions)" if len(family.names) > shown else ""
    return f"with {', '.join(parts)}{more}"


def check_with_storm(
    family: Family,
    policies: np.ndarray,
    values: np.ndarray,
    workers: int | None = None,
    reporter: Reporter | None = None,
    names: list[str | None] | None = None,
    baselines: int = 0,
    path: VerifyPath | str = VerifyPath.BATCH,
) -> tuple[Verification, np.ndarray]:
    """Storm's values of ``policies``, and how far they are from ``values`` (the search's).

    A difference beyond :data:`TOLERANCE` is a parley defect, not a figure:
    :class:`~parley_core.errors.EvaluatorDisagreement` names the policy, the objective and
    both values. ``names`` name the policies in that message (None: by their decisions);
    the first ``baselines`` rows are the baselines, counted apart in the result. ``path``:
    how Storm gets the policies (:class:`VerifyPath`; :func:`storm_verifier` says when the
    reference path stands in for policy programs)."""
    reporter = reporter or NullReporter()
    start = time.perf_counter()
    storm, path = storm_verifier(family, path, workers, reporter)
    with storm:
        reporter.stage("verify with Storm", len(policies))
        checked = storm.evaluate(policies, progress=reporter.advance)
    absolute, relative = differences(values, checked)
    if len(values) and (relative > TOLERANCE).any():
        row, column = np.unravel_index(int(np.argmax(relative)), relative.shape)
        name = names[row] if names else None
        policy = name if name is not None else _decisions(family, policies[row])
        objective = family.objectives[column].name
        raise EvaluatorDisagreement(
            f"the search's evaluator and Storm disagree on policy {policy}, objective {objective}: "
            f"{float(values[row, column])!r} against Storm's {float(checked[row, column])!r} "
            f"(relative difference {float(relative[row, column]):.1e}, tolerance {TOLERANCE:g}); "
            "this is a defect of parley's fast evaluator: rerun with --evaluator storm and report it"
        )
    verification = Verification(
        by=Verified.STORM_RECHECK,
        policies=len(policies) - baselines,
        baselines=baselines,
        max_difference=float(absolute.max()) if len(values) else 0.0,
        max_relative_difference=float(relative.max()) if len(values) else 0.0,
        seconds=time.perf_counter() - start,
        path=path.value,
    )
    return verification, checked


def storm_verifier(
    family: Family,
    path: VerifyPath | str = VerifyPath.BATCH,
    workers: int | None = None,
    reporter: Reporter | None = None,
) -> tuple[Any, VerifyPath]:
    """The Storm evaluator of a verification path, and the path it takes.

    Policy programs are written from the family's original model: a family read back from
    files has none and takes the reference path; so does a model parley cannot write policy
    programs for (it uses the names parley needs, say), and the reporter says so."""
    from parley_core.evaluate.storm import StormEvaluator

    if VerifyPath.of(path) is VerifyPath.BATCH and family.system is not None:
        from parley_core.evaluate.batch import BatchStormEvaluator

        try:
            return BatchStormEvaluator(family, workers=workers), VerifyPath.BATCH
        except (ModelError, RuntimeError) as exc:
            (reporter or NullReporter()).note(
                f"Storm checks the augmented model, one policy at a time: no policy programs for this model ({exc})"
            )
    return StormEvaluator(family, workers=workers), VerifyPath.REFERENCE
