"""The archive of evaluated values (sign space: every objective maximised) that branch and
bound prunes against: its *local upper bounds* (Klamroth, Lacour and Vanderpooten, EJOR
2015), the corners whose open orthants make up exactly the region no archived value weakly
dominates; the ties at the level of float noise a front does not keep twice; and the
staircase of points that covers a region of two objectives cut by half-spaces."""

from __future__ import annotations

import numpy as np

from parley_core.boxes import FLOOR

TOLERANCE = 1e-9
"""The front is exact to this: every policy of the family is weakly dominated by a front
value once each objective is given this much (of the value's size, at least 1), and
:data:`NOISE` more for the ties at the level of float noise that :func:`robust_front` drops."""
NOISE = 1e-12
"""Two values closer than this (of their size, at least 1) in an objective are tied there."""


class Archive:
    """Values in sign space (maximised) with their local upper bounds."""

    def __init__(self, n: int) -> None:
        self.points = np.zeros((0, n))
        self.corners = np.full((1, n), -np.inf)

    def add(self, point: np.ndarray) -> bool:
        """Add one value; False if the archive already weakly dominates it (or it is NaN)."""
        if np.isnan(point).any():
            return False
        point = np.maximum(point, FLOOR)  # an infinitely bad value is still a value
        if len(self.points) and (self.points >= point).all(axis=1).any():
            return False
        self.points = np.vstack([self.points[~(self.points <= point).all(axis=1)], point])
        hit = (self.corners < point).all(axis=1)
        born = np.repeat(self.corners[hit], len(point), axis=0)
        columns = np.tile(np.arange(len(point)), hit.sum())
        born[np.arange(len(born)), columns] = point[columns]
        kept = self.corners[~hit]
        everyone = np.vstack([kept, born])
        # a corner whose orthant lies inside another's is redundant
        below = (everyone[None, :, :] <= born[:, None, :]).all(axis=2)
        same = (everyone[None, :, :] == born[:, None, :]).all(axis=2)
        first_same = np.argmax(same, axis=1) == np.arange(len(kept), len(everyone))
        redundant = (below & ~same).any(axis=1) | ~first_same
        self.corners = np.vstack([kept, born[~redundant]])
        return True

    def open_corners(self, ideal: np.ndarray, cuts: list[tuple[np.ndarray, float]]) -> np.ndarray:
        """The corners whose orthant meets the region (ideal box and half-spaces) by more than
        the tolerance: a value better than the archive's by less than TOLERANCE (of its size,
        at least 1) in every objective it improves counts as found."""
        slack = TOLERANCE * np.maximum(1.0, np.abs(np.where(np.isfinite(ideal), ideal, 0.0)))
        inside = (self.corners < ideal - slack).all(axis=1)
        finite = np.maximum(self.corners, FLOOR)
        for weights, level in cuts:
            inside &= finite @ weights < level - weights @ slack
        return self.corners[inside]


def depth(ideal: np.ndarray, corners: np.ndarray, scale: np.ndarray) -> float:
    """How far the ideal point reaches beyond the archive: the largest, over open corners, of
    the smallest scaled distance to the ideal (the node's priority)."""
    if not len(corners):
        return 0.0
    gaps = np.minimum((ideal[None, :] - np.maximum(corners, FLOOR)) / scale, 1e300)
    return float(gaps.min(axis=1).max())


def robust_front(points: np.ndarray) -> np.ndarray:
    """Indices (sorted) of the points (sign space, maximised) that no kept point dominates
    beyond :data:`NOISE`: a point goes when a kept one is no worse than it by more than that
    (of its size, at least 1) in every objective and better by more in one.
    Such ties at the level of float noise (a probability of 0.99999999999999 beside
    0.99999999999998 with a much worse second objective) are not two front values. Every
    point dropped is covered by a kept one to within NOISE; the points are
    taken best first (by their objectives scaled to the points' spread), so that a dominating
    point is kept before what it dominates."""
    points = np.maximum(np.asarray(points, dtype=float), FLOOR)
    if len(points) < 2:
        return np.arange(len(points))
    finite = np.where(np.isfinite(points), points, 0.0)
    slack = NOISE * np.maximum(1.0, np.abs(finite))
    spread = finite.max(axis=0) - finite.min(axis=0)
    key = (finite / np.where(spread > 0, spread, 1.0)).sum(axis=1)
    kept: list[int] = []
    for i in np.argsort(-key, kind="stable"):
        if kept:
            best = points[kept]
            beyond = (best >= points[i] - slack[i]).all(axis=1) & (best > points[i] + slack[i]).any(axis=1)
            if beyond.any():
                continue
        kept.append(int(i))
    return np.sort(np.array(kept, dtype=np.int64))


def staircase(top: np.ndarray, weights: np.ndarray, levels: np.ndarray, steps: int) -> np.ndarray:
    """Points (sign space, two objectives, maximised) whose orthants cover the region below
    ``top`` and every half-space ``weights @ v <= levels`` (weights > 0, finite): the region's
    boundary sampled at ``steps`` + 1 values of the first objective, each point taking the
    highest second objective of its interval (the boundary does not rise)."""

    def height(x: np.ndarray) -> np.ndarray:
        """The largest second objective the region allows at first objective x."""
        cuts = (levels[None, :] - weights[None, :, 0] * x[:, None]) / weights[None, :, 1]
        return np.minimum(top[1], cuts.min(axis=1))

    # the region's top-left corner: where the cuts first go below the box
    left = float(np.min((levels - weights[:, 1] * top[1]) / weights[:, 0]))
    left = min(left, float(top[0]))
    grid = np.linspace(left, float(top[0]), steps + 1)
    heights = height(grid)
    # point i covers x in [grid[i-1], grid[i]] (the height does not increase); the first covers x <= left
    return np.vstack([[grid[0], top[1]], np.column_stack([grid[1:], heights[:-1]])])


OPEN_STEPS = 16
"""Points of the staircase that covers a sub-family left open (two objectives) in a bound."""


def region_points(ideal: np.ndarray, cuts: tuple[tuple[np.ndarray, float], ...]) -> np.ndarray:
    """Points (sign space) whose orthants cover a bounded sub-family's region (its ideal box
    and the half-spaces ``cuts``, each weights and level): for two objectives the staircase
    over both, else the ideal point."""
    usable = [(w, c) for w, c in cuts if np.isfinite(c) and (np.asarray(w) > 0).all()]
    if len(ideal) == 2 and usable and (ideal > FLOOR).all() and np.isfinite(ideal).all():
        weights = np.array([w for w, _ in usable], dtype=float)
        levels = np.array([c for _, c in usable], dtype=float)
        return staircase(ideal, weights, levels, OPEN_STEPS)
    return np.where(ideal <= FLOOR, -np.inf, ideal)[None, :]
