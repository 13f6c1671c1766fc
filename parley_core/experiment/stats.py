"""Statistics for comparing repetitions: Mann-Whitney U (scipy) and Vargha-Delaney A12."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from attrs import frozen
from scipy.stats import mannwhitneyu

ALPHA = 0.05


def a12(first: Sequence[float] | np.ndarray, second: Sequence[float] | np.ndarray) -> float:
    """Vargha and Delaney's A12: the probability that a value from ``first`` exceeds one from
    ``second`` (ties count half). 0.5 means no difference."""
    a = np.asarray(first, dtype=float)[:, None]
    b = np.asarray(second, dtype=float)[None, :]
    if a.size == 0 or b.size == 0:
        return 0.5
    return float(((a > b).sum() + 0.5 * (a == b).sum()) / (a.size * b.size))


@frozen(kw_only=True)
class Comparison:
    verdict: str  # "better", "worse" or "same" (for ``first`` against ``second``)
    p_value: float
    a12: float


def compare(
    first: Sequence[float] | np.ndarray, second: Sequence[float] | np.ndarray, alpha: float = ALPHA
) -> Comparison:
    """Two-sided Mann-Whitney U of two samples; the verdict follows A12 when p < alpha."""
    first, second = np.asarray(first, dtype=float), np.asarray(second, dtype=float)
    effect = a12(first, second)
    if np.array_equal(np.unique(first), np.unique(second)) and len(np.unique(first)) == 1:
        return Comparison(verdict="same", p_value=1.0, a12=effect)
    p = float(mannwhitneyu(first, second, alternative="two-sided").pvalue)
    if p < alpha and effect != 0.5:
        return Comparison(verdict="better" if effect > 0.5 else "worse", p_value=p, a12=effect)
    return Comparison(verdict="same", p_value=p, a12=effect)
