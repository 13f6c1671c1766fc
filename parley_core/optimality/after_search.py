"""The bounds a run computes after its search: the cheap certified outer bound of the
family (:mod:`parley_core.optimality.bound`, :mod:`parley_core.optimality.belief`) and branch and bound over the
decisions' ranges (:mod:`parley_core.optimality.branch_and_bound`), seeded with what the search evaluated."""

from __future__ import annotations

from typing import TYPE_CHECKING

import attrs

from parley_core.evaluate import Evaluator, QuotientBacked
from parley_core.model import Family
from parley_core.optimality.records import BoundMethod
from parley_core.progress import Reporter

if TYPE_CHECKING:
    from parley_core.optimality.bound import Bound
    from parley_core.optimality.requirement import Answer, Requirement
    from parley_core.search import SearchResult


def family_bound(family: Family, method: BoundMethod | str = BoundMethod.PARETO) -> Bound:
    """A family's cheap bound on its own ("pareto", "ideal" or "belief"): what a campaign stores."""
    return outer(family, None, method)[0]


def outer(family: Family, engine: Evaluator | None, method: BoundMethod | str, seconds: float | None = None):
    """The cheap bound (the ideal point; cut by weighted sums for "pareto", and for "belief"
    after the ideal point is tightened on the relaxation read as a POMDP, Storm's belief
    exploration stopped after ``seconds`` per objective) and the family's relaxed objectives
    it was computed on, for branch and bound to reuse."""
    from parley_core.optimality.bound import ideal_point, pareto_outer
    from parley_core.quotient.bounds import RelaxedObjectives
    from parley_core.quotient.coloring import build_quotient

    method = BoundMethod.of(method, cheap=True)
    quotient = engine.quotient if isinstance(engine, QuotientBacked) else build_quotient(family)
    # the weighted sums on as many threads as the evaluator has workers (idle while the bound runs)
    bounds = RelaxedObjectives(family, quotient, threads=engine.workers if engine is not None else 1)
    found = ideal_point(family, quotient, bounds)
    if method is BoundMethod.IDEAL:
        return found, bounds
    if method is BoundMethod.PARETO:
        return pareto_outer(family, quotient, found, bounds), bounds
    from parley_core.optimality.belief import belief_ideal

    found = belief_ideal(family, quotient, bounds, ideal=found, seconds=seconds)  # the relaxation as a POMDP
    cut = pareto_outer(family, quotient, found, bounds)
    if cut is found:
        return found, bounds
    return attrs.evolve(cut, method=f"{cut.method}; {found.method}", belief=found.belief), bounds


def _progress(reporter: Reporter, stage: str):
    """A progress callback that advances ``reporter``'s new stage by fractions of 1,000 steps."""
    steps = 1000
    reporter.stage(stage, steps)
    done = 0

    def progress(fraction: float) -> None:
        nonlocal done
        now = min(steps, int(fraction * steps))
        if now > done:
            reporter.advance(now - done)
            done = now

    return progress


def answer(
    family: Family,
    engine: Evaluator,
    requirement: Requirement,
    result: SearchResult,
    seconds: float | None,
    reporter: Reporter,
) -> Answer:
    """Branch and bound driven by a requirement's box (:mod:`parley_core.optimality.requirement`),
    seeded with everything the search evaluated, for at most ``seconds``."""
    from parley_core.optimality.requirement import answer as answer_box
    from parley_core.quotient.bounds import RelaxedObjectives
    from parley_core.quotient.coloring import build_quotient

    progress = _progress(reporter, "branch and bound (requirement)")
    boxes = engine if isinstance(engine, QuotientBacked) else None
    quotient = boxes.quotient if boxes is not None else build_quotient(family)
    seeds = (result.policies, result.values)
    if boxes is not None:
        seeds = boxes.box_seeds(*seeds)
    return answer_box(
        family,
        quotient,
        engine.evaluate,
        requirement,
        seeds=seeds,
        time_limit=seconds,
        progress=progress,
        bounds=RelaxedObjectives(family, quotient, threads=engine.workers),
        fronts=boxes.submit_box_fronts if boxes is not None else None,
        whole=boxes is not None and boxes.walks_boxes(),
    )


def refine(family: Family, engine: Evaluator, result: SearchResult, seconds: float | None, reporter: Reporter, cheap):
    """Branch and bound after the search, seeded with everything the search evaluated and
    started from the cheap bound's half-spaces (``cheap``: what :func:`outer` returns); with
    the seeds' values as branch and bound took them (:meth:`QuotientEvaluator.box_seeds`)."""
    from parley_core.optimality.branch_and_bound import branch_and_bound

    found, bounds = cheap
    progress = _progress(reporter, "branch and bound")
    seeds = (result.policies, result.values)
    boxes = engine if isinstance(engine, QuotientBacked) else None
    if boxes is not None:
        seeds = boxes.box_seeds(*seeds)
    exact = branch_and_bound(
        family,
        bounds.quotient,
        engine.evaluate,
        seeds=seeds,
        time_limit=seconds,
        progress=progress,
        root_cuts=found.cuts,
        bounds=bounds,
        fronts=boxes.submit_box_fronts if boxes is not None else None,
        whole=boxes is not None and boxes.walks_boxes(),
    )
    return exact, seeds[1]
