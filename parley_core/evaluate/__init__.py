"""Evaluators: policies (an int array, one row per policy, one column per decision) -> objective values.

:class:`~parley_core.evaluate.storm.StormEvaluator` is the reference and the judge of
correctness: it instantiates the decision constants, builds the DTMC with Storm and checks
each objective.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np

Progress = Callable[[int], None]
"""Called with the number of policies finished since the last call."""


@runtime_checkable
class Evaluator(Protocol):
    """Evaluates policies of one family; values are in the objectives' own units and directions."""

    name: str

    def evaluate(self, policies: np.ndarray, progress: Progress | None = None) -> np.ndarray:
        """``policies`` [n, n_decisions] int -> values [n, n_objectives] float."""
        ...

    def close(self) -> None:
        """Release worker processes and other resources; the evaluator may not be used afterwards."""
        ...
