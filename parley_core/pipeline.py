"""A run, stage by stage: build -> (prune) -> augment -> baselines -> search -> verify.

Each stage is timed and announced to a :class:`~parley_core.progress.Reporter` (the CLI
draws progress bars from it); nothing here prints. Verification re-checks every front
policy with Storm unless the search already used Storm, so every reported value is Storm's.
The run directory is written from the :class:`RunResult` by :mod:`parley_core.rundir.write`.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

import numpy as np
from attrs import field, frozen

from parley_core import metrics, robust
from parley_core.constraints import meets
from parley_core.errors import OptionError, SearchError
from parley_core.evaluate import Evaluator, EvaluatorKind, make_evaluator
from parley_core.evaluate.cache import CachingEvaluator
from parley_core.family.augment import augment
from parley_core.family.scenarios import ScenarioSet
from parley_core.model import Family, Front, Policy, SystemModel, Valued
from parley_core.optimality import after_search as run_bounds
from parley_core.plugin.casestudy import CaseStudy
from parley_core.progress import NullReporter, Reporter
from parley_core.robust import ScenarioModel
from parley_core.search import SearchResult, SearchSettings, configuration, search
from parley_core.verify import Verification, VerifyPath, by_search, check_with_storm, not_checked

if TYPE_CHECKING:
    from parley_core.optimality.bound import Bound


@frozen(kw_only=True)
class Prepared:
    case: CaseStudy
    options: Any
    system: SystemModel
    family: Family
    timings: dict[str, float] = field(factory=dict)
    scenarios: tuple[ScenarioModel, ...] = ()
    """A robust run's scenarios (:mod:`parley_core.robust`); ``options``, ``system`` and
    ``family`` are then the first scenario's. Empty: an ordinary run."""


@contextmanager
def _timed(timings: dict[str, float], name: str) -> Iterator[None]:
    start = time.perf_counter()
    try:
        yield
    finally:
        timings[name] = timings.get(name, 0.0) + time.perf_counter() - start


def make_family(system: SystemModel, *, prune: bool = False) -> Family:
    """Augment ``system``; with ``prune``, only at the observation valuations where some
    reachable state of some policy consults a service (found on the quotient MDP)."""
    from parley_core.prism.properties import name_unnamed_rewards

    system = name_unnamed_rewards(system)
    family = augment(system)  # also checks the model before Storm builds its quotient
    if prune:
        from parley_core.quotient.mdp import build_mdp, consulted_valuations

        kept = consulted_valuations(build_mdp(system))
        if len(kept) < len(family.valuations):
            family = augment(system, valuations=kept)
    return family


def prepare(case: CaseStudy, options: Any, reporter: Reporter | None = None) -> Prepared:
    """Build the case study's system model and augment it (pruned if the case study asks)."""
    reporter = reporter or NullReporter()
    timings: dict[str, float] = {}
    system, family = _build(case, options, reporter, timings)
    if family.left_out:
        reporter.note(f"{len(family.left_out)} observation valuations never consult a service and are left out")
    for note in family.system.notes if family.system else ():
        reporter.note(note)
    return Prepared(case=case, options=options, system=system, family=family, timings=timings)


def prepare_scenarios(
    case: CaseStudy, assignments: dict[str, str], scenarios: ScenarioSet, reporter: Reporter | None = None
) -> Prepared:
    """A robust run's models: the case study built and augmented once per scenario (each
    scenario's option values over ``assignments``, the run's ``--set``)."""
    reporter = reporter or NullReporter()
    timings: dict[str, float] = {}
    models = []
    for scenario, options in robust.scenario_options(case, assignments, scenarios):
        system, family = _build(case, options, reporter, timings, f" ({scenario.label})")
        models.append(ScenarioModel(scenario=scenario, options=options, system=system, family=family))
    first = models[0]
    if first.family.left_out:
        reporter.note(f"{len(first.family.left_out)} observation valuations never consult a service and are left out")
    return Prepared(
        case=case,
        options=first.options,
        system=first.system,
        family=first.family,
        timings=timings,
        scenarios=tuple(models),
    )


def _build(
    case: CaseStudy, options: Any, reporter: Reporter, timings: dict[str, float], label: str = ""
) -> tuple[SystemModel, Family]:
    """The case study's system model for ``options`` (the augmented one's, with named
    rewards) and its family."""
    with _timed(timings, "build"):
        if case.warm_up is not None:
            case.warm_up(options, reporter)
        reporter.stage("build model" + label)
        system = case.build(options)
    reporter.stage("augment" + label)
    with _timed(timings, "augment"):
        family = make_family(system, prune=case.prune)
    return family.system or system, family


def evaluate(
    family: Family,
    policies: Sequence[Policy],
    evaluator: Evaluator,
    reporter: Reporter | None = None,
    stage: str = "evaluate",
) -> Valued:
    """All ``policies`` with their values, in the given order."""
    reporter = reporter or NullReporter()
    for policy in policies:
        family.check(policy)
    reporter.stage(stage, len(policies))
    rows = np.array([p.values for p in policies], dtype=np.int64).reshape(-1, len(family.decisions))
    values = evaluator.evaluate(rows, progress=reporter.advance)
    return Valued(objectives=family.objectives, policies=policies, values=values)


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
    bound: str = "pareto",
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
    reporter = reporter or NullReporter()
    kind = EvaluatorKind.of(evaluator)
    family = prepared.family
    if not family.objectives:
        raise OptionError("the model has no objectives to optimize; give a properties file")
    scenarios = prepared.scenarios
    if scenarios and bound == "refine":
        raise OptionError(
            "--bound refine does not take --scenarios yet (branch and bound works on one model); "
            "use --bound pareto or ideal"
        )
    for policy in warm:
        family.check(policy)
    timings = dict(prepared.timings)
    directions = [o.direction for o in family.objectives]
    reporter.stage(f"{kind.value} evaluator")
    engine: Any
    with _timed(timings, "evaluator"):
        if scenarios:
            engine = robust.make_evaluator(scenarios, kind, workers, reporter)
        else:
            engine = make_evaluator(family, kind, workers)
    try:
        archive = CachingEvaluator(engine, len(family.decisions), len(family.objectives))
        with _timed(timings, "baselines"):
            baseline = evaluate(family, family.baseline_policies(), archive, reporter, stage="baselines")
        # a polished search advances by generations, then by polishing rounds: no known total
        reporter.stage("search", None if configuration(settings.algorithm).polish else settings.generations)
        with _timed(timings, "search"):
            starts = np.array([p.values for p in warm], dtype=np.int64).reshape(-1, len(family.decisions))
            result = search(family, engine, settings, archive=archive, progress=reporter.advance, warm=starts)
        if result.interrupted:
            reporter.note(
                f"search interrupted after {result.generations} generations; writing the front of what was evaluated"
            )
        refined = outer = None
        searched_values = result.values
        if bound == "refine" and not result.interrupted:
            with _timed(timings, "bound"):
                cheap = run_bounds.outer(family, engine, "pareto")
                outer = cheap[0]
                refined, searched_values = run_bounds.refine(family, engine, result, bound_time, reporter, cheap)
            if refined.stopped_by == "interrupted":
                reporter.note("branch and bound interrupted; writing the front and the bound so far")
    except BaseException:
        engine.close(abort=True)
        raise
    engine.close()

    names = [o.name for o in family.objectives]
    # the search's values as branch and bound saw them: one solver's values on both sides of
    # the merge, so that two policies tied to rounding do not both look nondominated
    found_policies, found_values = result.policies, searched_values
    if refined is not None and len(refined.values):
        found_policies = np.vstack([found_policies, refined.policies])
        found_values = np.vstack([found_values, refined.values])
    feasible = meets(found_values, names, settings.constraints)
    if not feasible.any():
        best = ", ".join(f"{o.name} {_best(found_values[:, i], o):.4g}" for i, o in enumerate(family.objectives))
        raise SearchError(
            f"no evaluated policy meets {' and '.join(map(str, settings.constraints))} (best values seen: {best}); "
            "relax the constraints or search longer"
        )
    feasible &= metrics.front_candidates(found_values)
    if not feasible.any():
        raise SearchError("every evaluated policy has a NaN objective value; check the objectives' formulas")
    mask = metrics.nondominated(found_values[feasible], directions)
    candidates = found_policies[feasible][mask]
    values = found_values[feasible][mask]
    # the baselines too: every value a run reports is Storm's
    base_rows = np.array([p.values for p in baseline.policies], dtype=np.int64).reshape(-1, len(family.decisions))
    rows = np.vstack([base_rows, candidates])
    searched = np.vstack([np.array(baseline.values).reshape(-1, len(names)), values])
    each = None
    with _timed(timings, "verify"):
        if kind is EvaluatorKind.STORM:
            verification, checked = by_search(), searched
        elif not verify:
            verification, checked = not_checked(), searched
        else:
            labels = [f"baseline {p.name}" for p in baseline.policies] + [None] * len(candidates)
            if scenarios:
                verification, checked, each = robust.check_scenarios(
                    scenarios, engine, rows, workers, reporter, labels, len(base_rows), verify_with
                )
            else:
                verification, checked = check_with_storm(
                    family, rows, searched, workers, reporter, labels, len(base_rows), verify_with
                )
        if scenarios and each is None:
            each = engine.scenario_values(rows)
        baseline = Valued(objectives=family.objectives, policies=baseline.policies, values=checked[: len(base_rows)])
        values = checked[len(base_rows) :]
    # Storm's values decide the front: drop anything they show to be dominated or infeasible.
    keep = (
        metrics.nondominated(values, directions)
        & meets(values, names, settings.constraints)
        & metrics.front_candidates(values)
    )
    candidates, values = candidates[keep], values[keep]
    order = np.lexsort(tuple(values[:, i] for i in reversed(range(values.shape[1]))))
    baseline_each = front_each = None
    if each is not None:
        baseline_each, front_each = each[: len(base_rows)], each[len(base_rows) :][keep][order]
    width = len(str(len(order)))
    front = Front(
        objectives=family.objectives,
        policies=[Policy(name=f"p{i + 1:0{width}d}", values=candidates[j]) for i, j in enumerate(order)],
        values=values[order],
    )
    found = None
    if refined is not None and outer is not None:
        from parley_core.optimality.bound import intersect, refined_bound

        found = refined_bound(family, refined)
        if not found.exact:
            found = intersect(outer, found, found.method + ", within the Pareto outer approximation")
    elif bound != "none":
        with _timed(timings, "bound"):
            reporter.stage("bound")
            found = (
                robust.bound(scenarios, engine, bound, functools.partial(run_bounds.outer, seconds=bound_time))
                if scenarios
                else run_bounds.outer(family, engine, bound, bound_time)[0]
            )
    reference = metrics.reference_point(family.objectives, np.array(front.values), np.array(baseline.values))
    describe = getattr(engine, "describe", None)
    return RunResult(
        prepared=prepared,
        settings=settings,
        evaluator=kind,
        workers=getattr(engine, "workers", 1),
        evaluator_info=describe() if describe else {},
        baseline=baseline,
        front=front,
        search=result,
        verification=verification,
        reference=tuple(float(r) for r in reference),
        selected=metrics.knee(np.array(front.values), directions),
        timings=timings,
        bound=found,
        baseline_scenarios=baseline_each,
        front_scenarios=front_each,
        warm_start=len(warm),
    )


def _best(column: np.ndarray, objective) -> float:
    return float(column.max() if objective.direction is objective.direction.MAX else column.min())
