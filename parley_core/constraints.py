"""Requirements on objectives (``success>=0.8``, ``cost<=60``): parsed from the command line,
given to pymoo as constraints, and used to filter fronts."""

from __future__ import annotations

import enum
from collections.abc import Sequence

import numpy as np
from attrs import field, frozen, validators

from parley_core.errors import OptionError


class Operator(enum.Enum):
    """How a constraint compares an objective's value with its bound."""

    AT_LEAST = ">="
    AT_MOST = "<="


@frozen(kw_only=True)
class Constraint:
    """A requirement on one objective: ``success>=0.8``, ``cost<=60``."""

    objective: str
    operator: Operator = field(converter=Operator, validator=validators.instance_of(Operator))
    """``>=`` or ``<=`` (an :class:`Operator`; its text is accepted too)."""
    bound: float

    @classmethod
    def parse(cls, text: str) -> Constraint:
        for operator in Operator:
            name, sep, bound = text.partition(operator.value)
            if sep:
                try:
                    return cls(objective=name.strip(), operator=operator, bound=float(bound))
                except ValueError:
                    break
        raise OptionError(
            f"malformed constraint {text!r}; write OBJECTIVE>=BOUND or OBJECTIVE<=BOUND, e.g. success>=0.8"
        )

    def column(self, names: Sequence[str]) -> int:
        """The position of the constrained objective among ``names``; an unknown one is an error."""
        if self.objective not in names:
            raise OptionError(f"constraint {self}: no objective {self.objective!r}; objectives: {', '.join(names)}")
        return list(names).index(self.objective)

    def violation(self, values: np.ndarray) -> np.ndarray:
        """How far values are from meeting the constraint (<= 0: met), as pymoo wants it."""
        return self.bound - values if self.operator is Operator.AT_LEAST else values - self.bound

    def __str__(self) -> str:
        return f"{self.objective}{self.operator.value}{self.bound:g}"


def meets(values: np.ndarray, names: Sequence[str], constraints: Sequence[Constraint]) -> np.ndarray:
    """Which rows of ``values`` (one column per objective in ``names``) meet every constraint."""
    ok = np.ones(len(values), dtype=bool)
    for constraint in constraints:
        ok &= constraint.violation(values[:, constraint.column(names)]) <= 0
    return ok
