"""Where a search starts: walks of policy improvement on the relaxation (``guided``, ``guided-small``).

NSGA-II spends most of its first thousand evaluations finding where the front is. The
quotient's relaxation knows more than the evaluator tells: for a policy and a weighting of
the objectives, :class:`~parley_core.quotient.improve.PolicyImprover` scores every value of
every decision by how it would change the policy's weighted value. :func:`guided_start`
walks from the baselines along ``directions`` weightings spread over the front:

1. take the best baseline under the weighting (walks from different baselines find
   different parts of the front; walks that continued from the best policy found so far
   ended on the same few points);
2. move every decision to its best-scored value (one computation of the scores serves every
   weighting that stands at the same policy: they are linear in the weights), and evaluate
   the results of all walks together (with the search's own evaluator, through the archive,
   so they count towards the budget and are the values the run reports);
3. keep walking where the weighted value grew, at most ``steps`` times (three: on map_10 and
   map_19 six found no better front at 1,000 evaluations, in half again the time).

Every policy evaluated on the way joins the archive. ``guided`` (the paper's NSGA-II) puts
them into its first population after the baselines; ``guided-small`` leaves them in the
archive, whose front half of its parents come from (put into ``small``'s first population,
they crowded out the random draws, and the search ended lower on map_19: 0.9989 of the best
known front at 4,000 evaluations against ``small``'s 0.9993). The walks are deterministic
(no random draws), so the configurations stay deterministic by seed. Where the relaxation
cannot guide (no quotient, objectives that do not combine into a weighted sum, see
:class:`~parley_core.quotient.improve.PolicyImprover`, no baseline to start from), nothing is
walked and the search starts as its configuration does unguided; :class:`Walked` says which.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np
from attrs import frozen

from parley_core.evaluate.cache import CachingEvaluator
from parley_core.model import Family

if TYPE_CHECKING:
    from parley_core.quotient.improve import PolicyImprover

DIRECTIONS = 12
STEPS = 3
SHARE = 0.25
"""At most this share of the search's evaluation budget goes to the walks."""


@frozen(kw_only=True)
class Walked:
    """What :func:`guided_start` did: the policies it evaluated (in order), or why it did nothing."""

    policies: np.ndarray
    seconds: float
    skipped: str = ""


def weightings(values: np.ndarray, count: int) -> np.ndarray:
    """``count`` weightings (rows, >= 0) spread over the directions between the objectives,
    each objective scaled by the spread of ``values`` (rows of objective values, any sign) so
    that no objective's units decide the spacing; with more than two objectives, the points
    of a lattice of the simplex inside it."""
    values = np.asarray(values, dtype=float)
    objectives = values.shape[1]
    finite = np.where(np.isfinite(values), values, np.nan)
    span = np.nanmax(finite, axis=0) - np.nanmin(finite, axis=0) if len(finite) else np.ones(objectives)
    span = np.where(np.isfinite(span) & (span > 1e-12), span, 1.0)
    if objectives == 2:
        angles = np.linspace(0.0, np.pi / 2, count + 2)[1:-1]
        raw = np.column_stack([np.cos(angles), np.sin(angles)])
    else:
        parts = objectives  # the smallest lattice with at least ``count`` points inside the simplex
        while math.comb(parts - 1, objectives - 1) < count:
            parts += 1
        grid = np.array(np.meshgrid(*[np.arange(parts + 1)] * objectives)).reshape(objectives, -1).T
        raw = grid[(grid.sum(axis=1) == parts) & (grid > 0).all(axis=1)].astype(float)
    return raw / span


def guided_start(
    family: Family,
    archive: CachingEvaluator,
    improver: PolicyImprover | str,
    budget: int | None,
    directions: int = DIRECTIONS,
    steps: int = STEPS,
    seconds: float | None = None,
) -> Walked:
    """Walk from the baselines by policy improvement (module docstring); the policies
    evaluated on the way are in ``archive``. ``improver``: the family's
    (:func:`~parley_core.quotient.improve.improver_for`), or why there is none; ``budget``:
    the search's evaluation budget (None: unlimited), of which at most :data:`SHARE` is spent
    here; ``seconds``: the search's time limit (None: none), after which no walk takes another
    step (then the walks depend on the machine's speed, as a time-limited search does anyway)."""
    start = time.perf_counter()
    empty = np.zeros((0, len(family.decisions)), dtype=np.int64)
    if isinstance(improver, str):
        return Walked(policies=empty, seconds=0.0, skipped=improver)
    baselines = np.array([p.values for p in family.baseline_policies()], dtype=np.int64)
    baselines = baselines.reshape(-1, len(family.decisions))
    signs = improver.signs
    # every search evaluates the baselines first anyway; within the budget, as it would
    room = None if budget is None else max(0, budget - len(archive))
    start_values = archive.evaluate(baselines, budget=room) * signs
    start_values = np.where(np.isfinite(start_values), start_values, -np.inf)
    before = len(archive)
    cap = None if budget is None else min(int(SHARE * budget), max(0, budget - before))
    if not np.isfinite(start_values).any(axis=1).any():
        return Walked(policies=empty, seconds=time.perf_counter() - start, skipped="no baseline was evaluated")
    directions_ = weightings(start_values, directions)
    firsts = [int(np.argmax(start_values @ w)) for w in directions_]
    walks = [(w, improver.positions(baselines[i]), float(start_values[i] @ w)) for w, i in zip(directions_, firsts)]
    gradients: dict[bytes, np.ndarray] = {}
    walked: list[np.ndarray] = []
    for _ in range(steps):
        if seconds is not None and time.perf_counter() - start > seconds:
            break
        wanted = {current.tobytes(): current for _, current, _ in walks if current.tobytes() not in gradients}
        for key, (scores, _) in zip(wanted, improver.gradients_of(list(wanted.values()))):
            gradients[key] = scores
        moves = []
        for weights, current, level in walks:
            moved = improver.improve(current, gradients[current.tobytes()], weights)
            if not np.array_equal(moved, current):
                moves.append((weights, moved, level))
        if cap is not None:
            moves = moves[: max(0, cap - (len(archive) - before))]
        if not moves:
            break
        candidates = np.array([improver.values(moved) for _, moved, _ in moves])
        new = [c for c in candidates if c not in archive]
        values = archive.evaluate(candidates) * signs
        walked += new
        walks = []
        for (weights, moved, level), value in zip(moves, values):
            reached = float(np.where(np.isfinite(value), value, -np.inf) @ weights)
            if reached > level + 1e-12 * max(1.0, abs(level)):
                walks.append((weights, moved, reached))
    unique = {row.tobytes(): row for row in walked}  # in the order first evaluated
    policies = np.array(list(unique.values()), dtype=np.int64).reshape(-1, len(family.decisions))
    return Walked(policies=policies, seconds=time.perf_counter() - start)
