"""An adaptive URC: one Storm-checked policy per scenario, switched by what the system observes.

A model's numbers drift (a robot's wheels wear, attacks come in waves). An
:class:`AdaptiveController` holds one policy per value of a drifting parameter, each
synthesized and checked for its own model (``parley adapt`` reads them from run
directories), and an :class:`Estimator` that weighs the observed events under each value:

- an *event* is a trial with an outcome and a context: a localisation that finds the
  estimate wrong (outcome 1) or right (0) after ``context`` moves. A plugin's
  :class:`EventModel` says which transitions of its model are trials and how likely an
  outcome is under each parameter value; the default, :func:`bernoulli`, is for a parameter
  that *is* the probability of the observed event per trial;
- how likely an outcome is comes from the model itself where it can: ``parley adapt``
  *calibrates* the controller (:class:`Calibration`), running each policy's DTMC at each
  value (Storm builds it) for many missions and counting the outcomes per context, so the
  estimator weighs the events as the model predicts them under the policy in force; a
  controller without a calibration uses the event model's ``probability``;
- the estimator keeps each value's log-likelihood of the events seen, discounted by
  ``forgetting`` at every mission's end (so that it follows a drift), and
- :meth:`AdaptiveURC.adapt`, called between missions, switches to the most likely value's
  policy when it beats the current one's by ``hysteresis`` (a log-likelihood margin: 2.0
  means e^2, about 7 times more likely), so that noise does not flip the policy back and forth.

Switching happens between missions only: each policy's Storm-checked values are those of a
mission run by that policy from the model's initial state; a switch inside a mission would
leave neither policy's values standing.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from attrs import field, frozen, validators

from parley_core.errors import ObservationError, ParleyError, PolicyError
from parley_core.urc.controller import URC, read_document
from parley_core.urc.events import Likelihood, bernoulli

FORMAT = "parley-adaptive-urc/1"

PolicyLikelihood = Callable[[int, np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""``likelihood(value_index, policies, outcomes, contexts)``: each event's probability under
the controller's ``value_index``-th value, given the index of the policy in force when it
happened."""


def _rates(value) -> np.ndarray:
    return np.asarray(value, dtype=float)


@frozen(kw_only=True)
class Calibration:
    """Per parameter value, policy and context, the probability of outcome 1 as the model
    predicts it: ``(ones + 1) / (trials + 2)`` over ``missions`` simulated missions of the
    policy's DTMC at the value (a context never seen there gets the policy's rate over all
    contexts; an event whose context is not in the table takes the next larger one's, or
    the largest's)."""

    contexts: tuple[int, ...] = field(converter=lambda v: tuple(int(x) for x in v))
    rates: np.ndarray = field(converter=_rates, eq=False)
    """[values, policies, contexts]"""
    missions: int

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, Calibration)
            and (self.contexts, self.missions) == (other.contexts, other.missions)
            and np.array_equal(self.rates, other.rates)
        )

    def likelihood(self, value: int, policies: np.ndarray, outcomes: np.ndarray, contexts: np.ndarray) -> np.ndarray:
        known = np.array(self.contexts)
        index = np.clip(np.searchsorted(known, contexts), 0, len(known) - 1)
        rate = self.rates[value, np.asarray(policies, dtype=np.int64), index]
        return np.where(np.asarray(outcomes, dtype=bool), rate, 1.0 - rate)

    def to_json(self) -> dict[str, Any]:
        return {"missions": self.missions, "contexts": list(self.contexts), "rates": self.rates.tolist()}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Calibration:
        return cls(contexts=data["contexts"], rates=data["rates"], missions=int(data["missions"]))


@frozen(kw_only=True)
class Estimator:
    """Settings of the estimator (module docstring)."""

    forgetting: float = field(default=0.9, validator=[validators.gt(0.0), validators.le(1.0)])
    """Each mission's end multiplies every log-likelihood by this (1: never forget)."""
    hysteresis: float = field(default=2.0, validator=validators.ge(0.0))
    """Switch when another value's log-likelihood exceeds the current one's by this much."""


class Beliefs:
    """The estimator's state for ``n`` independent systems at once (the drift simulation runs
    many; the runtime URC one): per system, each value's discounted log-likelihood and the
    index of the value whose policy is in force."""

    def __init__(self, values: Sequence[float], estimator: Estimator, likelihood: PolicyLikelihood, n: int, start: int):
        self.values = tuple(float(v) for v in values)
        self.estimator = estimator
        self.likelihood = likelihood
        self.scores = np.zeros((n, len(self.values)))
        self.current = np.full(n, start, dtype=np.int64)

    def observe(self, systems: np.ndarray, outcomes: np.ndarray, contexts: np.ndarray) -> None:
        """Events of ``systems`` (indices, one per event; a system may appear several times),
        under the policy each system has in force."""
        policies = self.current[systems]
        for j in range(len(self.values)):
            with np.errstate(divide="ignore"):
                logs = np.log(np.clip(self.likelihood(j, policies, outcomes, contexts), 0.0, 1.0))
            np.add.at(self.scores[:, j], systems, logs)

    def adapt(self) -> np.ndarray:
        """A mission ended: switch where another value is ``hysteresis`` more likely, then
        forget; returns which systems switched."""
        best = np.argmax(self.scores, axis=1)
        rows = np.arange(len(self.current))
        margin = self.scores[rows, best] - self.scores[rows, self.current]
        switch = (best != self.current) & (margin > self.estimator.hysteresis)
        self.current = np.where(switch, best, self.current)
        finite = np.isfinite(self.scores)
        self.scores = np.where(finite, self.scores * self.estimator.forgetting, -1e300)
        return switch


def _urcs(items: Sequence[URC]) -> tuple[URC, ...]:
    return tuple(items)


def _floats(items: Sequence[float]) -> tuple[float, ...]:
    return tuple(float(v) for v in items)


@frozen(kw_only=True)
class AdaptiveController:
    """One policy per value of a drifting parameter, and the estimator's settings."""

    parameter: str
    values: tuple[float, ...] = field(converter=_floats)
    controllers: tuple[URC, ...] = field(converter=_urcs)
    estimator: Estimator = field(factory=Estimator)
    start: int = 0
    """The value whose policy is in force before any event (default: the first)."""
    calibration: Calibration | None = None
    """The model's predictions of the events (None: the event model's ``probability``)."""

    def __attrs_post_init__(self) -> None:
        if len(self.values) != len(self.controllers) or len(self.values) < 2:
            raise PolicyError("an adaptive controller needs two or more parameter values, one controller each")
        if len(set(self.values)) != len(self.values):
            raise PolicyError(f"an adaptive controller gives {self.parameter} a value twice")
        first = self.controllers[0]
        for urc in self.controllers[1:]:
            if urc.observation != first.observation or urc.services != first.services:
                raise PolicyError("the controllers of an adaptive controller must read and decide the same things")
        if not 0 <= self.start < len(self.values):
            raise PolicyError(f"start {self.start} is not the index of one of the {len(self.values)} values")

    def likelihood(self, probability: Likelihood = bernoulli) -> PolicyLikelihood:
        """How the estimator weighs an event: by the calibration if there is one, else by
        ``probability`` (the case study's event model's) of the value."""
        if self.calibration is not None:
            return self.calibration.likelihood
        values = self.values

        def by_value(value: int, policies: np.ndarray, outcomes: np.ndarray, contexts: np.ndarray) -> np.ndarray:
            return probability(values[value], outcomes, contexts)

        return by_value

    def runtime(self, probability: Likelihood = bernoulli) -> AdaptiveURC:
        return AdaptiveURC(self, probability)

    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "parameter": self.parameter,
            "estimator": {"forgetting": self.estimator.forgetting, "hysteresis": self.estimator.hysteresis},
            "start": self.start,
            **({"calibration": self.calibration.to_json()} if self.calibration is not None else {}),
            "scenarios": [
                {"value": value, "controller": urc.to_json()} for value, urc in zip(self.values, self.controllers)
            ],
        }

    def save(self, path: Path | str) -> None:
        Path(path).write_text(json.dumps(self.to_json(), indent=2) + "\n")

    @classmethod
    def load(cls, path: Path | str) -> AdaptiveController:
        path = Path(path)
        return cls.from_document(read_document(path, "give a file written by `parley adapt`"), path)

    @classmethod
    def from_document(cls, data: Mapping[str, Any], path: Path) -> AdaptiveController:
        """The adaptive controller of a controller file's document, or PolicyError."""
        if data.get("format") != FORMAT:
            raise PolicyError(
                f"controller file {path} is not an adaptive controller ({FORMAT}); write it with `parley adapt`"
            )
        try:
            return cls(
                parameter=str(data["parameter"]),
                values=[float(s["value"]) for s in data["scenarios"]],
                controllers=[URC.from_json(s["controller"]) for s in data["scenarios"]],
                estimator=Estimator(**{k: float(v) for k, v in data.get("estimator", {}).items()}),
                start=int(data.get("start", 0)),
                calibration=Calibration.from_json(data["calibration"]) if "calibration" in data else None,
            )
        except (KeyError, TypeError, ValueError, ParleyError) as exc:
            raise PolicyError(f"controller file {path} is malformed ({exc}); write it with `parley adapt`") from None


def load_controller(path: Path) -> URC | AdaptiveController:
    """A plain controller (``parley select``) or an adaptive one (``parley adapt``), by the
    file's format."""
    data = read_document(path, "give a file written by `parley select` or `parley adapt`")
    if data.get("format") == FORMAT:
        return AdaptiveController.from_document(data, path)
    return URC.from_document(data, path)


class AdaptiveURC:
    """The runtime adaptive URC of one system: ``decide`` as the policy in force does,
    ``observe`` events as they happen, ``adapt`` at each mission's end."""

    def __init__(self, controller: AdaptiveController, probability: Likelihood = bernoulli) -> None:
        self.controller = controller
        self._beliefs = Beliefs(
            controller.values, controller.estimator, controller.likelihood(probability), 1, controller.start
        )
        self.switches: list[tuple[int, float, float]] = []
        """(mission, old value, new value) of every switch."""
        self.missions = 0

    @property
    def value(self) -> float:
        """The parameter value whose policy is in force."""
        return self.controller.values[int(self._beliefs.current[0])]

    @property
    def urc(self) -> URC:
        return self.controller.controllers[int(self._beliefs.current[0])]

    @property
    def scores(self) -> dict[float, float]:
        """Each value's discounted log-likelihood of the events seen."""
        return dict(zip(self.controller.values, (float(s) for s in self._beliefs.scores[0])))

    def decide(self, observation) -> dict[str, int]:
        return self.urc.decide(observation)

    def observe(self, outcome: bool | int, context: int = 0) -> None:
        if int(outcome) not in (0, 1):
            raise ObservationError(f"an event's outcome is 0 or 1, got {outcome!r}")
        self._beliefs.observe(np.zeros(1, dtype=np.int64), np.array([int(outcome)]), np.array([int(context)]))

    def adapt(self) -> float:
        """A mission ended: maybe switch (see the module docstring); returns the value in force."""
        before = self.value
        self._beliefs.adapt()
        self.missions += 1
        if self.value != before:
            self.switches.append((self.missions, before, self.value))
        return self.value
