"""A tighter ideal point: the quotient's relaxation read as a POMDP, bounded by Storm's
belief exploration.

The relaxation's schedulers see the true state; a policy sees only what the URC observes.
Read as a POMDP whose observation at a state is the set of decisions it consults
(:func:`parley_core.quotient.relaxation.observations`), every policy is a memoryless
observation-based scheduler, so the POMDP's optimum over all observation-based schedulers
(with memory) bounds every policy's value, and never more loosely than the MDP's. Storm's
belief discretization (Freudenthal triangulation, :func:`stormpy.pomdp.verify_with_belief_discretization`)
over-approximates that optimum: an upper limit for a maximised objective, a lower one for a
minimised one.

Storm answers only unbounded reachability probabilities (``P [F psi]``) and expected
reachability rewards (``R [F psi]``) this way; every other objective keeps the MDP's value
(:func:`parley_core.bound.ideal_point`). A step-bounded reward (``C<=k``: robot_grid's cost,
every objective of web_ids and tas) would need the step counter unfolded into the POMDP.
"""

from __future__ import annotations

import re
import time

import numpy as np

from parley_core.bound import PRECISION, Bound, ideal_point, relaxation_queries, sound_environment
from parley_core.model import Direction, Family
from parley_core.quotient.bounds import RelaxedObjectives
from parley_core.quotient.coloring import Quotient
from parley_core.quotient.relaxation import storm_model

RESOLUTION = 2
"""The discretization's resolution: higher is tighter and costs more (robot_grid 5x5: 0.2 s
at 2, 1.3 s at 3)."""

_UNTIL = re.compile(r'^(P(?:max|min)=\?) \[true U ("[^"]+")\]$')
_REWARD = re.compile(r'^R\{"[^"]+"\}(?:max|min)=\? \[F "[^"]+"\]$')


def belief_query(query: str | None) -> str | None:
    """The relaxation's query (:func:`parley_core.bound.relaxation_queries`) as Storm's
    belief exploration takes it, or None where it takes no such query."""
    if query is None:
        return None
    until = _UNTIL.match(query)
    if until:
        return f"{until.group(1)} [F {until.group(2)}]"
    return query if _REWARD.match(query) else None


def belief_ideal(
    family: Family,
    quotient: Quotient,
    bounds: RelaxedObjectives | None = None,
    resolution: int = RESOLUTION,
    ideal: Bound | None = None,
) -> Bound:
    """The ideal point (``ideal``, else :func:`~parley_core.bound.ideal_point`), each objective
    Storm's belief exploration answers replaced by the POMDP's over-approximation where that
    is tighter (widened by the solver's precision); ``details`` holds both values per
    objective."""
    import stormpy
    import stormpy.pomdp

    start = time.perf_counter()
    bounds = bounds or RelaxedObjectives(family, quotient)
    ideal = ideal or ideal_point(family, quotient, bounds)
    labels, queries = relaxation_queries(family, quotient)
    asked = [belief_query(q) for q in queries]
    point = np.array(ideal.points[0], dtype=float)
    details: dict[str, object] = {}
    if any(q is not None for q in asked):
        model = storm_model(bounds.relaxation, labels, pomdp=True)
        environment = sound_environment(PRECISION, relative=True)
        for i, (objective, query) in enumerate(zip(family.objectives, asked)):
            if query is None:
                continue
            (prop,) = stormpy.parse_properties(query)
            try:
                result = stormpy.pomdp.verify_with_belief_discretization(
                    model, prop, resolution=resolution, environment=environment
                )
            except RuntimeError as error:  # Storm refuses this POMDP or query: the MDP's value stands
                details[objective.name] = {"mdp": float(ideal.points[0][i]), "error": str(error).splitlines()[0]}
                continue
            value = float(result.value)
            # sound value iteration to PRECISION of the value, on either side of it: widened by twice that
            slack = 2 * PRECISION * max(1.0, abs(value)) if np.isfinite(value) else 0.0
            if objective.direction is Direction.MAX:
                point[i] = min(point[i], value + slack)
            else:
                point[i] = max(point[i], value - slack)
            details[objective.name] = {"mdp": float(ideal.points[0][i]), "pomdp": value}
    return Bound(
        objectives=family.objectives,
        points=point.reshape(1, -1),
        method=(
            "ideal point: per objective the best over the quotient's relaxation, read as a POMDP "
            f"where Storm's belief discretization (resolution {resolution}) answers"
        ),
        seconds=ideal.seconds + time.perf_counter() - start,
        details={"belief": details},
    )
