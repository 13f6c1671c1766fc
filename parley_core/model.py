"""Value objects shared by every stage: what a case study describes, and what a run produces.

All are frozen, keyword-only attrs classes with validators; none of them touches stormpy.
"""

from __future__ import annotations

import enum
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, TypeVar

import attrs
import numpy as np
from attrs import field, frozen, validators

from parley_core.docstrings import fields_in_help
from parley_core.errors import ModelError, PolicyError
from parley_core.tables import Tabular


def _suggest(name: str) -> str:
    fixed = re.sub(r"\W+", "_", str(name)).strip("_") or "name"
    return f"_{fixed}" if fixed[0].isdigit() else fixed


IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
"""A name PRISM and the run files can carry; the model's words, for an error's hint."""


def _identifier(instance: Any, attribute: attrs.Attribute, value: Any) -> None:
    """A name PRISM and the run files can carry: letters, digits and underscores, not starting
    with a digit (a :class:`ModelError` naming the field and a name that would do)."""
    if not isinstance(value, str) or not IDENTIFIER.fullmatch(value):
        kind = type(instance).__name__.lower()
        raise ModelError(
            f"{kind} {attribute.name} {value!r} is not an identifier: use letters, digits and underscores, "
            f"not starting with a digit (say {_suggest(value)!r})"
        )


_T = TypeVar("_T")


class Direction(enum.Enum):
    """Whether an objective is to be minimized or maximized."""

    MIN = "min"
    MAX = "max"

    @property
    def sign(self) -> float:
        """+1 for MIN, -1 for MAX: multiply a value by it to get a value to minimize."""
        return 1.0 if self is Direction.MIN else -1.0


class DecisionKind(enum.Enum):
    """How a service's constant is consulted by the model.

    FREQUENCY: the service runs once a counter reaches the constant (every k-th step).
    THRESHOLD: the service runs when a monitored value crosses the constant.
    The kind documents the meaning; augmentation treats both alike.
    """

    FREQUENCY = "frequency"
    THRESHOLD = "threshold"


def _tuple_of(value: Iterable[Any], item_type: type[_T]) -> tuple[_T, ...]:
    result = tuple(value)
    for item in result:
        if not isinstance(item, item_type):
            raise TypeError(f"expected {item_type.__name__}, got {type(item).__name__}: {item!r}")
    return result


@fields_in_help
@frozen(kw_only=True)
class Objective:
    """A quantity to optimize, given as a PCTL property over the system model.

    ``formula`` is a property of the form ``P=? [...]`` or ``R{"r"}=? [...]``; ``reference`` is
    the worst value still of interest (the hypervolume reference), or None to derive one from
    the data.
    """

    name: str = field(validator=_identifier)
    """An identifier: the CSV column, ``--constraint NAME<=V``'s name."""
    formula: str = field(validator=validators.min_len(1))
    """``P=? [...]`` or ``R{"r"}=? [...]`` over the system model's labels and variables."""
    direction: Direction = field(converter=Direction)
    """``Direction.MIN`` or ``Direction.MAX`` (or ``"min"``, ``"max"``)."""
    description: str = ""
    """One line for people, shown nowhere the formula is enough."""
    reference: float | None = None
    """The worst value still of interest (the hypervolume's reference), or None to derive one."""

    def to_minimize(self, value: float) -> float:
        return self.direction.sign * value

    def to_json(self) -> dict[str, Any]:
        """The objective as run files and stores record it."""
        return {"name": self.name, "direction": self.direction.value, "formula": self.formula}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Objective:
        return cls(name=data["name"], formula=data["formula"], direction=Direction(data["direction"]))


@fields_in_help
@frozen(kw_only=True)
class Service:
    """An uncertainty-reduction service, and the model constant that decides when it runs.

    In the input DTMC the constant (``constant``) is consulted by the commands that invoke
    or skip the service; the URC chooses its value, per observation valuation, in
    ``low..high``, or in ``choices`` when they are given (a set such as ``{2, 4}``, as
    PAYNT's holes have; ``low`` and ``high`` are then its smallest and largest value).
    """

    name: str = field(validator=_identifier)
    """An identifier naming the service (``localisation``)."""
    constant: str = field(validator=_identifier)
    """The model's ``const int`` that decides when the service runs (``c``)."""
    kind: DecisionKind = field(converter=DecisionKind)
    """``DecisionKind.FREQUENCY`` (every k-th step) or ``DecisionKind.THRESHOLD``."""
    low: int = field(validator=validators.instance_of(int))
    """The constant's smallest value."""
    high: int = field(validator=validators.instance_of(int))
    """The constant's largest value (at least ``low``)."""
    description: str = ""
    """One line for people."""
    choices: tuple[int, ...] = field(default=(), converter=lambda values: tuple(sorted({int(v) for v in values})))
    """The values allowed, when not every one of ``low..high`` is (empty: all of them)."""

    @high.validator
    def _check_range(self, _attribute: attrs.Attribute, high: int) -> None:
        if high < self.low:
            raise ModelError(
                f"service {self.name!r}: empty range {self.low}..{high} for {self.constant}; "
                "give LOW..HIGH with LOW <= HIGH"
            )

    @choices.validator
    def _check_choices(self, _attribute: attrs.Attribute, choices: tuple[int, ...]) -> None:
        if choices and (choices[0] != self.low or choices[-1] != self.high):
            raise ModelError(
                f"service {self.name!r}: the values {choices} of {self.constant} do not run from low {self.low} "
                f"to high {self.high}; give low and high as the smallest and largest value"
            )

    @classmethod
    def of_values(cls, *, name: str, constant: str, kind: DecisionKind, values, description: str = "") -> Service:
        """A service whose constant takes the given values (a range if they are contiguous)."""
        chosen = sorted({int(v) for v in values})
        if not chosen:
            raise ModelError(f"service {name!r}: no values for {constant}; give at least one")
        contiguous = chosen == list(range(chosen[0], chosen[-1] + 1))
        return cls(
            name=name,
            constant=constant,
            kind=kind,
            low=chosen[0],
            high=chosen[-1],
            choices=() if contiguous else chosen,
            description=description,
        )

    @property
    def values(self) -> Sequence[int]:
        """Every value the constant may take, in increasing order."""
        return self.choices if self.choices else range(self.low, self.high + 1)

    def domain_text(self) -> str:
        """``1..10`` or ``{2,4}``."""
        return "{" + ",".join(map(str, self.choices)) + "}" if self.choices else f"{self.low}..{self.high}"

    def to_json(self) -> dict[str, Any]:
        """The service as run files and controller files record it."""
        data: dict[str, Any] = {
            "name": self.name,
            "constant": self.constant,
            "kind": self.kind.value,
            "range": [self.low, self.high],
        }
        if self.choices:
            data["values"] = list(self.choices)
        return data

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Service:
        low, high = data["range"]
        return cls(
            name=data["name"],
            constant=data["constant"],
            kind=DecisionKind(data["kind"]),
            low=int(low),
            high=int(high),
            choices=data.get("values", ()),
        )


@fields_in_help
@frozen(kw_only=True)
class Baseline:
    """A reference policy that uses one value per service everywhere (a fixed frequency or threshold)."""

    name: str = field(validator=validators.min_len(1))
    """Its name in baseline.csv and the reports (``interval-3``)."""
    values: Mapping[str, int] = field(converter=lambda m: dict(m))
    """The value of each service constant, used at every observation valuation."""

    @classmethod
    def sweep(cls, constant: str, values: Iterable[int], name: str = "every-{}") -> tuple[Baseline, ...]:
        """One baseline per value of a service constant, named by ``name.format(value)``
        (``Baseline.sweep("c", range(1, 11), "interval-{}")``)."""
        return tuple(cls(name=name.format(v), values={constant: v}) for v in values)


# the converters of the fields that hold services, objectives and baselines (named
# functions, so that mypy's attrs plugin types the parameters of ``__init__``)
def _services(value: Iterable[Service]) -> tuple[Service, ...]:
    return _tuple_of(value, Service)


def _objectives(value: Iterable[Objective]) -> tuple[Objective, ...]:
    return _tuple_of(value, Objective)


def _baselines(value: Iterable[Baseline]) -> tuple[Baseline, ...]:
    return _tuple_of(value, Baseline)


@fields_in_help
@frozen(kw_only=True)
class SystemModel:
    """What a case study hands to the core: a DTMC with its services, observation and objectives.

    ``prism`` is the DTMC in the PRISM language; it declares each service's constant (undefined,
    or defined with a default). ``observation`` names the variables the URC may read, in the
    order that names its decision constants. ``context`` is the plugin's own data (for its
    plots); the core never looks inside it.
    """

    name: str = field(validator=_identifier)
    prism: str = field(validator=validators.min_len(1))
    services: tuple[Service, ...] = field(converter=_services, validator=validators.min_len(1))
    observation: tuple[str, ...] = field(converter=tuple[str, ...])
    """May be empty: a URC that reads nothing chooses one value per service (a family of
    constants, as PAYNT's holes are)."""
    objectives: tuple[Objective, ...] = field(converter=_objectives)
    """What to optimize; may be empty only for augmentation without a search."""
    baselines: tuple[Baseline, ...] = field(converter=_baselines, factory=tuple)
    description: str = ""
    context: Any = field(default=None, eq=False, repr=False)
    notes: tuple[str, ...] = field(default=(), converter=tuple[str, ...])
    """What the user should know about how parley reads the model (a run reports them)."""

    def __attrs_post_init__(self) -> None:
        for kind, names in (
            ("objective", [o.name for o in self.objectives]),
            ("service constant", [s.constant for s in self.services]),
            ("observation variable", list(self.observation)),
        ):
            duplicates = sorted({n for n in names if names.count(n) > 1})
            if duplicates:
                raise ModelError(f"duplicate {kind} {', '.join(duplicates)}; give each a distinct name")
        constants = {s.constant for s in self.services}
        for baseline in self.baselines:
            if set(baseline.values) != constants:
                raise ModelError(
                    f"baseline {baseline.name!r} sets {sorted(baseline.values)}, expected exactly {sorted(constants)}"
                )

    def objective(self, name: str) -> Objective:
        for objective in self.objectives:
            if objective.name == name:
                return objective
        raise ModelError(f"unknown objective {name!r}; valid: {', '.join(o.name for o in self.objectives)}")


def identifier(stem: str) -> str:
    """A family name made from a file stem or a case study's name: lower case, letters,
    digits and underscores, starting with a letter."""
    name = "".join(ch if ch.isalnum() else "_" for ch in stem.lower()) or "model"
    return name if name[0].isalpha() else f"m_{name}"


def decision_name(constant: str, valuation: tuple[int, ...]) -> str:
    """The decision constant for ``constant`` at an observation valuation: ``c_3_4``, ``c_m2``;
    with no observation variables, the constant itself."""
    parts = [f"m{-v}" if v < 0 else str(v) for v in valuation]
    return "_".join([constant, *parts])


@fields_in_help
@frozen(kw_only=True)
class Decision:
    """One decision constant of the augmented model: a service's value at one observation valuation."""

    name: str
    service: Service
    valuation: tuple[int, ...]


@fields_in_help
@frozen(kw_only=True)
class Family:
    """The augmented, parametric model: every policy is an assignment of its decision constants.

    ``prism`` is plain PRISM with each decision declared as an undefined ``const int``;
    ``decisions`` is their order in every policy vector. ``valuations`` are the observation
    valuations kept (those in the variables' ranges, minus ``left_out``: those at which no
    service is ever consulted, when pruned). ``system`` is the model it was augmented from
    (the quotient is built from it); a family read back from a run directory has none.
    """

    name: str = field(validator=_identifier)
    prism: str
    services: tuple[Service, ...] = field(converter=_services)
    observation: tuple[str, ...] = field(converter=tuple[str, ...])
    objectives: tuple[Objective, ...] = field(converter=_objectives)
    baselines: tuple[Baseline, ...] = field(converter=_baselines, factory=tuple)
    decisions: tuple[Decision, ...] = field(converter=tuple[Decision, ...])
    valuations: tuple[tuple[int, ...], ...] = field(converter=tuple[tuple[int, ...], ...])
    left_out: tuple[tuple[int, ...], ...] = field(converter=tuple[tuple[int, ...], ...], factory=tuple)
    system: SystemModel | None = field(default=None, eq=False, repr=False)

    @classmethod
    def of(cls, system: SystemModel, **fields: Any) -> Family:
        """A family augmented from ``system`` (its services, observation, objectives and baselines)."""
        return cls(
            name=system.name,
            services=system.services,
            observation=system.observation,
            objectives=system.objectives,
            baselines=system.baselines,
            system=system,
            **fields,
        )

    def origin(self) -> SystemModel:
        """The system model the family was augmented from; an error for a family read back from files."""
        if self.system is None:
            raise ModelError(
                f"the {self.name} family was read back from files and has no original model; "
                "rebuild it from the case study or the model file"
            )
        return self.system

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(d.name for d in self.decisions)

    def random(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """``count`` policies [count, decisions] drawn uniformly from each decision's values."""
        if not any(d.service.choices for d in self.decisions):
            return rng.integers(np.array(self.lows), np.array(self.highs) + 1, size=(count, len(self.decisions)))
        columns = [rng.choice(np.array(d.service.values), size=count) for d in self.decisions]
        return np.column_stack(columns).astype(np.int64) if columns else np.zeros((count, 0), dtype=np.int64)

    @property
    def lows(self) -> tuple[int, ...]:
        return tuple(d.service.low for d in self.decisions)

    @property
    def highs(self) -> tuple[int, ...]:
        return tuple(d.service.high for d in self.decisions)

    def properties_text(self) -> str:
        """The objectives as a properties file, with a ``// name: NAME, DIRECTION`` line each."""
        lines = []
        for objective in self.objectives:
            lines.append(f"// name: {objective.name}, {objective.direction.value}")
            lines.append(objective.formula)
        return "\n".join(lines) + "\n"

    def uniform(self, name: str, values: Mapping[str, int]) -> Policy:
        """The policy that uses ``values[constant]`` for every decision of that service."""
        return Policy(name=name, values=tuple(values[d.service.constant] for d in self.decisions))

    def baseline_policies(self) -> tuple[Policy, ...]:
        return tuple(self.uniform(b.name, b.values) for b in self.baselines)

    def check(self, policy: Policy) -> None:
        """Raise PolicyError unless the policy assigns every decision a value in its range."""
        if len(policy.values) != len(self.decisions):
            raise PolicyError(
                f"policy {policy.name!r} has {len(policy.values)} values, the model has {len(self.decisions)} decisions"
            )
        for decision, value in zip(self.decisions, policy.values):
            service = decision.service
            if not (value in service.choices if service.choices else service.low <= value <= service.high):
                raise PolicyError(
                    f"policy {policy.name!r}: {decision.name}={value} is outside "
                    f"{service.domain_text()}; use a value in {'that set' if service.choices else 'that range'}"
                )


@fields_in_help
@frozen(kw_only=True)
class Policy:
    """A URC policy: one value per decision constant of a family, in the family's order."""

    name: str
    values: tuple[int, ...] = field(converter=lambda v: tuple(int(x) for x in v))


@fields_in_help
@frozen(kw_only=True)
class Valued(Tabular):
    """Policies with their objective values (in the objectives' own units and directions):
    any evaluated set, such as the baselines or the policies of a file. A value may be
    infinite (the expected cost of a policy that may never reach its goal), never NaN."""

    objectives: tuple[Objective, ...] = field(converter=tuple[Objective, ...])
    policies: tuple[Policy, ...] = field(converter=tuple[Policy, ...])
    values: tuple[tuple[float, ...], ...] = field(
        converter=lambda rows: tuple(tuple(float(v) for v in r) for r in rows)
    )

    def __attrs_post_init__(self) -> None:
        if len(self.policies) != len(self.values):
            raise ValueError("a front needs one row of values per policy")
        for row in self.values:
            if len(row) != len(self.objectives) or any(math.isnan(v) for v in row):
                raise ValueError(f"bad objective values {row}")

    def __len__(self) -> int:
        return len(self.policies)

    def rows(self) -> list[dict[str, Any]]:
        return [
            {"policy": p.name, **{o.name: v for o, v in zip(self.objectives, row)}}
            for p, row in zip(self.policies, self.values)
        ]


@fields_in_help
@frozen(kw_only=True)
class Front(Valued):
    """A Pareto front: policies whose values no other policy of the front dominates (the
    pipeline builds it from the non-dominated Storm-checked policies, in lexicographic
    order of their values)."""
