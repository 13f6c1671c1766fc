"""Boxes of a family: per decision an interval of positions in its domain.

Branch and bound (:mod:`parley_core.optimality.branch_and_bound`) hands whole boxes to an evaluator that can
enumerate them where the policies are solved (the quotient's workers), so that only each
box's own non-dominated values travel back: a box of 4,096 web_ids policies returns a few
dozen rows instead of 4,096.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from attrs import field, frozen

FLOOR = -1e300
"""An infinitely bad value in sign space is still a value: it is compared as this."""


@frozen
class Box:
    """Positions ``lo[d]..hi[d]`` (inclusive) in each decision's domain."""

    lo: np.ndarray = field(eq=False)
    hi: np.ndarray = field(eq=False)

    @property
    def size(self) -> int:
        return int(np.prod(self.hi - self.lo + 1, dtype=np.int64))


@frozen(kw_only=True)
class BoxValues:
    """What an evaluator gives back for boxes: the rows of each box's own front and their
    values (in box order), how many policies it evaluated, and the seconds that cost (wall
    time, shared over the processes that solved them)."""

    rows: np.ndarray = field(eq=False)
    values: np.ndarray = field(eq=False)
    evaluated: int
    seconds: float


class Pending(Protocol):
    """Boxes being evaluated: ``done()`` and ``result()`` as a
    :class:`concurrent.futures.Future`'s."""

    def done(self) -> bool: ...

    def result(self) -> BoxValues: ...


@frozen
class Ready:
    """Boxes already evaluated (in this process)."""

    value: BoxValues

    def done(self) -> bool:
        return True

    def result(self) -> BoxValues:
        return self.value


def box_rows(box: Box, domains: list[np.ndarray]) -> np.ndarray:
    """The box's policies (rows of decision values), the last decision varying fastest."""
    widths = box.hi - box.lo + 1
    index = np.arange(box.size, dtype=np.int64)
    rows = np.empty((len(index), len(domains)), dtype=np.int64)
    for d in range(len(domains) - 1, -1, -1):
        index, digit = np.divmod(index, widths[d])
        rows[:, d] = domains[d][box.lo[d] + digit]
    return rows


def local_front(values: np.ndarray, signs: np.ndarray) -> np.ndarray:
    """Indices of the rows no other row weakly dominates in sign space (of equal values the
    first), NaN rows left out: exactly the rows that could enter a branch and bound archive
    that already holds the others (:class:`parley_core.optimality.branch_and_bound.Archive` rejects what it weakly
    dominates)."""
    values = np.asarray(values, dtype=float).reshape(-1, len(signs))
    finite = ~np.isnan(values).any(axis=1)
    candidates = np.flatnonzero(finite)
    if not len(candidates):
        return candidates
    points = np.maximum(values[candidates] * signs, FLOOR)
    # sort so that a dominating point precedes what it dominates: lexicographically
    # descending, equal points in their original order (np.lexsort is stable)
    order = np.lexsort(tuple(-points[:, k] for k in range(points.shape[1] - 1, -1, -1)))
    if points.shape[1] == 2:
        # descending first objective: a point is kept when its second beats every earlier one
        second = points[order, 1]
        before = np.concatenate([[-np.inf], np.maximum.accumulate(second)[:-1]])
        kept = order[second > before]
    else:
        chosen: list[int] = []
        best = np.zeros((0, points.shape[1]))
        for i in order:
            if not len(best) or not (best >= points[i]).all(axis=1).any():
                chosen.append(int(i))
                best = np.vstack([best, points[i]])
        kept = np.array(chosen, dtype=np.int64)
    return np.sort(candidates[kept])
