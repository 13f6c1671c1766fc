"""What a search is asked to do (:class:`SearchSettings`) and what it did (:class:`SearchResult`)."""

from __future__ import annotations

import enum
from typing import TYPE_CHECKING

import attrs
import numpy as np
from attrs import field, frozen, validators

from parley_core.constraints import Constraint

if TYPE_CHECKING:
    from parley_core.search.guide import Walked
    from parley_core.search.polish import Polished


def _positive_or_none(_instance, attribute: attrs.Attribute, value) -> None:
    if value is not None and value <= 0:
        raise ValueError(f"{attribute.name} must be positive or None, got {value}")


@frozen(kw_only=True)
class SearchSettings:
    """Algorithm, budget and seed of a search.

    ``algorithm`` names a configuration of :data:`~parley_core.search.algorithms.ALGORITHMS`
    (:func:`~parley_core.search.algorithms.configuration` checks the name)
    (``paper`` is the paper's NSGA-II: SBX and polynomial mutation on rounded integers,
    population 100, 40 generations). The search stops at whichever limit comes first:
    ``generations`` (None: no limit), ``max_evaluations`` (new policies, the baselines
    included) or ``time_limit`` (seconds of search). ``constraints`` make the search prefer
    policies that meet them (pymoo's constraint handling).
    """

    algorithm: str = "paper"
    population: int = field(default=100, validator=validators.ge(2))
    generations: int | None = field(default=40, validator=_positive_or_none)
    max_evaluations: int | None = field(default=None, validator=_positive_or_none)
    time_limit: float | None = field(default=None, validator=_positive_or_none)
    seed: int = 1
    constraints: tuple[Constraint, ...] = field(default=(), converter=tuple[Constraint, ...])

    def __attrs_post_init__(self) -> None:
        if self.generations is None and self.max_evaluations is None and self.time_limit is None:
            raise ValueError("a search needs a limit: generations, max_evaluations or time_limit")


def default(name: str):
    """The default of a :class:`SearchSettings` field (the CLI's defaults come from here)."""
    return attrs.fields_dict(SearchSettings)[name].default


class Stop(enum.Enum):
    """Why a search ended."""

    GENERATIONS = "generations"
    EVALUATIONS = "evaluations"
    TIME = "time"
    INTERRUPTED = "interrupted"
    STALLED = "stalled"
    """No new policy in 25 generations in a row (:class:`~parley_core.search.problem.Stalled`)."""
    EXHAUSTED = "exhausted"
    """Polishing found no neighbour of the front left to try (:mod:`parley_core.search.polish`)."""


@frozen(kw_only=True)
class SearchResult:
    """Everything the search evaluated (the archive, in the order first evaluated)."""

    policies: np.ndarray = field(eq=False)
    values: np.ndarray = field(eq=False)
    evaluations: int
    generations: int
    seconds: float
    stopped_by: Stop
    walked: Walked | None = None
    """The walks of policy improvement a ``guided`` search started from (None: not guided)."""
    polished: Polished | None = None
    """What polishing the front did in a ``polished`` search (None: not polished)."""

    @property
    def interrupted(self) -> bool:
        return self.stopped_by is Stop.INTERRUPTED
