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
(:func:`parley_core.optimality.bound.ideal_point`). A step-bounded reward (``C<=k``: robot_grid's cost,
every objective of web_ids and tas) would need the step counter unfolded into the POMDP.

Storm's belief exploration has no time limit of its own and does not answer Ctrl-C; on a
small model it ran for minutes without a result (the hand-written breaking model's
``R{"once"}=? [F broken]``, ``tests/test_quotient.py``). Each query therefore runs in a
process of its own, stopped after :data:`SECONDS` (or the caller's limit); the MDP's value
stands for that objective, and the bound's details say so.
"""

from __future__ import annotations

import os
import signal
import time

import numpy as np
from loky.backend.context import get_context

from parley_core.evaluate.pool import may_start_processes
from parley_core.model import Direction, Family
from parley_core.optimality.bound import PRECISION, Bound, ideal_point, relaxation_queries, sound_environment
from parley_core.optimality.records import BeliefValue
from parley_core.quotient.bounds import RelaxedObjectives
from parley_core.quotient.coloring import Quotient
from parley_core.quotient.relaxation import storm_model

SECONDS = 60.0
"""How long Storm's belief exploration may take per objective, from the start of its process
(importing stormpy there takes about a second)."""
RESOLUTION = 2
"""The discretization's resolution: higher is tighter and costs more (robot_grid 5x5: 0.2 s
at 2, 1.3 s at 3)."""


def _discretize(relaxation, labels, query: str, resolution: int, connection) -> None:
    """In a process of its own: Storm's belief discretization of the relaxation read as a
    POMDP, sent as ("value", v) or ("error", the first line of Storm's refusal)."""
    import stormpy
    import stormpy.pomdp

    model = storm_model(relaxation, labels, pomdp=True)
    (prop,) = stormpy.parse_properties(query)
    try:
        result = stormpy.pomdp.verify_with_belief_discretization(
            model, prop, resolution=resolution, environment=sound_environment(PRECISION, relative=True)
        )
    except RuntimeError as error:  # Storm refuses this POMDP or query
        connection.send(("error", str(error).splitlines()[0]))
        return
    connection.send(("value", float(result.value)))


def _within(relaxation, labels, query: str, resolution: int, seconds: float) -> tuple[str, float | str]:
    """:func:`_discretize` in a spawned process, stopped after ``seconds``: ("value", v), or
    ("error", why) when Storm refused, died or ran out of time."""
    if not may_start_processes():
        return "error", "Storm's belief exploration needs a process of its own, and this one may start none"
    context = get_context("loky")  # spawned without re-running the caller's main module
    receive, send = context.Pipe(duplex=False)
    process = context.Process(target=_discretize, args=(relaxation, labels, query, resolution, send), daemon=True)
    process.start()
    send.close()
    try:
        if receive.poll(seconds):
            return receive.recv()
        return "error", f"Storm's belief exploration did not finish in {seconds:g} s (stopped)"
    except EOFError:
        return "error", f"Storm's belief exploration ended without an answer (exit status {process.exitcode})"
    finally:
        if process.is_alive():
            os.kill(process.pid, signal.SIGKILL)  # loky's processes have no kill()
        process.join()
        receive.close()


def belief_ideal(
    family: Family,
    quotient: Quotient,
    bounds: RelaxedObjectives | None = None,
    resolution: int = RESOLUTION,
    ideal: Bound | None = None,
    seconds: float | None = None,
) -> Bound:
    """The ideal point (``ideal``, else :func:`~parley_core.optimality.bound.ideal_point`), each objective
    Storm's belief exploration answers within ``seconds`` (default :data:`SECONDS`) replaced by
    the POMDP's over-approximation where that is tighter (widened by the solver's precision);
    ``belief`` holds both values per objective, or the MDP's and why Storm gave none."""
    start = time.perf_counter()
    seconds = SECONDS if seconds is None else seconds
    bounds = bounds or RelaxedObjectives(family, quotient)
    ideal = ideal or ideal_point(family, quotient, bounds)
    labels, queries = relaxation_queries(family, quotient)
    asked = [None if q is None else q.eventually() for q in queries]
    point = np.array(ideal.points[0], dtype=float)
    details: dict[str, BeliefValue] = {}
    for i, (objective, query) in enumerate(zip(family.objectives, asked)):
        if query is None:
            continue
        kind, answer = _within(bounds.relaxation, labels, query, resolution, seconds)
        if kind == "error":  # the MDP's value stands
            details[objective.name] = BeliefValue(mdp=float(ideal.points[0][i]), error=str(answer))
            continue
        value = float(answer)
        # sound value iteration to PRECISION of the value, on either side of it: widened by twice that
        slack = 2 * PRECISION * max(1.0, abs(value)) if np.isfinite(value) else 0.0
        if objective.direction is Direction.MAX:
            point[i] = min(point[i], value + slack)
        else:
            point[i] = max(point[i], value - slack)
        details[objective.name] = BeliefValue(mdp=float(ideal.points[0][i]), pomdp=value)
    return Bound(
        objectives=family.objectives,
        points=point.reshape(1, -1),
        method=(
            "ideal point: per objective the best over the quotient's relaxation, read as a POMDP "
            f"where Storm's belief discretization (resolution {resolution}) answers"
        ),
        seconds=ideal.seconds + time.perf_counter() - start,
        belief=details,
    )
