"""Polishing a front by predicted hypervolume (``polished``): the relaxation's scores as a surrogate.

After a search has found roughly where the front is, most of what it still lacks is close
to points it already has: the same policies with one decision changed. There are many such
neighbours (on a 10x10 map, 900 per policy) and the evaluator's budget is small, so which
ones to evaluate is the whole question. :class:`~parley_core.quotient.improve.PolicyImprover`
answers it: its scores give, for every decision and value, the first-order change of each
objective (by the performance-difference lemma, on the quotient's relaxation), so one
computation of a front policy's scores predicts the values of all its one-decision
neighbours. Each round:

1. ``expand`` front policies not yet expanded get their scores (the front's two ends and
   the policies beside its widest gaps first: on map_10 and map_12 that reached 0.99974 and
   0.99978 of the best known front at 1,000 evaluations, against 0.99967 and 0.99966 for
   front policies drawn at random), and their neighbours join a pool with their predicted
   values;
2. the pool's predictions are ranked by the hypervolume each would add to the current front
   (exactly, for two objectives), then those the front dominates by how near below it they
   are;
3. the best ``batch`` of them not yet evaluated are evaluated (by the search's evaluator,
   through the archive: they count towards the budget and are the values the run reports).

Predictions only choose what to evaluate; a wrong prediction costs one evaluation. Where the
relaxation cannot predict (no quotient, objectives that do not combine into a weighted sum),
or the family has other than two objectives, or the search has constraints (the ranking
does not take them into account yet), nothing is polished and :class:`Polished` says why.
Deterministic by seed.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

import numpy as np
from attrs import frozen

from parley_core.evaluate.cache import CachingEvaluator
from parley_core.metrics import nondominated
from parley_core.model import Family

if TYPE_CHECKING:
    from parley_core.quotient.improve import PolicyImprover

BATCH = 20
"""Policies evaluated a round."""
EXPAND = 4
"""Front policies whose scores are computed a round (expanding fewer, only while the pool
held fewer than ``batch`` predictions above the front, reached 0.9981 and 0.9976 on map_10 and
map_12 instead of 0.9998: predictions from earlier, now dominated parents mislead)."""


@frozen(kw_only=True)
class Polished:
    """What :func:`polish` did: evaluations spent, front policies expanded (scores computed)."""

    evaluations: int
    expanded: int
    seconds: float
    skipped: str = ""


def staircase(front: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A two-objective front (rows, both maximised, mutually non-dominated) sorted by the
    first objective: its first and second coordinates (the second then decreasing)."""
    order = np.argsort(front[:, 0], kind="stable")
    return front[order, 0], front[order, 1]


def dominated(front: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Which ``points`` some point of ``front`` weakly dominates (two objectives, maximised)."""
    xs, ys = staircase(front)
    at = np.searchsorted(xs, points[:, 0], side="left")  # the first front point at least as far right
    height = np.where(at < len(xs), ys[np.minimum(at, len(xs) - 1)], -np.inf)
    return height >= points[:, 1]


def shortfall(front: np.ndarray, points: np.ndarray) -> np.ndarray:
    """How far below the staircase of ``front`` each of ``points`` is, as a share of the
    front's extent in each objective (the smaller of the two; 0 for a point on or above it)."""
    xs, ys = staircase(front)
    span = np.maximum(np.ptp(front, axis=0), 1e-12) if len(front) > 1 else np.ones(2)
    at = np.searchsorted(xs, points[:, 0], side="left")
    height = np.where(at < len(xs), ys[np.minimum(at, len(xs) - 1)], -np.inf)
    down = np.clip(height - points[:, 1], 0.0, None) / span[1]
    right = np.searchsorted(-ys, -points[:, 1], side="right") - 1  # the last front point at least as high
    across = np.where(right >= 0, np.clip(xs[np.maximum(right, 0)] - points[:, 0], 0.0, None) / span[0], np.inf)
    return np.minimum(down, across)


def contributions(front: np.ndarray, points: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """The hypervolume (above ``reference``) each of ``points`` would add to ``front`` alone
    (two objectives, maximised; points above the reference): the area under the point's
    corner and above the front's staircase, by prefix sums over the staircase's steps."""
    xs, ys = staircase(front)
    keep = (xs > reference[0]) & (ys > reference[1])
    xs, ys = xs[keep], ys[keep]
    lefts = np.concatenate([[reference[0]], xs])  # step i covers (lefts[i], lefts[i + 1]] at heights[i]
    heights = np.concatenate([ys, [reference[1]]])
    widths = np.diff(lefts)
    area = np.concatenate([[0.0], np.cumsum(widths * heights[:-1])])
    width = np.concatenate([[0.0], np.cumsum(widths)])
    x, y = points[:, 0], points[:, 1]
    first = np.searchsorted(-heights, -y, side="right")  # the first step lower than the point
    last = np.searchsorted(lefts, x, side="left") - 1  # the step the point's corner lies in
    last = np.maximum(last, 0)
    inner = np.minimum(first, last)
    whole = (y * (width[last] - width[inner])) - (area[last] - area[inner])  # steps first..last-1
    part = (y - heights[last]) * (x - lefts[last])
    return np.where((first <= last) & (x > reference[0]) & (y > reference[1]), whole + part, 0.0)


def _ranked(
    front: np.ndarray,
    reference: np.ndarray,
    predicted: np.ndarray,
    open_: np.ndarray,
    below: np.ndarray,
    used: np.ndarray,
) -> Iterator[int]:
    """The open pool entries in the order polishing tries them: the predicted hypervolume gain
    first; where none is predicted, the nearest below the front. A gain is at least 0 and a
    shortfall's rank at most -1, so the entries above the front come first, each group in the
    pool's order. ``below`` is updated for the entries not yet known to be below (once below,
    always below: the front only grows); those below are ranked only when the caller asks for
    more than the entries above (lazily: ``used`` then says which the caller took)."""
    unsettled = open_[~below[open_]]
    below[unsettled] = dominated(front, predicted[unsettled])
    above = open_[~below[open_]]
    yield from above[np.argsort(-contributions(front, predicted[above], reference), kind="stable")].tolist()
    low = open_[below[open_] & ~used[open_]]
    # ranked by shortfall + 1 (the order since polishing began: shortfalls below 1e-16 tie
    # there, and are taken in the pool's order)
    yield from low[np.argsort(shortfall(front, predicted[low]) + 1.0, kind="stable")].tolist()


def unavailable(family: Family, improver: PolicyImprover | str, constrained: bool = False) -> str:
    """Why :func:`polish` cannot run ("": it can): ``improver`` is the family's
    (:func:`~parley_core.quotient.improve.improver_for`) or why there is none. A search that
    cannot polish gives the whole budget to its first stage."""
    if len(family.objectives) != 2:
        return "polishing ranks two objectives only"
    if constrained:
        return "polishing does not rank by constraints"
    return improver if isinstance(improver, str) else ""


def polish(
    family: Family,
    archive: CachingEvaluator,
    improver: PolicyImprover,
    budget: int,
    seed: int,
    *,
    batch: int = BATCH,
    expand: int = EXPAND,
    seconds: float | None = None,
    progress: Callable[[int], None] | None = None,
) -> Polished:
    """Spend the archive's evaluations up to ``budget`` on the neighbours of its front with the
    largest predicted hypervolume gain (module docstring; :func:`unavailable` says where it
    cannot run). ``seconds``: stop after this long (None: no limit); ``progress`` is called
    after every round."""
    start = time.perf_counter()
    if not len(archive):
        return Polished(evaluations=0, expanded=0, seconds=0.0, skipped="nothing evaluated to polish")
    rng = np.random.default_rng(seed)
    signs = improver.signs
    directions = [o.direction for o in family.objectives]
    expanded: set[bytes] = set()
    parents: list[np.ndarray] = []  # pool: parent policy, decision, new value, predicted values
    pool_parent = np.zeros(0, dtype=np.int64)
    pool_decision = np.zeros(0, dtype=np.int64)
    pool_value = np.zeros(0, dtype=np.int64)
    pool_predicted = np.zeros((0, 2))
    used = np.zeros(0, dtype=bool)
    below = np.zeros(0, dtype=bool)  # predicted below the front: for good, as the front only grows
    before = len(archive)
    while len(archive) < budget:
        if seconds is not None and time.perf_counter() - start > seconds:
            break
        values = archive.values * signs
        finite = np.isfinite(values).all(axis=1)
        members = np.flatnonzero(finite)[nondominated(archive.values[finite], directions)]
        front = values[members]
        reference = values[finite].min(axis=0) - 1e-9 * np.maximum(1.0, np.abs(values[finite].min(axis=0)))
        policies, _ = archive.rows(members)
        fresh = [i for i in range(len(members)) if policies[i].tobytes() not in expanded]
        # the front's ends and the policies beside its widest gaps first (ties in seeded order)
        order = np.argsort(front[:, 0], kind="stable")
        gaps = (front[order[1:], 0] - front[order[:-1], 0]) * (front[order[:-1], 1] - front[order[1:], 1])
        priority = np.zeros(len(front))
        priority[order[:-1]] = gaps
        priority[order[1:]] = np.maximum(priority[order[1:]], gaps)
        priority[order[[0, -1]]] = np.inf
        shuffled = rng.permutation(len(fresh))
        picks = shuffled[np.argsort(-priority[np.asarray(fresh, dtype=np.int64)][shuffled], kind="stable")]
        chosen_parents = [policies[fresh[i]] for i in (picks[:expand] if fresh else [])]
        at_of = [improver.positions(p) for p in chosen_parents]
        added: list[tuple[np.ndarray, ...]] = []
        for parent, at, (scores, own) in zip(chosen_parents, at_of, improver.gradients_of(at_of)):
            expanded.add(parent.tobytes())
            delta = scores - scores[:, np.arange(len(at)), at][:, :, None]  # [objective, decision, value]
            valid = np.isfinite(delta).all(axis=0)
            valid[np.arange(len(at)), at] = False
            decision, position = np.nonzero(valid)
            parents.append(parent)
            added.append(
                (
                    np.full(len(decision), len(parents) - 1),
                    decision,
                    improver.table[decision, position],
                    (own[:, None] + delta[:, decision, position]).T,
                )
            )
        if added:  # one copy of the pool a round
            pool_parent = np.concatenate([pool_parent, *(a[0] for a in added)])
            pool_decision = np.concatenate([pool_decision, *(a[1] for a in added)])
            pool_value = np.concatenate([pool_value, *(a[2] for a in added)])
            pool_predicted = np.vstack([pool_predicted, *(a[3] for a in added)])
            fresh_count = sum(len(a[0]) for a in added)
            used = np.concatenate([used, np.zeros(fresh_count, dtype=bool)])
            below = np.concatenate([below, np.zeros(fresh_count, dtype=bool)])
        open_ = np.flatnonzero(~used)
        if not len(open_):
            break
        chosen: list[np.ndarray] = []
        keys: set[bytes] = set()
        for j in _ranked(front, reference, pool_predicted, open_, below, used):
            used[j] = True
            child = parents[pool_parent[j]].copy()
            child[pool_decision[j]] = pool_value[j]
            key = child.tobytes()
            if key in keys or child in archive:
                continue
            keys.add(key)
            chosen.append(child)
            if len(chosen) >= min(batch, budget - len(archive)):
                break
        if chosen:
            archive.evaluate(np.array(chosen, dtype=np.int64))
        if progress:
            progress(1)
    return Polished(evaluations=len(archive) - before, expanded=len(expanded), seconds=time.perf_counter() - start)
