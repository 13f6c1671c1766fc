"""Quality of fronts: non-domination, hypervolume, spread, knee point.

Values are given in the objectives' own units with their directions (a tuple of
:class:`~parley_core.model.Direction`); each function converts to minimization itself.
Hypervolume and non-domination come from moocore.
"""

from __future__ import annotations

from collections.abc import Sequence

import moocore
import numpy as np

from parley_core.boxes import FLOOR
from parley_core.model import Direction, Objective


def _maximize(directions: Sequence[Direction]) -> list[bool]:
    return [d is Direction.MAX for d in directions]


def _as_min(values: np.ndarray, directions: Sequence[Direction]) -> np.ndarray:
    return np.asarray(values, dtype=float).reshape(-1, len(directions)) * np.array([d.sign for d in directions])


def nondominated(values: np.ndarray, directions: Sequence[Direction]) -> np.ndarray:
    """Boolean mask of the points no other point dominates; of equal points only the first is kept."""
    values = np.asarray(values, dtype=float).reshape(-1, len(directions))
    if len(values) == 0:
        return np.zeros(0, dtype=bool)
    return np.asarray(moocore.is_nondominated(values, maximise=_maximize(directions), keep_weakly=False))


TIE_TOLERANCE = 1e-9
"""Values of a set closer than this times their objective's largest magnitude there (at
least 1, :func:`tie_scale`) are ties: the verification tolerance, within which the search's
evaluator and Storm may differ (:data:`parley_core.verify.TOLERANCE`)."""


def _maximised(values: np.ndarray, directions: Sequence[Direction]) -> np.ndarray:
    """Values to maximise, an infinitely bad value clamped to :data:`~parley_core.boxes.FLOOR`."""
    signs = np.where(_maximize(directions), 1.0, -1.0)
    return np.maximum(np.asarray(values, dtype=float).reshape(-1, len(directions)) * signs, FLOOR)


def tie_scale(values: np.ndarray, tolerance: float = TIE_TOLERANCE) -> np.ndarray:
    """Per objective, how close two of these values must be to tie: ``tolerance`` times the
    objective's largest finite magnitude here (at least 1). One width per objective keeps
    the tie relation the same for every pair (a front's costs of 20 and of 100 tie at the
    same distance)."""
    values = np.asarray(values, dtype=float)
    finite = np.where(np.isfinite(values), np.abs(values), 0.0)
    return tolerance * np.maximum(1.0, finite.max(axis=0) if len(values) else 1.0)


def _near(part: np.ndarray, others: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """[len(part), len(others)]: within ``scale`` of each other in every objective."""
    return (np.abs(part[:, None, :] - others[None, :, :]) <= scale).all(axis=2)


def tolerant_front(values: np.ndarray, directions: Sequence[Direction], tolerance: float = TIE_TOLERANCE) -> np.ndarray:
    """Boolean mask of the points on the front once values within the tolerance
    (:func:`tie_scale`) are ties: a point is off it when a point on it is no worse in every
    objective (up to a tie) and better beyond a tie in one. Every point of a tie is kept
    (:func:`tie_points` groups them); a point that differs from another by float noise only,
    which exact comparison would call dominated or keep as a point of its own, is a tie. Points
    are decided best first (by their sum in tolerance units), so that with two objectives a
    point's dominators are decided before it and every point left off is dominated by one
    kept. NaN rows are never on it."""
    values = np.asarray(values, dtype=float).reshape(-1, len(directions))
    keep = np.zeros(len(values), dtype=bool)
    rows = np.flatnonzero(~np.isnan(values).any(axis=1))
    if not len(rows):
        return keep
    points = _maximised(values[rows], directions)
    scale = tie_scale(values[rows], tolerance)
    exact = points[np.asarray(moocore.is_nondominated(points, maximise=True, keep_weakly=True))]
    # a point off the exact front can only be on this one as a tie of an exact front point
    close = np.zeros(len(points), dtype=bool)
    for lo in range(0, len(points), 1024):
        close[lo : lo + 1024] = _near(points[lo : lo + 1024], exact, scale).any(axis=1)
    candidates = np.flatnonzero(close)
    units = np.where(points[candidates] > FLOOR, points[candidates], 0.0) / scale
    order = candidates[np.lexsort((np.arange(len(candidates)), -units.sum(axis=1)))]
    kept = np.empty((len(order), points.shape[1]))  # the points kept so far, in order
    count = 0
    for i in order:
        others = kept[:count]
        no_worse = (others >= points[i] - scale).all(axis=1)
        if not (no_worse & (others > points[i] + scale).any(axis=1)).any():
            kept[count] = points[i]
            count += 1
            keep[rows[i]] = True
    return keep


def tie_points(values: np.ndarray, directions: Sequence[Direction], tolerance: float = TIE_TOLERANCE) -> np.ndarray:
    """The point (1, 2, ...) of each row, in order of first appearance: rows within the
    tolerance (:func:`tie_scale`) of each other in every objective, directly or through
    other rows, are one point (so no two points of a front are ties)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    points = _maximised(values, directions)
    if not len(points):
        return np.zeros(0, dtype=np.int64)
    scale = tie_scale(values, tolerance)
    pairs = [np.argwhere(_near(points[lo : lo + 1024], points, scale)) + [lo, 0] for lo in range(0, len(points), 1024)]
    edges = np.vstack(pairs)
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(len(points), len(points)))
    _, labels = connected_components(graph, directed=False)
    first: dict[int, int] = {}
    return np.array([first.setdefault(int(label), len(first) + 1) for label in labels], dtype=np.int64)


def distinct_front(values: np.ndarray, directions: Sequence[Direction], tolerance: float = TIE_TOLERANCE) -> np.ndarray:
    """The values of :func:`tolerant_front`, one row per point (the first of each tie): what
    the quality measures that count points (spread, gaps) measure."""
    values = np.asarray(values, dtype=float).reshape(-1, len(directions))
    front = values[tolerant_front(values, directions, tolerance)]
    _, first = np.unique(tie_points(front, directions, tolerance), return_index=True)
    return front[np.sort(first)]


def front_candidates(values: np.ndarray) -> np.ndarray:
    """Which rows may be on a front: an infinite value (an expected cost of a policy that
    may never reach its goal, say) keeps a row off unless every row is infinite in that
    objective. NaN never is a candidate."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return np.zeros(len(values), dtype=bool)
    finite = np.isfinite(values)
    allowed = finite | (~finite & ~finite.any(axis=0))
    return allowed.all(axis=1) & ~np.isnan(values).any(axis=1)


def reference_point(objectives: Sequence[Objective], *sets: np.ndarray) -> np.ndarray:
    """The hypervolume reference: each objective's ``reference`` if set, else its worst
    finite value in ``sets`` moved away by a tenth of the range (so extreme points still
    count); an objective without any finite value gets 1."""
    directions = [o.direction for o in objectives]
    stacked = np.vstack([np.asarray(s, dtype=float).reshape(-1, len(objectives)) for s in sets])
    as_min = _as_min(stacked, directions)
    finite = np.isfinite(as_min)
    worst = np.where(finite.any(axis=0), np.where(finite, as_min, -np.inf).max(axis=0), 1.0)
    best = np.where(finite.any(axis=0), np.where(finite, as_min, np.inf).min(axis=0), 1.0)
    span = worst - best
    offset = np.where(span > 0, 0.1 * span, np.maximum(0.1 * np.abs(worst), 1.0))
    ref_min = worst + offset
    result = ref_min * np.array([d.sign for d in directions])
    for i, objective in enumerate(objectives):
        if objective.reference is not None:
            result[i] = objective.reference
    return result


def hypervolume(values: np.ndarray, directions: Sequence[Direction], reference: Sequence[float]) -> float:
    """Volume dominated by the points and bounded by ``reference``; points not strictly better
    than the reference in every objective contribute nothing, and neither do points with an
    infinite value."""
    as_min = _as_min(values, directions)
    ref_min = _as_min(np.asarray(reference, dtype=float), directions)[0]
    inside = as_min[(as_min < ref_min).all(axis=1) & np.isfinite(as_min).all(axis=1)]
    if len(inside) == 0:
        return 0.0
    return float(moocore.hypervolume(inside, ref=ref_min))


def spread(
    values: np.ndarray,
    directions: Sequence[Direction],
    *,
    bounds: tuple[np.ndarray, np.ndarray] | None = None,
    extremes: np.ndarray | None = None,
) -> float:
    """Deb et al.'s spread (Delta, NSGA-II paper, 2002) of a two-objective front; lower is better.

    Delta = (d_f + d_l + sum |d_i - mean d|) / (d_f + d_l + (N - 1) mean d), with d_i the
    distances between neighboring points and d_f, d_l the distances from the front's end
    points to ``extremes`` (two points, e.g. the ends of a reference front; without them
    d_f = d_l = 0 and only the uniformity of the spacing counts). Objectives are normalized
    to [0, 1] by ``bounds`` (ideal, nadir) or by the front's own range. Fewer than two
    points give 1.0.
    """
    if len(directions) != 2:
        raise ValueError("spread is defined for two objectives")
    points = _as_min(values, directions)
    if len(points) < 2:
        return 1.0
    low, high = (
        (points.min(axis=0), points.max(axis=0))
        if bounds is None
        else (_as_min(bounds[0], directions)[0], _as_min(bounds[1], directions)[0])
    )
    low, high = np.minimum(low, high), np.maximum(low, high)
    scale = np.where(high - low > 0, high - low, 1.0)
    norm = (points - low) / scale
    norm = norm[np.lexsort((norm[:, 1], norm[:, 0]))]
    gaps = np.linalg.norm(np.diff(norm, axis=0), axis=1)
    mean = gaps.mean()
    d_f = d_l = 0.0
    if extremes is not None:
        ends = (_as_min(extremes, directions) - low) / scale
        ends = ends[np.argsort(ends[:, 0])]
        d_f = float(np.linalg.norm(norm[0] - ends[0]))
        d_l = float(np.linalg.norm(norm[-1] - ends[-1]))
    denominator = d_f + d_l + (len(norm) - 1) * mean
    if denominator == 0:
        return 1.0
    return float((d_f + d_l + np.abs(gaps - mean).sum()) / denominator)


def igd_plus(
    values: np.ndarray, reference: np.ndarray, directions: Sequence[Direction], *, bounds: tuple[np.ndarray, np.ndarray]
) -> float:
    """IGD+ (Ishibuchi et al., EMO 2015; moocore's ``igd_plus``) of a front against a
    reference front, both normalized to [0, 1] by ``bounds`` (ideal, nadir); lower is
    better, 0 when the front covers the reference. An empty front gives infinity."""
    points, ref = _as_min(values, directions), _as_min(reference, directions)
    if len(points) == 0:
        return float("inf")
    low, high = _as_min(bounds[0], directions)[0], _as_min(bounds[1], directions)[0]
    low, high = np.minimum(low, high), np.maximum(low, high)
    scale = np.where(high - low > 0, high - low, 1.0)
    return float(moocore.igd_plus((points - low) / scale, ref=(ref - low) / scale))


def mean_gap(values: np.ndarray, directions: Sequence[Direction]) -> float:
    """The paper's "spread" (evaluation.py): mean distance between neighboring points after
    normalizing each objective by the front's own range; 1.5 when undefined, as there."""
    points = _as_min(values, directions)
    span = points.max(axis=0) - points.min(axis=0) if len(points) else np.zeros(len(directions))
    if len(points) < 2 or (span == 0).any():
        return 1.5
    norm = (points - points.min(axis=0)) / span
    norm = norm[np.argsort(norm[:, 0], kind="stable")]
    return float(np.linalg.norm(np.diff(norm, axis=0), axis=1).mean())


def knee(values: np.ndarray, directions: Sequence[Direction]) -> int:
    """Index of the point closest to the ideal point after normalizing each objective to [0, 1]."""
    points = _as_min(values, directions)
    if len(points) == 0:
        raise ValueError("no points")
    span = points.max(axis=0) - points.min(axis=0)
    norm = (points - points.min(axis=0)) / np.where(span > 0, span, 1.0)
    return int(np.argmin(np.linalg.norm(norm, axis=1)))


def front_disagreements(
    found: np.ndarray, values: np.ndarray, directions: Sequence[Direction], tolerance: float = 1e-9
) -> tuple[np.ndarray, np.ndarray]:
    """How ``found`` fails to be the Pareto front of ``values`` up to ties within
    ``tolerance`` (:func:`tie_scale` of both sets): the values no found value weakly
    dominates once given the tolerance, and the found values that are not (to the tolerance)
    one of the float-exact front's. Both empty: the same front, as branch and bound promises
    it. Counting the points of two fronts instead counts ties at the level of float noise (a
    probability of 1.0000000000000036 beside 1.0), which one side may keep and the other drop.
    NaN rows of ``values`` are left out."""
    values = np.asarray(values, dtype=float)
    found = np.asarray(found, dtype=float).reshape(-1, values.shape[1])
    values = values[~np.isnan(values).any(axis=1)]
    exact = values[nondominated(values, directions)]
    mine, theirs, best = (_maximised(v, directions) for v in (found, values, exact))

    scale = tie_scale(np.vstack([values, found]), tolerance)

    covered = np.zeros(len(theirs), dtype=bool)
    member = np.zeros(len(mine), dtype=bool)
    for lo in range(0, len(theirs), 1024):  # in slices: values x found can be large
        part = theirs[lo : lo + 1024]
        covered[lo : lo + 1024] = (mine[None, :, :] >= (part - scale)[:, None, :]).all(axis=2).any(axis=1)
    with np.errstate(invalid="ignore"):  # inf - inf: equal infinities are caught by ==
        for lo in range(0, len(mine), 1024):
            part = mine[lo : lo + 1024]
            near = (best[None, :, :] == part[:, None, :]) | (np.abs(best[None, :, :] - part[:, None, :]) <= scale)
            member[lo : lo + 1024] = near.all(axis=2).any(axis=1)
    return values[~covered], found[~member]  # a NaN found value is never near one
