"""The reference evaluator: instantiate, build with Storm, check. Slow and simple, and the judge.

A small policy DTMC (:data:`EXACT_STATES`) is checked in exact rational arithmetic; a larger
one by sound value iteration with the precision chosen per property shape
(:func:`check_value`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import stormpy
import stormpy.developer as storm_dev
from attrs import frozen

from parley_core.errors import ModelError
from parley_core.evaluate.pool import PoolOwner, ProcessPool, default_workers, worker_state
from parley_core.model import Family
from parley_core.prism import program as prism
from parley_core.progress import Progress

EXACT_STATES = 4_000
"""An unbounded reward (``R=? [F phi]``, ``R=? [C]``) of a policy DTMC up to this many
states is checked in exact rational arithmetic (PAYNT's dpm, 3,896 states: 0.1 s for both
objectives; maze, whose expected steps reach 10^5, 4 ms where sound value iteration took
10 s). Other objectives, and larger models, get sound value iteration (:func:`check_value`):
exact arithmetic costs 2-6 times as much on step-bounded objectives (robot_grid's C<=k)."""

PRECISION = 1e-12
"""The precision of Storm's equation solving: relative for probabilities, relative to the
largest value for rewards (see :func:`reference_environment`)."""


def reference_environment(precision: float = PRECISION, relative: bool = True) -> stormpy.Environment:
    """Storm's native solver with sound value iteration at ``precision``.

    Storm's default solvers stop at a relative precision of 1e-6 (seen here 2e-8 away from
    the exact rational result on robot_grid models) and bound nothing; sound value
    iteration bounds its error and, at 1e-12, agrees with the exact result to about 1e-15
    at no measurable extra cost. Bounded properties (``C<=k``, ``F<=k``) are computed
    exactly by iteration anyway.
    """
    environment = stormpy.Environment()
    solver = environment.solver()
    solver.set_linear_equation_solver_type(storm_dev.EquationSolverType.NATIVE)
    native = solver.native()
    native.method = storm_dev.NativeLinearEquationSolverMethod.SOUND_VALUE_ITERATION
    native.precision = stormpy.Rational(precision)
    native.relative_termination_criterion = relative
    return environment


def unbounded_reward(prop) -> bool:
    """Whether a property is a reward over an unbounded horizon (``R=? [F phi]``, ``R=? [C]``)."""
    formula = prop.get_raw_formula()
    return bool(formula.is_reward_operator_formula) and not isinstance(
        formula.subformula, (stormpy.logic.CumulativeRewardFormula, stormpy.logic.InstantaneousRewardFormula)
    )


def check_value(model, prop, relative_environment: stormpy.Environment) -> float:
    """One property's value at the model's (only) initial state; see :func:`check_values`."""
    return check_values(model, prop, relative_environment, [model.initial_states[0]])[0]


def check_values(model, prop, relative_environment: stormpy.Environment, states) -> list[float]:
    """One property's values at ``states``, by sound value iteration.

    A probability is solved to a relative precision of 1e-12: Storm's graph analysis leaves
    only states with values strictly between 0 and 1 to the solver. An unbounded reward is
    not: states that earn nothing before the target keep the value 0, and sound value
    iteration with a relative criterion never ends there (seen on PAYNT's dpm, a reward that
    is 0 in many states: over 20 minutes for 3,665 states). Rewards are therefore solved to
    an absolute precision of 1e-12 times the largest value of any state, which Storm's
    default solver estimates first (a bound of 1e-12 relative to the largest value; the
    estimate only sets where to stop, the bound is sound value iteration's)."""
    if not unbounded_reward(prop):
        result = stormpy.model_checking(model, prop, environment=relative_environment)
        return [float(result.get_value(s)) for s in states]
    estimate = np.asarray(stormpy.model_checking(model, prop).get_value_vector(), dtype=float)
    finite = estimate[np.isfinite(estimate)]
    scale = max(1.0, float(np.abs(finite).max())) if len(finite) else 1.0
    absolute = reference_environment(PRECISION * scale, relative=False)
    result = stormpy.model_checking(model, prop, environment=absolute)
    return [float(result.get_value(s)) for s in states]


def check_instance(
    instance,
    properties,
    objective_names,
    unbounded: list[bool],
    environment,
    *,
    at: Callable[[Any], list[int]] | None = None,
) -> tuple[Any, list[int], list[list[float]]]:
    """Build a program whose constants are all defined and check every property at each of
    its initial states (or at the states ``at(model)`` names): the model, those states and
    ``values[state][objective]``.

    Checked at its one initial state alone, a model of at most :data:`EXACT_STATES` states
    has its unbounded rewards checked in exact rational arithmetic."""
    options = stormpy.BuilderOptions(properties)

    def build(value_type, build_options):
        try:
            return stormpy.build_model[value_type](instance, options=build_options)
        except RuntimeError as exc:
            raise ModelError(f"Storm cannot build the model: {prism.storm_message(exc)}") from None

    model = build(float, options)
    initial = list(model.initial_states) if at is None else at(model)
    exact = None
    if model.nr_states <= EXACT_STATES and any(unbounded) and initial == list(model.initial_states)[:1]:
        exact = build(stormpy.Rational, stormpy.BuilderOptions(properties))
    columns = []
    for prop, name, is_unbounded in zip(properties, objective_names, unbounded):
        try:
            if exact is not None and is_unbounded:
                columns.append([float(stormpy.model_checking(exact, prop).get_value(exact.initial_states[0]))])
            else:
                columns.append(check_values(model, prop, environment, initial))
        except RuntimeError as exc:
            raise ModelError(f"Storm cannot check objective {name!r}: {prism.storm_message(exc)}") from None
    return model, initial, [list(row) for row in zip(*columns)] if columns else [[] for _ in initial]


@frozen(kw_only=True)
class StormTask:
    """What a process needs to check policies of one family (picklable)."""

    prism: str
    names: tuple[str, ...]
    formulas: tuple[str, ...]
    objective_names: tuple[str, ...]

    @classmethod
    def of(cls, family: Family) -> StormTask:
        return cls(
            prism=family.prism,
            names=family.names,
            formulas=tuple(o.formula for o in family.objectives),
            objective_names=tuple(o.name for o in family.objectives),
        )


class StormChecker:
    """Checks policies of one family in this process: parse once, then build and check each policy."""

    def __init__(self, task: StormTask) -> None:
        self.task = task
        self.program = prism.parse_program(task.prism, origin="the augmented model")
        self.properties = prism.parse_properties(task.formulas, self.program, origin="objective")
        for prop, name in zip(self.properties, task.objective_names):
            prism.check_property_references(prop, self.program, origin=f"objective {name!r}")
        by_name = {c.name: c.expression_variable for c in self.program.constants}
        missing = [n for n in task.names if n not in by_name]
        if missing:
            raise ModelError(f"the augmented model lacks decision constants {', '.join(missing[:5])}")
        self.variables = [by_name[n] for n in task.names]
        self.environment = reference_environment()
        self.unbounded_rewards = [unbounded_reward(p) for p in self.properties]

    def check(self, values) -> list[float]:
        manager = self.program.expression_manager
        instance = self.program.define_undefined_constants(
            {v: manager.integer(int(k)) for v, k in zip(self.variables, values)}
        )
        _, _, rows = check_instance(
            instance, self.properties, self.task.objective_names, self.unbounded_rewards, self.environment
        )
        if len(rows) != 1:
            raise ModelError(f"the model has {len(rows)} initial states; parley needs exactly one")
        return rows[0]


def _worker_check(task: StormTask, values: tuple[int, ...]) -> list[float]:
    return worker_state(StormChecker, task).check(values)


class StormEvaluator(PoolOwner):
    """Evaluate policies with Storm, in this process or in ``workers`` processes."""

    name = "storm"

    def __init__(self, family: Family, workers: int | None = None) -> None:
        self.family = family
        self.task = StormTask.of(family)
        self.local = StormChecker(self.task)  # also validates the family before any work is sent out
        self.workers = default_workers(workers)
        self._pool: ProcessPool | None = None

    def describe(self) -> dict[str, object]:
        return {}

    def evaluate(self, policies: np.ndarray, progress: Progress | None = None) -> np.ndarray:
        policies = np.asarray(policies, dtype=np.int64).reshape(-1, len(self.family.decisions))
        rows = [tuple(int(v) for v in row) for row in policies]
        out = np.empty((len(rows), len(self.family.objectives)))
        if self.workers == 1 or len(rows) <= 2:
            for i, row in enumerate(rows):
                out[i] = self.local.check(row)
                if progress:
                    progress(1)
            return out
        pool = self._executor()
        futures = [pool.submit(_worker_check, self.task, row) for row in rows]
        for i, future in enumerate(futures):
            out[i] = future.result()
            if progress:
                progress(1)
        return out
