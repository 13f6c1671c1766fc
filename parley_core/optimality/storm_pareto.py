"""Storm's own multi-objective Pareto query on the quotient's relaxation: a second view of
the curve that the kernels' outer bound (:func:`parley_core.optimality.bound.pareto_outer`) covers.

Storm's multi-objective model checking (``multi(...)``, its PCAA method) accepts the
relaxation's objectives, step-bounded cumulative rewards included, and answers with two
polytopes: an *under*-approximation, spanned by values that schedulers of the relaxation
reach, and an *over*-approximation of what they can reach. The under-approximation's vertices are points some relaxed scheduler achieves
(to Storm's precision), so every sound outer bound of the relaxation weakly dominates them:
the tests hold :func:`~parley_core.optimality.bound.pareto_outer`'s staircase, computed by parley's own
backward induction, against this independent implementation. Storm's over-approximation is
not used as a bound: its weighted sums come from value iteration that bounds no error.
"""

from __future__ import annotations

import time

import numpy as np
from attrs import field, frozen

from parley_core.errors import ModelError
from parley_core.model import Family
from parley_core.optimality.bound import relaxation_queries
from parley_core.quotient.bounds import RelaxedObjectives
from parley_core.quotient.coloring import Quotient
from parley_core.quotient.relaxation import storm_model


@frozen(kw_only=True)
class StormPareto:
    """Storm's answer to the multi-objective query, in the objectives' own units."""

    query: str
    achieved: np.ndarray = field(eq=False)
    """Vertices of the under-approximation: values relaxed schedulers reach."""
    seconds: float


def storm_pareto(family: Family, quotient: Quotient, precision: float = 1e-6) -> StormPareto:
    """Storm's Pareto approximation of the relaxation's objectives, to ``precision`` (Storm's
    distance between the two polytopes); a :class:`~parley_core.errors.ModelError` when an
    objective has no query on the relaxation or Storm refuses the combination."""
    import stormpy

    start = time.perf_counter()
    relaxation = RelaxedObjectives(family, quotient).relaxation
    labels, queries = relaxation_queries(family, quotient)
    if len(queries) < 2:
        raise ModelError("a multi-objective query needs at least two objectives")
    missing = [o.name for o, q in zip(family.objectives, queries) if q is None]
    if missing:
        raise ModelError(f"no query on the relaxation for objective(s) {', '.join(missing)}")
    text = "multi(" + ", ".join(q.text for q in queries if q is not None) + ")"
    model = storm_model(relaxation, labels)
    (prop,) = stormpy.parse_properties(text)
    environment = stormpy.Environment()
    environment.modelchecker().multi().precision = stormpy.Rational(precision)
    try:
        result = stormpy.model_checking(model, prop, environment=environment)
    except RuntimeError as exc:
        raise ModelError(f"Storm cannot answer {text}: {exc}") from None
    return StormPareto(
        query=text,
        achieved=np.array(result.get_under_approximation().vertices, dtype=float).reshape(-1, len(queries)),
        seconds=time.perf_counter() - start,
    )
