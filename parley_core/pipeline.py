"""A run, stage by stage: build -> (prune) -> augment -> baselines -> search -> verify.

Each stage is timed and announced to a :class:`~parley_core.progress.Reporter` (the CLI
draws progress bars from it); nothing here prints. Verification re-checks every front
policy with Storm unless the search already used Storm, so every reported value is Storm's.
The run directory is written from the :class:`RunResult` by :mod:`parley_core.rundir.write`.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np
from attrs import field, frozen

from parley_core import metrics, robust
from parley_core.constraints import Constraint, meets
from parley_core.errors import OptionError, ParleyDefect, SearchError
from parley_core.evaluate import Evaluator, EvaluatorKind, evaluate_policies, make_evaluator
from parley_core.evaluate.cache import CachingEvaluator
from parley_core.family.prepare import Prepared
from parley_core.family.scenarios import ScenarioModel
from parley_core.model import Direction, Family, Front, Policy, Valued
from parley_core.optimality import after_search as run_bounds
from parley_core.optimality.records import BoundMethod, Stopped
from parley_core.progress import NullReporter, Reporter, timed
from parley_core.search import SearchResult, SearchSettings, configuration, search
from parley_core.verify import Verification, VerifyPath, by_search, check_with_storm, not_checked

if TYPE_CHECKING:
    from parley_core.optimality.bound import Bound
    from parley_core.optimality.branch_and_bound import ExactResult
    from parley_core.optimality.requirement import Answer, Requirement


@frozen(kw_only=True)
class RunResult:
    prepared: Prepared
    settings: SearchSettings
    evaluator: EvaluatorKind
    workers: int
    baseline: Valued
    front: Front
    search: SearchResult
    verification: Verification
    reference: tuple[float, ...]
    selected: int
    timings: dict[str, float]
    evaluator_info: dict[str, Any] = field(factory=dict)
    bound: Bound | None = None
    """A certified outer bound of the family (None: not asked for, or not available)."""
    baseline_scenarios: np.ndarray | None = field(default=None, eq=False)
    """A robust run's values of each baseline in each scenario [baselines, scenarios, objectives]
    (Storm's, as ``baseline``'s); ``baseline`` holds their worst case."""
    front_scenarios: np.ndarray | None = field(default=None, eq=False)
    """The same for the front's policies, in the front's order."""
    warm_start: int = 0
    """Policies of an earlier front the search started from (0: a cold start)."""

    @property
    def scenarios(self) -> tuple[ScenarioModel, ...]:
        return self.prepared.scenarios

    @property
    def family(self) -> Family:
        return self.prepared.family


def run(
    prepared: Prepared,
    settings: SearchSettings,
    *,
    evaluator: EvaluatorKind | str = EvaluatorKind.QUOTIENT,
    workers: int | None = None,
    reporter: Reporter | None = None,
    verify: bool = True,
    bound: BoundMethod | str = BoundMethod.PARETO,
    bound_time: float | None = None,
    verify_with: str | VerifyPath = VerifyPath.BATCH,
    warm: Sequence[Policy] = (),
) -> RunResult:
    """Baselines, search, verification, bound; returns everything the report needs.

    ``bound``: "pareto" (default) an outer approximation of the Pareto curve of the
    quotient's relaxation, "ideal" its ideal point, "belief" the outer approximation on the
    ideal point of the relaxation read as a POMDP (:mod:`parley_core.optimality.belief`): certified outer bounds of the family
    (:mod:`parley_core.optimality.bound`); "refine" runs branch
    and bound over the decisions' ranges after the search (:mod:`parley_core.optimality.branch_and_bound`) for at
    most ``bound_time`` seconds (None: until the front is proven exact), whose policies join
    the front and whose open sub-families make the bound; "none" skips it. With "belief",
    ``bound_time`` limits Storm's belief exploration per objective (None:
    :data:`parley_core.optimality.belief.SECONDS`).

    ``warm``: policies (an earlier front, say for other numbers of the model) the search
    starts from besides the baselines (a warm start, :func:`parley_core.search.run.initial_population`).

    ``verify_with``: how Storm re-checks the front (:class:`parley_core.verify.VerifyPath`).
    ``verify=False`` skips re-checking the front with Storm when another evaluator searched
    (campaigns may choose it for time); the result then says so (``verification.by``).
    """
    steps = _Steps(
        prepared,
        settings,
        kind=EvaluatorKind.of(evaluator),
        workers=workers,
        reporter=reporter or NullReporter(),
        bound=BoundMethod.of(bound),
        bound_time=bound_time,
        warm=warm,
    )
    engine = steps.evaluator()
    try:
        searched = steps.search(engine)
    except BaseException:
        engine.close(abort=True)
        raise
    engine.close()
    candidates, values = steps.candidates(searched)
    checked = steps.verify(engine, searched.baseline, candidates, values, verify, verify_with)
    return _result(steps, engine, searched, checked, steps.certified_bound(engine, searched))


def _result(steps: _Steps, engine: Evaluator, searched: _Searched, checked: _Checked, found: Bound | None) -> RunResult:
    """The run's result from its verified candidates: the front Storm's values decide, its
    reference point and knee."""
    prepared, settings = steps.prepared, steps.settings
    front, baseline_each, front_each = steps.front(checked)
    objectives = prepared.family.objectives
    reference = metrics.reference_point(objectives, np.array(front.values), np.array(checked.baseline.values))
    return RunResult(
        prepared=prepared,
        settings=settings,
        evaluator=steps.kind,
        workers=engine.workers,
        evaluator_info=engine.describe(),
        baseline=checked.baseline,
        front=front,
        search=searched.result,
        verification=checked.verification,
        reference=tuple(float(r) for r in reference),
        selected=metrics.knee(np.array(front.values), [o.direction for o in objectives]),
        timings=steps.timings,
        bound=found,
        baseline_scenarios=baseline_each,
        front_scenarios=front_each,
        warm_start=len(steps.warm),
    )


@frozen(kw_only=True)
class _Searched:
    """What the search (and branch and bound, with ``--bound refine``) found."""

    baseline: Valued
    """The baselines, the search evaluator's values."""
    result: SearchResult
    values: np.ndarray = field(eq=False)
    """The search's values as branch and bound saw them (the search's own without it)."""
    refined: ExactResult | None = None
    outer: Bound | None = None
    """The cheap bound branch and bound started from."""


@frozen(kw_only=True)
class _Checked:
    """The baselines and the front's candidates with the values Storm gave them."""

    baseline: Valued
    candidates: np.ndarray = field(eq=False)
    values: np.ndarray = field(eq=False)
    verification: Verification
    each: np.ndarray | None = field(default=None, eq=False)
    """A robust run's values per scenario [baselines + candidates, scenarios, objectives]."""


class _Steps:
    """The steps of one run, in order: :meth:`evaluator`, :meth:`search`, :meth:`candidates`,
    :meth:`verify`, :meth:`front`, :meth:`certified_bound`. Each is timed into ``timings``."""

    def __init__(
        self,
        prepared: Prepared,
        settings: SearchSettings,
        *,
        kind: EvaluatorKind,
        workers: int | None,
        reporter: Reporter,
        bound: BoundMethod,
        bound_time: float | None,
        warm: Sequence[Policy],
    ) -> None:
        self.prepared = prepared
        self.family = family = prepared.family
        if not family.objectives:
            raise OptionError("the model has no objectives to optimize; give a properties file")
        self.scenarios = prepared.scenarios
        if self.scenarios and bound is BoundMethod.REFINE:
            raise OptionError(
                "--bound refine does not take --scenarios yet (branch and bound works on one model); "
                "use --bound pareto or ideal"
            )
        for policy in warm:
            family.check(policy)
        self.settings, self.kind, self.workers, self.reporter = settings, kind, workers, reporter
        self.bound, self.bound_time, self.warm = bound, bound_time, warm
        self.timings = dict(prepared.timings)
        self.names = [o.name for o in family.objectives]
        self.directions = [o.direction for o in family.objectives]

    def evaluator(self) -> Evaluator:
        self.reporter.stage(f"{self.kind.value} evaluator")
        with timed(self.timings, "evaluator"):
            if self.scenarios:
                return robust.make_evaluator(self.scenarios, self.kind, self.workers, self.reporter)
            return make_evaluator(self.family, self.kind, self.workers)

    def search(self, engine: Evaluator) -> _Searched:
        """The baselines, then the search from them (and the warm start), then branch and
        bound if asked; every policy evaluated once, through one archive."""
        family, reporter, settings = self.family, self.reporter, self.settings
        archive = CachingEvaluator(engine, len(family.decisions), len(family.objectives))
        with timed(self.timings, "baselines"):
            baseline = evaluate_policies(family, family.baseline_policies(), archive, reporter, stage="baselines")
        # a polished search advances by generations, then by polishing rounds: no known total
        reporter.stage("search", None if configuration(settings.algorithm).polish else settings.generations)
        with timed(self.timings, "search"):
            starts = np.array([p.values for p in self.warm], dtype=np.int64).reshape(-1, len(family.decisions))
            result = search(family, engine, settings, archive=archive, progress=reporter.advance, warm=starts)
        if result.interrupted:
            reporter.note(
                f"search interrupted after {result.generations} generations; writing the front of what was evaluated"
            )
        if self.bound is not BoundMethod.REFINE or result.interrupted:
            return _Searched(baseline=baseline, result=result, values=result.values)
        with timed(self.timings, "bound"):
            cheap = run_bounds.outer(family, engine, BoundMethod.PARETO)
            refined, values = run_bounds.refine(family, engine, result, self.bound_time, reporter, cheap)
        if refined.stopped_by is Stopped.INTERRUPTED:
            reporter.note("branch and bound interrupted; writing the front and the bound so far")
        return _Searched(baseline=baseline, result=result, values=values, refined=refined, outer=cheap[0])

    def search_on(self, engine: Evaluator, searched: _Searched, requirement: Requirement, seconds: float) -> _Searched:
        """A check's search once more, for ``seconds``, if nothing it evaluated meets the
        requirement: started from the population closest to the box (the least shortfall
        below its corner, scaled by the levels), with the next seed; both searches' policies."""
        done = searched.result
        signs = np.array([1.0 if d is Direction.MAX else -1.0 for d in self.directions])
        if seconds < 1.0 or done.interrupted or requirement.met(done.values, signs).any():
            return searched
        corner = requirement.corner
        scale = np.where(requirement.constrained, np.maximum(1.0, np.abs(corner)), np.inf)
        with np.errstate(invalid="ignore", over="ignore"):
            short = np.nan_to_num(np.maximum(corner - done.values * signs, 0.0) / scale, nan=np.inf).sum(axis=1)
        closest = done.policies[np.argsort(short, kind="stable")[: self.settings.population]]
        settings = attrs.evolve(self.settings, generations=None, time_limit=seconds, seed=self.settings.seed + 1)
        archive = CachingEvaluator(engine, len(self.family.decisions), len(self.family.objectives))
        self.reporter.stage("search (closer to the box)", None)
        with timed(self.timings, "search"):
            more = search(self.family, engine, settings, archive=archive, progress=self.reporter.advance, warm=closest)
        merged = attrs.evolve(
            done,
            policies=np.vstack([done.policies, more.policies]),
            values=np.vstack([done.values, more.values]),
            evaluations=done.evaluations + more.evaluations,
            generations=done.generations + more.generations,
            seconds=done.seconds + more.seconds,
            stopped_by=more.stopped_by,
        )
        return attrs.evolve(searched, result=merged, values=merged.values)

    def candidates(self, searched: _Searched) -> tuple[np.ndarray, np.ndarray]:
        """The evaluated policies that meet the constraints and no other evaluated one
        dominates, with their values."""
        # the search's values as branch and bound saw them: one solver's values on both sides of
        # the merge, so that two policies tied to rounding do not both look nondominated
        policies, values = searched.result.policies, searched.values
        if searched.refined is not None and len(searched.refined.values):
            policies = np.vstack([policies, searched.refined.policies])
            values = np.vstack([values, searched.refined.values])
        constraints = self.settings.constraints
        feasible = meets(values, self.names, constraints)
        if not feasible.any():
            objectives = self.family.objectives
            best = ", ".join(f"{o.name} {_best(values[:, i], o):.4g}" for i, o in enumerate(objectives))
            raise SearchError(
                f"no evaluated policy meets {' and '.join(map(str, constraints))} (best values seen: {best}); "
                "relax the constraints or search longer"
            )
        feasible &= metrics.front_candidates(values)
        if not feasible.any():
            raise SearchError("every evaluated policy has a NaN objective value; check the objectives' formulas")
        mask = metrics.tolerant_front(values[feasible], self.directions)
        return policies[feasible][mask], values[feasible][mask]

    def verify(
        self,
        engine: Evaluator,
        baseline: Valued,
        candidates: np.ndarray,
        values: np.ndarray,
        verify: bool,
        verify_with: str | VerifyPath,
    ) -> _Checked:
        """Storm's values of the baselines and the candidates (every value a run reports is
        Storm's), in every scenario of a robust run."""
        family = self.family
        base_rows = np.array([p.values for p in baseline.policies], dtype=np.int64).reshape(-1, len(family.decisions))
        rows = np.vstack([base_rows, candidates])
        searched = np.vstack([np.array(baseline.values).reshape(-1, len(self.names)), values])
        each = None
        worst_case = engine if isinstance(engine, robust.WorstCaseEvaluator) else None
        with timed(self.timings, "verify"):
            if self.kind is EvaluatorKind.STORM:
                verification, checked = by_search(), searched
            elif not verify:
                verification, checked = not_checked(), searched
            else:
                labels = [f"baseline {p.name}" for p in baseline.policies] + [None] * len(candidates)
                if worst_case is not None:
                    verification, checked, each = robust.check_scenarios(
                        self.scenarios,
                        worst_case,
                        rows,
                        self.workers,
                        self.reporter,
                        labels,
                        len(base_rows),
                        verify_with,
                    )
                else:
                    verification, checked = check_with_storm(
                        family, rows, searched, self.workers, self.reporter, labels, len(base_rows), verify_with
                    )
            if worst_case is not None and each is None:
                each = worst_case.scenario_values(rows)
        return _Checked(
            baseline=Valued(objectives=family.objectives, policies=baseline.policies, values=checked[: len(base_rows)]),
            candidates=candidates,
            values=checked[len(base_rows) :],
            verification=verification,
            each=each,
        )

    def front(self, checked: _Checked) -> tuple[Front, np.ndarray | None, np.ndarray | None]:
        """The front Storm's values decide (anything they show to be dominated or infeasible
        dropped), in lexicographic order of the values, and a robust run's values per scenario
        of the baselines and of the front."""
        values = checked.values
        keep = (
            metrics.tolerant_front(values, self.directions)
            & meets(values, self.names, self.settings.constraints)
            & metrics.front_candidates(values)
        )
        candidates, values = checked.candidates[keep], values[keep]
        order = np.lexsort(tuple(values[:, i] for i in reversed(range(values.shape[1]))))
        baseline_each = front_each = None
        if checked.each is not None:
            bases = len(checked.baseline.policies)
            baseline_each, front_each = checked.each[:bases], checked.each[bases:][keep][order]
        width = len(str(len(order)))
        front = Front(
            objectives=self.family.objectives,
            policies=[Policy(name=f"p{i + 1:0{width}d}", values=candidates[j]) for i, j in enumerate(order)],
            values=values[order],
        )
        return front, baseline_each, front_each

    def certified_bound(self, engine: Evaluator, searched: _Searched) -> Bound | None:
        """Branch and bound's bound (within the cheap one it started from), else the cheap
        bound asked for (in a robust run, every scenario's intersected)."""
        if searched.refined is not None and searched.outer is not None:
            from parley_core.optimality.bound import intersect, refined_bound

            found = refined_bound(self.family, searched.refined)
            if found.exact:
                return found
            return intersect(searched.outer, found, found.method + ", within the Pareto outer approximation")
        if self.bound is BoundMethod.NONE or self.bound is BoundMethod.REFINE:  # refine: the search was interrupted
            return None
        with timed(self.timings, "bound"):
            self.reporter.stage("bound")
            if self.scenarios:
                assert isinstance(engine, robust.WorstCaseEvaluator)
                outer = functools.partial(run_bounds.outer, seconds=self.bound_time)
                return robust.bound(self.scenarios, engine, self.bound, outer)
            return run_bounds.outer(self.family, engine, self.bound, self.bound_time)[0]


def _best(column: np.ndarray, objective) -> float:
    return float(column.max() if objective.direction is objective.direction.MAX else column.min())


@frozen(kw_only=True)
class CheckResult:
    """A requirement's answer (:func:`check`): branch and bound's :class:`~parley_core.optimality.requirement.Answer`
    and, where it is feasible, the run of the policies inside the box, their values Storm's."""

    prepared: Prepared
    answer: Answer
    run: RunResult | None
    timings: dict[str, float]

    @property
    def family(self) -> Family:
        return self.prepared.family


SEARCH_SHARE = 0.25
"""Of a check's time limit, what the search before branch and bound may take at most."""
INSIDE = 16
"""A feasible check verifies and writes at most this many of the policies found inside the box,
evenly spaced along their front (map_10's default search finds about 1,100 inside success >= 0.8,
cost <= 60)."""


def check(
    prepared: Prepared,
    settings: SearchSettings,
    requirements: Sequence[Constraint],
    *,
    time_limit: float | None = None,
    workers: int | None = None,
    reporter: Reporter | None = None,
    verify_with: str | VerifyPath = VerifyPath.BATCH,
) -> CheckResult:
    """Is there a policy of the family inside the box ``requirements`` make? The baselines and
    a search that prefers policies meeting them (at most :data:`SEARCH_SHARE` of
    ``time_limit``), then branch and bound driven by the box
    (:mod:`parley_core.optimality.requirement`) for the time left, started from what the
    search found. Feasible: the policies found inside the box are verified by Storm and make
    the run; infeasible: the answer holds the certificate; unknown: the share of the family
    left open."""
    from parley_core.optimality.requirement import Requirement, Verdict

    reporter = reporter or NullReporter()
    requirement = Requirement.of(prepared.family, requirements)
    if prepared.scenarios:
        raise OptionError("parley check does not take --scenarios yet (branch and bound works on one model)")
    began = time.perf_counter()
    if time_limit is not None:
        share = SEARCH_SHARE * time_limit
        settings = attrs.evolve(settings, time_limit=min(settings.time_limit or share, share))
    # the search and the front keep what meets the box to the tolerance, as branch and bound does
    settings = attrs.evolve(settings, constraints=requirement.relaxed())
    steps = _Steps(
        prepared, settings, kind=EvaluatorKind.QUOTIENT, workers=workers, reporter=reporter,
        bound=BoundMethod.NONE, bound_time=None, warm=(),
    )  # fmt: skip
    engine = steps.evaluator()
    try:
        searched = steps.search(engine)
        if time_limit is not None:  # nothing inside yet: the rest of the search's share, from the closest
            searched = steps.search_on(
                engine, searched, requirement, SEARCH_SHARE * time_limit - (time.perf_counter() - began)
            )
        left = None if time_limit is None else max(0.0, time_limit - (time.perf_counter() - began))
        if searched.result.interrupted:  # Ctrl-C in the search: the answer so far, unknown unless found
            left = 0.0
        with timed(steps.timings, "bound"):
            found = run_bounds.answer(prepared.family, engine, requirement, searched.result, left, reporter)
    except BaseException:
        engine.close(abort=True)
        raise
    engine.close()
    if found.verdict is not Verdict.FEASIBLE:
        return CheckResult(prepared=prepared, answer=found, run=None, timings=steps.timings)
    searched = attrs.evolve(searched, refined=found.result)
    candidates, values = steps.candidates(searched)
    if len(candidates) > INSIDE:  # a few policies across the box's part of the front, not all of it
        order = np.lexsort(tuple(values[:, i] for i in reversed(range(values.shape[1]))))
        chosen = order[np.unique(np.linspace(0, len(order) - 1, INSIDE).round().astype(int))]
        candidates, values = candidates[chosen], values[chosen]
    checked = steps.verify(engine, searched.baseline, candidates, values, True, verify_with)
    if not meets(checked.values, steps.names, settings.constraints).any():
        raise ParleyDefect(
            f"the quotient evaluator found policies inside {requirement}, and Storm's values put none of them "
            "there; please report it with the command"
        )
    result = _result(steps, engine, searched, checked, None)
    return CheckResult(prepared=prepared, answer=found, run=result, timings=steps.timings)
