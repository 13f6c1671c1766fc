"""The test kit for parley and its plugins: helpers that need no core internals, and the
conformance suite.

- :func:`storm_values` checks PRISM text with plain stormpy calls (nothing of parley's
  evaluators), so a test can compare parley's values with Storm's on the same text.
- :func:`chain_values` checks a DTMC a test builds state by state (exact rationals), to
  compare a plugin's generated model with an independent one.
- :func:`case_study`, :func:`family` and :func:`values` build a case study's family and
  evaluate policies on it, the way a run does.
- :class:`~parley_core.testing.suite.ConformanceSuite` (import it from
  ``parley_core.testing.suite``, which needs pytest) runs the conformance checks of
  :mod:`parley_core.testing.conformance` on case studies; parley's pytest plugin adds
  ``pytest --parley-case NAME`` to run them without a test file. See docs/plugins.md.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable, Mapping, Sequence

import attrs
import numpy as np

from parley_core.model import Family, Policy, SystemModel
from parley_core.plugin.casestudy import CaseStudy


def storm_values(
    prism_text: str, formulas: Sequence[str], constants: Mapping[str, int] | None = None, exact: bool = False
) -> list[float]:
    """Each formula's value at the initial state of the DTMC ``prism_text`` with the given
    undefined constants defined. ``exact`` builds and checks with rational numbers (for
    nested thresholds such as ``P<1`` that rounding must not decide)."""
    import stormpy

    from parley_core.prism.program import quiet_storm

    quiet_storm()
    fd, path = tempfile.mkstemp(suffix=".prism")
    with os.fdopen(fd, "w") as handle:
        handle.write(prism_text)
    try:
        program = stormpy.parse_prism_program(path)
    finally:
        os.unlink(path)
    if constants:
        manager = program.expression_manager
        by_name = {c.name: c.expression_variable for c in program.constants}
        program = program.define_undefined_constants({by_name[k]: manager.integer(v) for k, v in constants.items()})
    properties = stormpy.parse_properties(";".join(formulas), program)
    if exact:
        model = stormpy.build_model[stormpy.Rational](program, properties)
    else:
        model = stormpy.build_model(program, properties)
    state = model.initial_states[0]
    return [float(stormpy.model_checking(model, p).get_value(state)) for p in properties]


def case_study(name: str) -> CaseStudy:
    """An installed case study by name (built-in or from an entry point)."""
    from parley_core.plugin.manager import load_registry

    return load_registry(strict=True).get(name)


def family(
    source: CaseStudy | str | SystemModel,
    assignments: Iterable[str] = (),
    *,
    prune: bool | None = None,
    width: int | None = None,
) -> Family:
    """The family a run would search: a case study (or its name) built with ``--set``-style
    ``assignments`` over its defaults, or a system model, augmented. ``prune`` defaults to
    the case study's own setting (False for a system model). ``width`` cuts every service's
    range to its first ``width`` values (a small family, for exhaustive checks), dropping the
    baselines that leave it."""
    from parley_core.family.prepare import make_family

    if isinstance(source, SystemModel):
        system, default_prune = source, False
    else:
        case = case_study(source) if isinstance(source, str) else source
        system, default_prune = case.build(case.options(list(assignments))), case.prune
    if width is not None:
        services = [attrs.evolve(s, high=min(s.high, s.low + width - 1), choices=()) for s in system.services]
        ranges = {s.constant: s.values for s in services}
        baselines = [b for b in system.baselines if all(v in ranges.get(c, (v,)) for c, v in b.values.items())]
        system = attrs.evolve(system, services=services, baselines=baselines)
    return make_family(system, prune=default_prune if prune is None else prune)


def values(
    family: Family, policies: Policy | Sequence[Policy] | np.ndarray, evaluator: str = "storm", workers: int = 1
) -> np.ndarray:
    """The objective values [policies, objectives] of policies of ``family``, by the Storm
    evaluator (the reference; default) or the quotient evaluator, in this process (or in
    ``workers`` processes)."""
    from parley_core.evaluate import make_evaluator

    if isinstance(policies, Policy):
        policies = [policies]
    if isinstance(policies, np.ndarray):
        rows = np.asarray(policies, dtype=np.int64).reshape(-1, len(family.decisions))
    else:
        for policy in policies:
            family.check(policy)
        rows = np.array([p.values for p in policies], dtype=np.int64).reshape(-1, len(family.decisions))
    engine = make_evaluator(family, evaluator, workers=workers)
    try:
        return engine.evaluate(rows)
    finally:
        engine.close()


def chain_values(
    start,
    commands,
    labels: Mapping[str, object],
    reward: str,
    formulas: Sequence[str],
) -> list[float]:
    """Storm's values at ``start`` of a DTMC given by its semantics: ``commands(state)`` lists
    the state's enabled commands as ``([(probability, successor)], reward)`` (probabilities
    as ``fractions.Fraction``; several commands are mixed uniformly, as Storm builds a DTMC
    whose commands overlap, and a state without any needs a self-loop command);
    ``labels`` maps a label to a predicate of states; ``reward`` names the reward structure
    the formulas use. Built in exact arithmetic with stormpy's sparse builder: no PRISM."""
    from fractions import Fraction

    import stormpy

    index, order, rows = {start: 0}, [start], []
    for state in order:
        found = commands(state)
        row: dict[int, Fraction] = {}
        for distribution, _ in found:
            for q, successor in distribution:
                if q == 0:
                    continue
                if successor not in index:
                    index[successor] = len(order)
                    order.append(successor)
                row[index[successor]] = row.get(index[successor], Fraction(0)) + Fraction(q) / len(found)
        rows.append((row, sum(Fraction(r) for _, r in found) / len(found)))
    builder = stormpy.datastructures.SparseMatrixBuilder[stormpy.Rational](len(order), len(order))
    for i, (row, _) in enumerate(rows):
        for j in sorted(row):
            builder.add_next_value(i, j, stormpy.Rational(str(row[j])))
    labeling = stormpy.models.StateLabeling(len(order))
    labeling.add_label("init")
    labeling.add_label_to_state("init", 0)
    for label, holds in labels.items():
        labeling.add_label(label)
        for i, state in enumerate(order):
            if holds(state):  # type: ignore[operator]
                labeling.add_label_to_state(label, i)
    rewards = stormpy.models.SparseRewardModel[stormpy.Rational](
        optional_state_action_reward_vector=[stormpy.Rational(str(r)) for _, r in rows]
    )
    components = stormpy.models.SparseModelComponents[stormpy.Rational](
        transition_matrix=builder.build(), state_labeling=labeling, reward_models={reward: rewards}
    )
    model = stormpy.models.SparseDtmc[stormpy.Rational](components)
    return [
        float(stormpy.model_checking(model, prop).get_value(model.initial_states[0]))
        for prop in stormpy.parse_properties("; ".join(formulas))
    ]


def left_to_storm(family: Family) -> tuple[str, ...]:
    """The objectives the quotient evaluator cannot solve and has Storm check instead."""
    from parley_core.evaluate.quotient import QuotientEvaluator

    with QuotientEvaluator(family, workers=1) as evaluator:
        return evaluator.fallback


__all__ = ["case_study", "chain_values", "family", "left_to_storm", "storm_values", "values"]
