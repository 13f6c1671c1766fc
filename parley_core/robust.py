"""Robust runs: one family per scenario, each policy scored by its worst case over them.

A scenario set (:mod:`parley_core.family.scenarios`) changes a model's numbers, not its structure:
every scenario's quotient must have the same states, choices and transitions as the first
one's (:func:`check_structure`), and the same decisions and objectives, so that one policy
means the same thing in each. The search sees the worst value per objective (the smallest
of a maximised one, the largest of a minimised one) of one evaluator per scenario
(:class:`WorstCaseEvaluator`); every front policy and baseline is then re-checked by Storm
in every scenario (:func:`check_scenarios`), and the worst of Storm's values is what the
front reports. A bound of any one scenario bounds the worst case too (a policy's worst value
is no better than its value there), so the run's bound is every scenario's bound intersected.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from parley_core.errors import OptionError
from parley_core.evaluate import Consulting, EvaluatorKind
from parley_core.family.scenarios import ScenarioModel
from parley_core.model import Direction, Family, Objective
from parley_core.optimality.records import BoundMethod
from parley_core.progress import NullReporter, Progress, Reporter


def worst(values: np.ndarray, objectives: Sequence[Objective]) -> np.ndarray:
    """The worst case over scenarios of values [n, scenarios, objectives]: per objective the
    smallest value of a maximised one, the largest of a minimised one (NaN if any is NaN)."""
    values = np.asarray(values, dtype=float)
    out = np.empty((values.shape[0], values.shape[2]))
    for j, objective in enumerate(objectives):
        column = values[:, :, j]
        out[:, j] = column.min(axis=1) if objective.direction is Direction.MAX else column.max(axis=1)
    return out


def _decision_space(family: Family) -> tuple:
    return (
        family.observation,
        tuple((d.name, d.service.constant, tuple(d.service.values)) for d in family.decisions),
        tuple((o.name, o.direction) for o in family.objectives),
    )


def _changed(first: ScenarioModel, other: ScenarioModel) -> str:
    """The options in which two scenarios differ, for an error message."""
    keys = [
        k
        for k in dict.fromkeys(first.scenario.keys + other.scenario.keys)
        if first.scenario.values.get(k) != other.scenario.values.get(k)
    ]
    return ", ".join(f"option {k}" for k in keys) or "its options"


def check_decisions(models: Sequence[ScenarioModel]) -> None:
    """Every scenario's family has the first one's decisions, observation and objectives."""
    first = models[0]
    for model in models[1:]:
        if _decision_space(model.family) != _decision_space(first.family):
            raise OptionError(
                f"scenario {model.label} changes the model's structure ({_changed(first, model)}): its URC "
                f"would decide other things ({len(model.family.decisions)} decisions against "
                f"{len(first.family.decisions)} of {first.label}, or other objectives); scenarios may change "
                "only the model's numbers"
            )


STRUCTURE = ("state_choices", "choice_branches", "targets", "choice_dec", "choice_val")
"""The quotient arrays two scenarios must share: states, choices, transitions, decisions."""


def check_structure(models: Sequence[ScenarioModel], quotients: Sequence[Any]) -> None:
    """Every scenario's quotient has the first one's states, choices and transitions (Storm
    explores states in the same order when only probabilities and rewards differ)."""
    first, reference = models[0], quotients[0]
    for model, quotient in zip(models[1:], quotients[1:]):
        same = quotient.states == reference.states and all(
            np.array_equal(getattr(quotient, name), getattr(reference, name)) for name in STRUCTURE
        )
        if not same:
            raise OptionError(
                f"scenario {model.label} changes the model's structure ({_changed(first, model)}): its model has "
                f"{quotient.states} states and {quotient.branches} transitions against {reference.states} and "
                f"{reference.branches} of {first.label}; scenarios may change only probabilities and rewards "
                "(a probability that becomes 0 or 1 removes transitions): drop the scenario or run it on its own"
            )


class WorstCaseEvaluator:
    """An evaluator of the worst case over one evaluator per scenario; it remembers every
    scenario's values of what it evaluated (:meth:`scenario_values`)."""

    def __init__(self, engines: Sequence[Any], objectives: Sequence[Objective], n_decisions: int) -> None:
        self.engines = list(engines)
        self.objectives = tuple(objectives)
        self.name = self.engines[0].name
        self.n_decisions = n_decisions
        self._seen: dict[bytes, np.ndarray] = {}

    @property
    def workers(self) -> int:
        return self.engines[0].workers

    def _each(self, policies: np.ndarray, progress: Progress | None) -> tuple[np.ndarray, np.ndarray]:
        """Values [n, scenarios, objectives] and consulted decisions [n, decisions] (in any scenario)."""
        count = len(self.engines)
        done = [0, 0]  # policies evaluated over all scenarios, progress reported

        def advance(n: int) -> None:
            done[0] += n
            now = done[0] // count
            if progress and now > done[1]:
                progress(now - done[1])
                done[1] = now

        values, consulted = [], np.zeros(policies.shape, dtype=bool)
        for engine in self.engines:
            if isinstance(engine, Consulting):
                value, mask = engine.evaluate_consulted(policies, progress=advance)
                consulted |= mask
            else:
                value = engine.evaluate(policies, progress=advance)
                consulted[:] = True
            values.append(np.asarray(value, dtype=float))
        each = np.stack(values, axis=1)
        for row, value in zip(policies, each):
            self._seen[row.tobytes()] = value
        return each, consulted

    def evaluate_consulted(self, policies: np.ndarray, progress: Progress | None = None):
        policies = np.asarray(policies, dtype=np.int64).reshape(-1, self.n_decisions)
        each, consulted = self._each(policies, progress)
        return worst(each, self.objectives), consulted

    def evaluate(self, policies: np.ndarray, progress: Progress | None = None) -> np.ndarray:
        return self.evaluate_consulted(policies, progress)[0]

    def scenario_values(self, policies: np.ndarray) -> np.ndarray:
        """Every scenario's values [n, scenarios, objectives] of ``policies`` (evaluating the new ones)."""
        policies = np.asarray(policies, dtype=np.int64).reshape(-1, self.n_decisions)
        new = np.array([row for row in policies if row.tobytes() not in self._seen], dtype=np.int64)
        if len(new):
            self._each(new.reshape(-1, self.n_decisions), None)
        return (
            np.stack([self._seen[row.tobytes()] for row in policies])
            if len(policies)
            else np.empty((0, len(self.engines), len(self.objectives)))
        )

    def describe(self) -> dict[str, object]:
        return {"scenarios": [e.describe() for e in self.engines]}

    def close(self, abort: bool = False) -> None:
        for engine in self.engines:
            engine.close(abort=abort)


def make_evaluator(
    models: Sequence[ScenarioModel], kind: EvaluatorKind, workers: int | None, reporter: Reporter | None = None
) -> WorstCaseEvaluator:
    """Build every scenario's quotient, check that they share one structure, and the worst
    case of one evaluator of ``kind`` per scenario."""
    from parley_core.evaluate.quotient import QuotientEvaluator
    from parley_core.evaluate.storm import StormEvaluator
    from parley_core.quotient.coloring import build_quotient

    reporter = reporter or NullReporter()
    check_decisions(models)
    reporter.stage("scenario models", len(models))
    quotients = []
    for model in models:
        quotients.append(build_quotient(model.family))
        reporter.advance(1)
    check_structure(models, quotients)
    engines: list[Any] = []
    try:
        for model, quotient in zip(models, quotients):
            if kind is EvaluatorKind.QUOTIENT:
                # one process each: a pool per scenario starts workers x scenarios processes, and
                # on 2 cores their start-up cost more than they saved (3 scenarios of a 5x5 map:
                # 35 s against 6 s for baselines, search and bound)
                engines.append(QuotientEvaluator(model.family, workers=1, quotient=quotient))
            else:
                engines.append(StormEvaluator(model.family, workers=workers))
    except BaseException:
        for engine in engines:
            engine.close(abort=True)
        raise
    first = models[0].family
    return WorstCaseEvaluator(engines, first.objectives, len(first.decisions))


def check_scenarios(
    models: Sequence[ScenarioModel],
    engine: WorstCaseEvaluator,
    policies: np.ndarray,
    workers: int | None,
    reporter: Reporter,
    names: list[str | None],
    baselines: int,
    path,
):
    """Storm's values of ``policies`` in every scenario, checked against the search's; returns
    the combined verification, the worst case [n, objectives] and every scenario's [n, scenarios, objectives]."""
    from parley_core.errors import EvaluatorDisagreement
    from parley_core.verify import Verification, check_with_storm

    searched = engine.scenario_values(policies)
    checked = np.empty_like(searched)
    parts = []
    for s, model in enumerate(models):
        reporter.note(f"Storm checks scenario {model.label} ({s + 1} of {len(models)})")
        try:
            part, checked[:, s] = check_with_storm(
                model.family, policies, searched[:, s], workers, reporter, names, baselines, path
            )
        except EvaluatorDisagreement as exc:
            raise EvaluatorDisagreement(f"in scenario {model.label}: {exc}") from None
        parts.append(part)
    verification = Verification(
        by=parts[0].by,
        policies=parts[0].policies,
        baselines=parts[0].baselines,
        max_difference=max(p.max_difference for p in parts),
        max_relative_difference=max(p.max_relative_difference for p in parts),
        seconds=sum(p.seconds for p in parts),
        path=parts[0].path,
        scenarios=len(models),
    )
    return verification, worst(checked, engine.objectives), checked


def bound(models: Sequence[ScenarioModel], engine: WorstCaseEvaluator, method: BoundMethod, outer):
    """Every scenario's bound (``outer(family, engine, method)``), intersected."""
    from parley_core.optimality.bound import intersect

    found, seconds = None, 0.0
    for model, part in zip(models, engine.engines):
        this = outer(model.family, part, method)[0]
        seconds += this.seconds
        found = this if found is None else intersect(found, this, this.method)
    assert found is not None
    if len(models) > 1:
        found = type(found)(
            objectives=found.objectives,
            points=found.points,
            method=f"{found.method.split(':')[0]}: of each of the {len(models)} scenarios, intersected "
            "(a policy's worst case is no better than its value in any one scenario)",
            seconds=seconds,
        )
    return found
