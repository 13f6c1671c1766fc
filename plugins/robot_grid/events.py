"""What the robot's localisations tell about its slip probability ``p`` (for the adaptive URC).

A localisation (``localise``: the Turn module at ``t=2`` sets the move counter ``step`` to 1)
is a trial: its outcome is 1 when the estimate (xhat, yhat) it corrects was wrong, its
context the moves since the last localisation (``step`` before it). A move goes astray with
probability 3p, so after k moves the estimate is right with probability about (1-3p)^k:
:func:`wrong_probability`. "About": a move into the border leaves the robot where the
estimate expects it, two deviations may cancel, and a crashed robot stops; the likelihood
only ranks the scenarios for the adaptive URC, whose policies' values are Storm's.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from parley_core import EventModel


def localisations(before: Mapping[str, np.ndarray], after: Mapping[str, np.ndarray]):
    """Trials, outcomes and contexts of transitions (module docstring)."""
    trial = (before["t"] == 2) & (after["t"] == 0) & (after["step"] == 1)
    wrong = (before["xhat"] != before["x"]) | (before["yhat"] != before["y"])
    return trial, wrong.astype(np.int64), before["step"]


def wrong_probability(p: float, outcomes: np.ndarray, contexts: np.ndarray) -> np.ndarray:
    """The probability of each localisation's outcome after ``contexts`` moves if the slip
    probability is ``p``: wrong with 1 - (1-3p)^k."""
    wrong = 1.0 - (1.0 - 3.0 * p) ** np.asarray(contexts, dtype=float)
    return np.where(np.asarray(outcomes, dtype=bool), wrong, 1.0 - wrong)


SLIP = EventModel(
    description="a localisation finds the estimate wrong after k moves with probability about 1-(1-3p)^k",
    variables=("t", "step", "x", "y", "xhat", "yhat"),
    events=localisations,
    probability=wrong_probability,
)
