"""A plugin's closed-loop simulator and what its episodes give (value objects), and the
99 % intervals that ``parley validate`` and ``parley simulate`` set next to Storm's values.

:class:`Simulator` is a :class:`~parley_core.CaseStudy` field; :mod:`parley_core.simulation.validate`
runs it (this module imports nothing of the pipeline, so the case study contract does not).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from attrs import field, frozen

from parley_core.docstrings import fields_in_help
from parley_core.model import SystemModel
from parley_core.progress import Progress
from parley_core.urc.controller import URC

Z99 = 2.5758293035489004
"""The standard normal quantile of 0.995."""


@fields_in_help
@frozen(kw_only=True)
class Episodes:
    """What a simulator's episodes of one policy gave: per objective, one value per episode
    (1.0 or 0.0 for a probability objective), notes for the user, and whatever the
    simulator's ``draw`` needs (trajectories)."""

    values: Mapping[str, np.ndarray] = field(converter=dict)
    notes: tuple[str, ...] = ()
    trace: Any = field(default=None, eq=False, repr=False)


@fields_in_help
@frozen(kw_only=True)
class Simulator:
    """A plugin's closed-loop simulator (the :class:`~parley_core.CaseStudy` field ``simulator``).

    ``run(system, options, urc, episodes, seed, progress)`` runs the URC in closed loop on
    the system that ``system`` (built from the run's ``options``) models, ``episodes``
    times, deterministically for a seed, calling ``progress(n)`` as episodes finish; it
    returns an :class:`Episodes` with a value per episode for every objective it can
    estimate (probability objectives as 1.0/0.0). ``draw(system, episodes, axes)``
    optionally draws the episodes (from above, for a robot) on a matplotlib axes."""

    description: str
    run: Callable[[SystemModel, Any, URC, int, int, Progress | None], Episodes]
    draw: Callable[[SystemModel, Episodes, Any], None] | None = None


def wilson(successes: int, n: int) -> tuple[float, float]:
    """Wilson's 99 % interval of a proportion."""
    p = successes / n
    denominator = 1 + Z99**2 / n
    center = (p + Z99**2 / (2 * n)) / denominator
    half = Z99 * math.sqrt(p * (1 - p) / n + Z99**2 / (4 * n * n)) / denominator
    return max(0.0, center - half), min(1.0, center + half)


@frozen(kw_only=True)
class Estimate:
    """One objective of one policy: the simulated mean with its 99 % interval, the value
    model checking gives (``checked``), and episodes cut short (``parley simulate``)."""

    objective: str
    kind: str
    """``probability``, ``mean`` or ``mean reward``"""
    mean: float = field(converter=float)
    low: float = field(converter=float)
    high: float = field(converter=float)
    checked: float = field(converter=float)
    episodes: int = field(converter=int)
    cut: int = field(default=0, converter=int)

    @property
    def agrees(self) -> bool:
        """The checked value lies in the interval."""
        return bool(self.low <= self.checked <= self.high)
