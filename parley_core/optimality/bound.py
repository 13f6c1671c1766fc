"""How good is a front: a certified outer bound on what any policy of the family reaches.

The bound is a set of points B such that every policy of the family is weakly dominated by
some point of B. This module computes the cheap one, the *ideal point*: per objective, the
best value over all schedulers of the quotient's relaxation (:mod:`parley_core.quotient.relaxation`),
whose schedulers include every policy's DTMC, solved by Storm with sound value iteration and
widened by its precision. The run reports how much of the bound's hypervolume its front
covers (the gap).

An objective the relaxation cannot express (a state formula that mentions "deadlock" other
than as an eventual target, or one the quotient evaluator leaves to Storm) gets the trivial
bound: the best value its kind can have (1 or 0 for a probability, 0 or infinity for a
reward).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from attrs import field, frozen, validators

from parley_core import metrics
from parley_core.model import Direction, Family, Objective
from parley_core.optimality.archive import staircase
from parley_core.optimality.records import BeliefValue, SearchCounts
from parley_core.quotient.bounds import RelaxedObjectives
from parley_core.quotient.coloring import Quotient
from parley_core.quotient.compile import KernelKind, KernelObjective
from parley_core.quotient.relaxation import storm_model

if TYPE_CHECKING:
    from parley_core.optimality.branch_and_bound import ExactResult

PRECISION = 1e-9
"""Sound value iteration's precision on the relaxation: absolute for probabilities, relative
to the largest state value for rewards; the bound is widened by it."""


@frozen(kw_only=True)
class Bound:
    """Points (rows, in the objectives' own units) that weakly dominate every policy of the family."""

    objectives: tuple[Objective, ...] = field(converter=tuple[Objective, ...])
    points: np.ndarray = field(eq=False)
    method: str
    exact: bool = False
    """The points are the family's whole Pareto front (branch and bound finished)."""
    seconds: float = 0.0
    search: SearchCounts | None = field(default=None, eq=False)
    """Branch and bound's counts, where it made the bound."""
    belief: Mapping[str, BeliefValue] | None = field(default=None, eq=False)
    """The belief bound's values per objective, where it tightened the ideal point."""
    cuts: tuple = field(default=(), eq=False, repr=False)
    """Half-spaces (weights, level) in sign space (every objective maximised) that every
    policy satisfies, where the method found them."""

    def dominates(self, values: np.ndarray, tolerance: float = 1e-9) -> np.ndarray:
        """Which rows of ``values`` some point of the bound weakly dominates (to ``tolerance``
        of the value's size, at least 1)."""
        signs = np.array([o.direction.sign for o in self.objectives])
        points = np.asarray(self.points, dtype=float) * signs
        rows = np.asarray(values, dtype=float).reshape(-1, len(self.objectives)) * signs
        slack = tolerance * np.maximum(1.0, np.abs(np.where(np.isfinite(rows), rows, 0.0)))
        with np.errstate(invalid="ignore"):
            return ((points[None, :, :] <= rows[:, None, :] + slack[:, None, :]).all(axis=2)).any(axis=1)

    def hypervolume(self, reference: Sequence[float]) -> float:
        directions = [o.direction for o in self.objectives]
        if not np.isfinite(self.points).all():
            return float("inf")
        return metrics.hypervolume(np.asarray(self.points, dtype=float), directions, reference)


def _trivial(objective: Objective, kernel: KernelObjective | None) -> float:
    probability = kernel is not None and kernel.kind in (KernelKind.UNTIL, KernelKind.BOUNDED)
    if probability or (kernel is None and objective.formula.lstrip().startswith("P")):
        return 1.0 if objective.direction is Direction.MAX else 0.0
    return float("inf") if objective.direction is Direction.MAX else 0.0


def _label(mask: np.ndarray | None, name: str, default: str) -> str:
    """A state formula for a mask: its label, or ``true``/``false`` when it holds everywhere
    or nowhere (a label on no state does not exist in Storm's explicit format)."""
    if mask is None:
        return default
    if bool(np.all(mask)):
        return "true"
    if not bool(np.any(mask)):
        return "false"
    return f'"{name}"'


@frozen(kw_only=True)
class Query:
    """A single-objective query on the relaxation, as parts: what it asks (``kind``), ``max``
    or ``min``, its state formulas (a label such as ``"psi0"``, or ``true``/``false``), its
    reward structure and step bound; :attr:`text` is Storm's property syntax."""

    kind: KernelKind
    best: str = field(validator=validators.in_(("max", "min")))
    left: str = "true"
    right: str = "false"
    reward: str | None = None
    steps: int | None = None

    @property
    def text(self) -> str:
        if self.kind is KernelKind.UNTIL:
            return f"P{self.best}=? [{self.left} U {self.right}]"
        if self.kind is KernelKind.BOUNDED:
            return f"P{self.best}=? [{self.left} U<={self.steps} {self.right}]"
        reward = f'R{{"{self.reward}"}}{self.best}=?'
        if self.kind is KernelKind.REACH_REWARD:
            return f"{reward} [F {self.right}]"
        if self.kind is KernelKind.CUMULATIVE:
            return f"{reward} [C<={self.steps}]"
        return f"{reward} [C]"

    def eventually(self) -> str | None:
        """The query as an eventually-formula (``F psi``), what Storm's belief exploration of
        a POMDP takes: reachability (an until from ``true``) and rewards to a target; None
        for any other."""
        if self.kind is KernelKind.UNTIL and self.left == "true":
            return f"P{self.best}=? [F {self.right}]"
        return self.text if self.kind is KernelKind.REACH_REWARD else None


def _query(index: int, objective: Objective, kernel: KernelObjective) -> Query | None:
    """The single-objective query on the relaxation (labels phi_i, psi_i; rewards r0, r1, ...)."""
    best = "max" if objective.direction is Direction.MAX else "min"
    left = _label(kernel.left, f"phi{index}", "true")
    right = f'"psi{index}"' if kernel.right_deadlock else _label(kernel.right, f"psi{index}", "false")
    if kernel.kind is KernelKind.UNTIL:
        if kernel.right_deadlock and left != "true":
            return None
        return Query(kind=kernel.kind, best=best, left=left, right=right)
    if kernel.kind is KernelKind.BOUNDED:
        return (
            None
            if kernel.right_deadlock
            else Query(kind=kernel.kind, best=best, left=left, right=right, steps=kernel.steps)
        )
    reward = f"r{kernel.reward}"
    if kernel.kind is KernelKind.REACH_REWARD:
        return Query(kind=kernel.kind, best=best, right=right, reward=reward)
    if kernel.kind is KernelKind.CUMULATIVE:
        return Query(kind=kernel.kind, best=best, reward=reward, steps=kernel.steps)
    return Query(kind=kernel.kind, best=best, reward=reward)


def sound_environment(precision: float, relative: bool):
    """A Storm environment whose MDP solver is sound value iteration at ``precision``."""
    import stormpy
    import stormpy.developer as storm_dev

    environment = stormpy.Environment()
    minmax = environment.solver().min_max()
    minmax.method = storm_dev.MinMaxMethod.SOUND_VALUE_ITERATION
    minmax.precision = stormpy.Rational(precision)
    minmax.relative_termination_criterion = relative
    return environment


def _solve(model, text: str) -> tuple[float, float]:
    import stormpy

    (prop,) = stormpy.parse_properties(text)
    initial = model.initial_states[0]
    estimate = np.asarray(stormpy.model_checking(model, prop).get_value_vector(), dtype=float)
    finite = estimate[np.isfinite(estimate)]
    scale = max(1.0, float(np.abs(finite).max())) if len(finite) else 1.0
    environment = sound_environment(PRECISION * scale, relative=False)
    value = float(stormpy.model_checking(model, prop, environment=environment).get_value(initial))
    return value, PRECISION * scale


def relaxation_queries(
    family: Family, quotient: Quotient, wanted: Sequence[bool] | None = None
) -> tuple[dict[str, np.ndarray], list[Query | None]]:
    """Storm's single-objective queries on the relaxation (None where it cannot express one,
    or where ``wanted`` is False) and the state labels they use (``phi_i``, ``psi_i``: one
    more state, the relaxation's deadlock sink)."""
    labels: dict[str, np.ndarray] = {}
    queries: list[Query | None] = []
    for i, (objective, kernel) in enumerate(zip(family.objectives, quotient.objectives)):
        if kernel is None or (wanted is not None and not wanted[i]):
            queries.append(None)
            continue
        query = _query(i, objective, kernel)
        queries.append(query)
        if query is None:
            continue
        if kernel.left is not None:
            labels[f"phi{i}"] = np.append(kernel.left, False)
        if kernel.right is not None:
            # a policy's own deadlocks are the relaxation's moves to the sink
            labels[f"psi{i}"] = np.append(kernel.right, bool(kernel.right_deadlock))
    return labels, queries


def ideal_point(
    family: Family, quotient: Quotient, bounds: RelaxedObjectives | None = None, by_storm: bool = False
) -> Bound:
    """The ideal point over all schedulers of the quotient's relaxation: a sound bound. Each
    objective the compiled kernels bound (:mod:`parley_core.quotient.bounds`, safe by
    construction) is solved there, the others (all, with ``by_storm``) by Storm's sound value
    iteration."""
    start = time.perf_counter()
    bounds = bounds or RelaxedObjectives(family, quotient)
    relaxation = bounds.relaxation
    everything = bounds.restrict(np.zeros(len(bounds.sizes), dtype=np.int64), bounds.sizes - 1)
    own = bounds.ideal(everything) * bounds.signs
    ours = [supported and not by_storm for supported in bounds.supported]
    labels, queries = relaxation_queries(family, quotient, [not own for own in ours])
    model = storm_model(relaxation, labels) if any(q is not None for q in queries) else None
    point = []
    for i, (objective, kernel, query) in enumerate(zip(family.objectives, quotient.objectives, queries)):
        if ours[i]:
            point.append(float(own[i]))
        elif query is None:
            point.append(_trivial(objective, kernel))
        else:
            value, precision = _solve(model, query.text)
            point.append(value + precision * (1.0 if objective.direction is Direction.MAX else -1.0))
    by = "compiled kernels" + (", Storm" if model is not None else "")
    return Bound(
        objectives=family.objectives,
        points=np.array([point]),
        method=f"ideal point: per objective the best over all schedulers of the quotient's relaxation ({by})",
        seconds=time.perf_counter() - start,
    )


def refined_bound(family: Family, result: ExactResult) -> Bound:
    """The bound branch and bound leaves: its front and the regions (ideal points, for two
    objectives cut by their half-spaces) of the sub-families it did not resolve (all of which
    it proved to hold no better policy otherwise)."""
    directions = [o.direction for o in family.objectives]
    points = np.asarray(result.bound, dtype=float).reshape(-1, len(directions))
    if len(points):
        points = points[metrics.nondominated(points, directions)]
    return Bound(
        objectives=family.objectives,
        points=points,
        method=(
            "branch and bound: the whole Pareto front, proven on the quotient's relaxation"
            if result.exact
            else "branch and bound: the front and the regions of the sub-families left open"
        )
        + (f" (not covering {result.unknown} policies that have no value)" if result.unknown else ""),
        exact=result.exact,
        seconds=result.seconds,
        search=result.counts(),
    )


DIRECTIONS = 24
"""Weighted sums the Pareto outer approximation solves (two objectives)."""
STEPS = 96
"""Points of the staircase that covers the approximation's boundary from outside."""
ATTAINED = 1e-12
"""A balanced weighted sum this close to the ideal point's (relative) shows one scheduler
attains the ideal point: no weighted sum can cut it, none is solved (sound either way: the
ideal box holds every policy)."""


def pareto_outer(
    family: Family, quotient: Quotient, ideal: Bound | None = None, bounds: RelaxedObjectives | None = None
) -> Bound:
    """An outer approximation of the relaxation's Pareto curve, for two objectives that
    combine in a weighted sum (step-bounded rewards and at most one reachability objective, or
    minimised expected rewards to one target): the ideal box cut by the half-spaces of
    ``DIRECTIONS`` weighted sums, each a sound upper bound on the relaxation
    (:mod:`parley_core.quotient.bounds`), covered by a staircase of points. Otherwise (or if
    nothing is cut) the ideal point."""
    start = time.perf_counter()
    bounds = bounds or RelaxedObjectives(family, quotient)
    ideal = ideal or ideal_point(family, quotient, bounds)
    if len(family.objectives) != 2 or not bounds.combines or not np.isfinite(ideal.points).all():
        return ideal
    signs = bounds.signs
    view = bounds.restrict(np.zeros(len(bounds.sizes), dtype=np.int64), bounds.sizes - 1)
    top = np.minimum(ideal.points[0] * signs, bounds.ideal(view))  # sign space: maximised
    # scale the objectives by how far the relaxation's worst-for-the-other extremes lie
    angles = np.linspace(0.0, np.pi / 2, DIRECTIONS + 2)[1:-1]
    extremes = bounds.weighted(view, np.array([[1.0, 1e-6], [1e-6, 1.0]]))
    span = np.abs(top - np.array([extremes[1] - 1e-6 * top[1], extremes[0] - 1e-6 * top[0]]))
    span = np.where(np.isfinite(span) & (span > 1e-12), span, 1.0)
    weights = np.column_stack([np.cos(angles) / span[0], np.sin(angles) / span[1]])
    # a scheduler that attains the whole ideal point (herman's: fewest steps and likeliest to
    # stabilise in 30 at once) leaves every weighted sum at the ideal's: one balanced sum shows it
    middle = len(weights) // 2
    levels = np.empty(len(weights))
    levels[middle] = bounds.weighted(view, weights[middle : middle + 1])[0]
    if levels[middle] >= weights[middle] @ top - ATTAINED * (1.0 + abs(weights[middle] @ top)):
        return ideal
    others = np.arange(len(weights)) != middle
    levels[others] = bounds.weighted(view, weights[others])
    finite = np.isfinite(levels)
    weights, levels = weights[finite], levels[finite]
    if not len(levels):
        return ideal

    points = staircase(top, weights, levels, STEPS)
    how = (
        "backward induction"
        if bounds.weighted_ok
        else "expected rewards to the target"
        if bounds.summed_ok
        else "backward induction over the step bound, then expected rewards to the target"
    )
    return Bound(
        objectives=family.objectives,
        points=points * signs,
        cuts=tuple((w, float(c)) for w, c in zip(weights, levels)),
        method=(
            "Pareto outer approximation: the relaxation's ideal box cut by "
            f"{len(levels)} weighted sums ({how}), covered by a staircase"
        ),
        seconds=ideal.seconds + time.perf_counter() - start,
    )


def intersect(first: Bound, second: Bound, method: str) -> Bound:
    """A bound from two: what both leave open (per pair of points the worse value of each
    objective, the dominated ones dropped), or ``second`` alone if that would take more than
    a million pairs (each is sound on its own)."""
    directions = [o.direction for o in first.objectives]
    a, b = np.asarray(first.points, dtype=float), np.asarray(second.points, dtype=float)
    if len(a) * len(b) > 1_000_000:
        return second
    signs = np.array([o.direction.sign for o in first.objectives])  # +1: minimised
    pairs = np.maximum(a[:, None, :] * signs, b[None, :, :] * signs).reshape(-1, len(signs)) * signs
    pairs = pairs[metrics.nondominated(pairs, directions)]
    return Bound(
        objectives=first.objectives,
        points=np.unique(pairs, axis=0),
        method=method,
        exact=first.exact or second.exact,
        seconds=first.seconds + second.seconds,
        search=second.search if second.search is not None else first.search,
        belief=second.belief if second.belief is not None else first.belief,
        cuts=first.cuts + second.cuts,
    )
