"""Evaluators: policies (an int array, one row per policy, one column per decision) -> objective values.

:class:`~parley_core.evaluate.storm.StormEvaluator` is the reference and the judge of
correctness: it instantiates the decision constants, builds the DTMC with Storm and checks
each objective. :class:`~parley_core.evaluate.quotient.QuotientEvaluator` is the fast path
(:mod:`parley_core.quotient`). :func:`make_evaluator` picks one by :class:`EvaluatorKind`.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from parley_core.errors import OptionError
from parley_core.model import Family, Policy, Valued
from parley_core.progress import NullReporter, Progress, Reporter

if TYPE_CHECKING:
    from parley_core.boxes import Box, Pending
    from parley_core.quotient.coloring import Quotient
    from parley_core.quotient.mdp import QuotientMDP


class EvaluatorKind(enum.Enum):
    """The evaluators a run can search with."""

    QUOTIENT = "quotient"
    """One MDP for all policies, solved by compiled kernels (fast; the default)."""
    STORM = "storm"
    """Build and check each policy's DTMC with Storm (the reference)."""

    @classmethod
    def of(cls, kind: EvaluatorKind | str) -> EvaluatorKind:
        try:
            return cls(kind)
        except ValueError:
            raise OptionError(f"unknown evaluator {kind!r}; valid: {', '.join(k.value for k in cls)}") from None


@runtime_checkable
class Evaluator(Protocol):
    """Evaluates policies of one family; values are in the objectives' own units and directions.

    Optional capabilities are protocols of their own, asked with ``isinstance``: a
    :class:`Consulting` evaluator also says which decisions each policy consulted, a
    :class:`QuotientBacked` one holds the family's quotient that bounds and branch and bound
    work on."""

    name: str

    @property
    def workers(self) -> int:
        """Worker processes it evaluates on (1: in this process)."""
        ...

    def evaluate(self, policies: np.ndarray, progress: Progress | None = None) -> np.ndarray:
        """``policies`` [n, n_decisions] int -> values [n, n_objectives] float."""
        ...

    def describe(self) -> dict[str, object]:
        """What a run's summary.json records of it (``evaluator_details``; empty: nothing)."""
        ...

    def close(self, abort: bool = False) -> None:
        """Release worker processes and other resources; the evaluator may not be used
        afterwards. ``abort``: an error or Ctrl-C is on its way up, end the workers at once."""
        ...


@runtime_checkable
class Consulting(Evaluator, Protocol):
    """An evaluator that also says which decisions each policy consulted (those of the
    valuations its reachable states observe): the search's cache keeps them."""

    def evaluate_consulted(
        self, policies: np.ndarray, progress: Progress | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Values [n, n_objectives] and consulted decisions [n, n_decisions] bool."""
        ...


@runtime_checkable
class QuotientBacked(Consulting, Protocol):
    """An evaluator on the family's quotient MDP: bounds are computed on its quotient, and
    branch and bound evaluates whole boxes of policies through it."""

    quotient: Quotient

    def submit_box_fronts(self, boxes: list[Box], signs: np.ndarray) -> Pending:
        """Start evaluating ``boxes`` (in sign space ``signs``); each box's own non-dominated rows."""
        ...

    def box_seeds(self, rows: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Seeds for branch and bound: ``rows`` with their values as box evaluation gives them."""
        ...

    def walks_boxes(self) -> bool:
        """Whether box evaluation walks boxes (then branch and bound evaluates whole ones)."""
        ...


def make_evaluator(
    family: Family,
    kind: EvaluatorKind | str = EvaluatorKind.QUOTIENT,
    workers: int | None = None,
    mdp: QuotientMDP | None = None,
) -> Evaluator:
    """The evaluator of ``kind`` for the family (``mdp``: a quotient MDP to reuse)."""
    kind = EvaluatorKind.of(kind)
    if kind is EvaluatorKind.QUOTIENT:
        from parley_core.evaluate.quotient import QuotientEvaluator

        return QuotientEvaluator(family, workers=workers, mdp=mdp)
    from parley_core.evaluate.storm import StormEvaluator

    return StormEvaluator(family, workers=workers)


def evaluate_policies(
    family: Family,
    policies: Sequence[Policy],
    evaluator: Evaluator,
    reporter: Reporter | None = None,
    stage: str = "evaluate",
) -> Valued:
    """All ``policies`` with their values, in the given order."""
    reporter = reporter or NullReporter()
    for policy in policies:
        family.check(policy)
    reporter.stage(stage, len(policies))
    rows = np.array([p.values for p in policies], dtype=np.int64).reshape(-1, len(family.decisions))
    values = evaluator.evaluate(rows, progress=reporter.advance)
    return Valued(objectives=family.objectives, policies=policies, values=values)
