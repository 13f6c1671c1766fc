"""A run, stage by stage: build -> augment -> baselines -> search -> verify -> (report).

Each stage is timed and announced to a :class:`Reporter` (the CLI draws progress bars from
it); nothing here prints. Verification re-checks every front policy with Storm unless the
search already used Storm, so every reported value is Storm's.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any, Protocol

import numpy as np
from attrs import field, frozen

from parley_core import metrics
from parley_core.augment import augment
from parley_core.casestudy import CaseStudy
from parley_core.errors import ModelError, OptionError
from parley_core.evaluate import Evaluator
from parley_core.evaluate.storm import StormEvaluator
from parley_core.model import Family, Front, Policy, SystemModel
from parley_core.search import Archive, SearchResult, SearchSettings, meets, search

EVALUATORS = ("quotient", "storm")


class Reporter(Protocol):
    def stage(self, name: str, total: int | None = None) -> None:
        """A stage starts; ``total`` units of work are expected (None: unknown)."""

    def advance(self, n: int = 1) -> None:
        """``n`` units of the current stage are done."""

    def note(self, text: str) -> None:
        """Something the user should know (a warning, an interruption)."""


class NullReporter:
    def stage(self, name: str, total: int | None = None) -> None:
        pass

    def advance(self, n: int = 1) -> None:
        pass

    def note(self, text: str) -> None:
        pass


@frozen(kw_only=True)
class Prepared:
    case: CaseStudy
    options: Any
    system: SystemModel
    family: Family
    timings: dict[str, float] = field(factory=dict)


@contextmanager
def _timed(timings: dict[str, float], name: str) -> Iterator[None]:
    start = time.perf_counter()
    try:
        yield
    finally:
        timings[name] = timings.get(name, 0.0) + time.perf_counter() - start


def prepare(case: CaseStudy, options: Any, reporter: Reporter | None = None) -> Prepared:
    """Build the case study's system model and augment it."""
    reporter = reporter or NullReporter()
    timings: dict[str, float] = {}
    reporter.stage("build model")
    with _timed(timings, "build"):
        system = case.build(options)
    reporter.stage("augment")
    with _timed(timings, "augment"):
        family = augment(system, prune=case.prune)
    if family.left_out:
        reporter.note(f"{len(family.left_out)} observation valuations never consult a service and are left out")
    return Prepared(case=case, options=options, system=system, family=family, timings=timings)


def make_evaluator(family: Family, kind: str = "quotient", workers: int | None = None) -> Evaluator:
    """The evaluator called ``kind``: "quotient" (fast, the default) or "storm" (the reference)."""
    if kind == "quotient":
        from parley_core.evaluate.quotient import QuotientEvaluator

        return QuotientEvaluator(family, workers=workers)
    if kind == "storm":
        return StormEvaluator(family, workers=workers)
    raise OptionError(f"unknown evaluator {kind!r}; valid: {', '.join(EVALUATORS)}")


def evaluate(
    family: Family,
    policies: Sequence[Policy],
    evaluator: Evaluator | Archive,
    reporter: Reporter | None = None,
    stage: str = "evaluate",
) -> Front:
    """All ``policies`` with their values, in the given order."""
    reporter = reporter or NullReporter()
    for policy in policies:
        family.check(policy)
    reporter.stage(stage, len(policies))
    rows = np.array([p.values for p in policies], dtype=np.int64).reshape(-1, len(family.decisions))
    values = evaluator.evaluate(rows, progress=reporter.advance)
    return Front(objectives=family.objectives, policies=policies, values=values)


@frozen(kw_only=True)
class Verification:
    by: str
    policies: int
    max_difference: float
    seconds: float


@frozen(kw_only=True)
class RunResult:
    prepared: Prepared
    settings: SearchSettings
    evaluator: str
    workers: int
    baseline: Front
    front: Front
    search: SearchResult
    verification: Verification
    reference: tuple[float, ...]
    selected: int
    timings: dict[str, float]
    evaluator_info: dict[str, Any] = field(factory=dict)

    @property
    def family(self) -> Family:
        return self.prepared.family

    def hypervolume(self, front: Front) -> float:
        return metrics.hypervolume(np.array(front.values), self._directions, self.reference)

    def spread(self, front: Front) -> float | None:
        """Deb's spread of the front's non-dominated points (None unless two objectives)."""
        if len(self._directions) != 2:
            return None
        values = np.array(front.values)
        return metrics.spread(values[metrics.nondominated(values, self._directions)], self._directions)

    @property
    def _directions(self):
        return [o.direction for o in self.family.objectives]


def run(
    prepared: Prepared,
    settings: SearchSettings,
    *,
    evaluator: str = "quotient",
    workers: int | None = None,
    reporter: Reporter | None = None,
    verify: bool = True,
) -> RunResult:
    """Baselines, search, verification; returns everything the report needs.

    ``verify=False`` skips re-checking the front with Storm when another evaluator searched
    (campaigns may choose it for time); the result then says so (``verification.by``).
    """
    reporter = reporter or NullReporter()
    family = prepared.family
    if not family.objectives:
        raise OptionError("the model has no objectives to optimise; give a properties file")
    timings = dict(prepared.timings)
    directions = [o.direction for o in family.objectives]
    reporter.stage(f"{evaluator} evaluator")
    with _timed(timings, "evaluator"):
        engine = make_evaluator(family, evaluator, workers)
    try:
        archive = Archive(engine, len(family.decisions), len(family.objectives))
        with _timed(timings, "baselines"):
            baseline = evaluate(family, family.baseline_policies(), archive, reporter, stage="baselines")
        reporter.stage("search", settings.generations)
        with _timed(timings, "search"):
            result = search(family, engine, settings, archive=archive, on_generation=lambda _p: reporter.advance(1))
        if result.interrupted:
            reporter.note(
                f"search interrupted after {result.generations} of {settings.generations} generations; "
                "writing the front of what was evaluated"
            )
    finally:
        engine.close()

    names = [o.name for o in family.objectives]
    feasible = meets(result.values, names, settings.constraints)
    if not feasible.any():
        best = ", ".join(f"{o.name} {_best(result.values[:, i], o):.4g}" for i, o in enumerate(family.objectives))
        raise ModelError(
            f"no evaluated policy meets {' and '.join(map(str, settings.constraints))} (best values seen: {best}); "
            "relax the constraints or search longer"
        )
    mask = metrics.nondominated(result.values[feasible], directions)
    candidates = result.policies[feasible][mask]
    values = result.values[feasible][mask]
    with _timed(timings, "verify"):
        verification, values = _verify(family, candidates, values, evaluator, workers, reporter, verify)
    # Storm's values decide the front: drop anything they show to be dominated or infeasible.
    keep = metrics.nondominated(values, directions) & meets(values, names, settings.constraints)
    candidates, values = candidates[keep], values[keep]
    order = np.lexsort(tuple(values[:, i] for i in reversed(range(values.shape[1]))))
    width = len(str(len(order)))
    front = Front(
        objectives=family.objectives,
        policies=[Policy(name=f"p{i + 1:0{width}d}", values=candidates[j]) for i, j in enumerate(order)],
        values=values[order],
    )
    reference = metrics.reference_point(family.objectives, np.array(front.values), np.array(baseline.values))
    return RunResult(
        prepared=prepared,
        settings=settings,
        evaluator=evaluator,
        workers=getattr(engine, "workers", 1),
        evaluator_info=_describe(engine),
        baseline=baseline,
        front=front,
        search=result,
        verification=verification,
        reference=tuple(float(r) for r in reference),
        selected=metrics.knee(np.array(front.values), directions),
        timings=timings,
    )


def _verify(family, policies, values, evaluator, workers, reporter, verify=True) -> tuple[Verification, np.ndarray]:
    if evaluator == "storm":
        return Verification(by="storm (the search's own evaluator)", policies=len(policies), max_difference=0.0, seconds=0.0), values
    if not verify:
        return Verification(by="none (values of the quotient evaluator)", policies=0, max_difference=float("nan"), seconds=0.0), values
    return check_with_storm(family, policies, values, workers, reporter)


def check_with_storm(
    family: Family, policies: np.ndarray, values: np.ndarray, workers: int | None = None, reporter: Reporter | None = None
) -> tuple[Verification, np.ndarray]:
    """Storm's values of ``policies``, and how far they are from ``values`` (the search's)."""
    reporter = reporter or NullReporter()
    start = time.perf_counter()
    with StormEvaluator(family, workers=workers) as storm:
        reporter.stage("verify with Storm", len(policies))
        checked = storm.evaluate(policies, progress=reporter.advance)
    difference = float(np.abs(checked - values).max()) if len(values) else 0.0
    return Verification(by="storm", policies=len(policies), max_difference=difference, seconds=time.perf_counter() - start), checked



def _best(column: np.ndarray, objective) -> float:
    return float(column.max() if objective.direction.value == "max" else column.min())


def _describe(engine: Evaluator) -> dict[str, Any]:
    quotient = getattr(engine, "quotient", None)
    if quotient is None:
        return {}
    return {
        "quotient_states": quotient.states,
        "quotient_choices": quotient.choices,
        "quotient_transitions": quotient.branches,
        "objectives_checked_by_storm": list(getattr(engine, "fallback", ())),
    }
