"""What a plugin tells an adaptive URC about a drifting parameter: which transitions of its
model are *events* (trials with an outcome and a context) and how likely an outcome is under
each value of the parameter. The plugin contract (``CaseStudy.events``) holds these; the
adaptive controller that weighs them is :mod:`parley_core.urc.adaptive`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
from attrs import field, frozen

from parley_core.docstrings import fields_in_help

Events = Callable[[Mapping[str, np.ndarray], Mapping[str, np.ndarray]], tuple[np.ndarray, np.ndarray, np.ndarray]]
"""``events(before, after)``: for transitions from states with variable values ``before`` to
``after`` (arrays, one entry per transition), which are trials, their outcomes (0/1) and
their contexts (integers)."""

Likelihood = Callable[[float, np.ndarray, np.ndarray], np.ndarray]
"""``probability(value, outcomes, contexts)``: each event's probability if the parameter is ``value``."""


def bernoulli(value: float, outcomes: np.ndarray, contexts: np.ndarray) -> np.ndarray:
    """The default likelihood: the parameter is the probability of outcome 1 per trial."""
    return np.where(np.asarray(outcomes, dtype=bool), value, 1.0 - value)


@fields_in_help
@frozen(kw_only=True)
class EventModel:
    """What a plugin tells the estimator about one drifting parameter (the
    :class:`~parley_core.CaseStudy` field ``events``, by option name)."""

    description: str
    variables: tuple[str, ...] = field(converter=tuple)
    """The state variables ``events`` reads."""
    events: Events
    probability: Likelihood = bernoulli
