"""Evaluators: policies (an int array, one row per policy, one column per decision) -> objective values.

:class:`~parley_core.evaluate.storm.StormEvaluator` is the reference and the judge of
correctness: it instantiates the decision constants, builds the DTMC with Storm and checks
each objective. :class:`~parley_core.evaluate.quotient.QuotientEvaluator` is the fast path
(:mod:`parley_core.quotient`). :func:`make_evaluator` picks one by :class:`EvaluatorKind`.
"""

from __future__ import annotations

import enum
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from parley_core.errors import OptionError
from parley_core.progress import Progress

if TYPE_CHECKING:
    from parley_core.model import Family
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
    """Evaluates policies of one family; values are in the objectives' own units and directions."""

    name: str

    def evaluate(self, policies: np.ndarray, progress: Progress | None = None) -> np.ndarray:
        """``policies`` [n, n_decisions] int -> values [n, n_objectives] float."""
        ...

    def close(self, abort: bool = False) -> None:
        """Release worker processes and other resources; the evaluator may not be used
        afterwards. ``abort``: an error or Ctrl-C is on its way up, end the workers at once."""
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
