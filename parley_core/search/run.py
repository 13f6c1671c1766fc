"""Running a search: the first population, the loop, Ctrl-C, the result."""

from __future__ import annotations

import sys
import time

import attrs
import numpy as np
from pymoo.core.termination import TerminateIfAny

from parley_core.evaluate import Evaluator, QuotientBacked
from parley_core.evaluate.cache import CachingEvaluator
from parley_core.model import Family
from parley_core.progress import Progress
from parley_core.search.algorithms import configuration
from parley_core.search.guide import guided_start
from parley_core.search.polish import Polished, polish, unavailable
from parley_core.search.problem import Genes, PolicyProblem, termination
from parley_core.search.settings import SearchResult, SearchSettings, Stop


def initial_population(
    family: Family, settings: SearchSettings, blend: float = 0.0, warm: np.ndarray | None = None
) -> np.ndarray:
    """The baselines, then policies drawn from the seed up to the population size, as genes
    (:class:`Genes`): uniformly random ones, and with ``blend`` (a share of the draws) blends
    of two baselines (each decision from either), which lie between points the baseline
    already reaches. ``warm``: policies of an earlier front to start from (a warm start):
    they come after the baselines, evenly spaced along their order if there are more than
    the population has room for, and the random draws fill the rest."""
    rng = np.random.default_rng(settings.seed)
    genes = Genes(family)
    baselines = genes.encode(
        np.array([p.values for p in family.baseline_policies()], dtype=np.int64).reshape(-1, len(genes.lows))
    )
    if warm is not None and len(warm):
        room = max(0, settings.population - len(baselines))
        warm = np.asarray(warm, dtype=np.int64).reshape(-1, len(genes.lows))
        if len(warm) > room:
            warm = warm[np.unique(np.linspace(0, len(warm) - 1, room).round().astype(np.int64))]
        baselines = np.vstack([baselines, genes.encode(warm)])
    lows, highs = genes.lows, genes.highs
    n_random = max(0, settings.population - len(baselines))
    rows = rng.integers(lows, highs + 1, size=(n_random, len(lows)))
    if blend > 0 and len(baselines) >= 2:
        blended = np.flatnonzero(rng.random(n_random) < blend)
        pairs = baselines[rng.integers(0, len(baselines), size=(len(blended), 2))]
        pick = rng.random((len(blended), len(lows))) < 0.5
        rows[blended] = np.where(pick, pairs[:, 0], pairs[:, 1])
    return np.vstack([baselines, rows]).astype(float)


def search(
    family: Family,
    evaluator: Evaluator,
    settings: SearchSettings,
    *,
    archive: CachingEvaluator | None = None,
    progress: Progress | None = None,
    warm: np.ndarray | None = None,
) -> SearchResult:
    """Run the settings' search configuration; Ctrl-C stops it and returns what was
    evaluated so far (``interrupted``).

    ``archive`` may hold policies evaluated before (by the same evaluator); they are not
    evaluated again, count towards ``max_evaluations`` and belong to the result.
    ``progress`` is called once per generation. ``warm``: policies to start from besides
    the baselines (:func:`initial_population`).
    """
    archive = (
        archive if archive is not None else CachingEvaluator(evaluator, len(family.decisions), len(family.objectives))
    )
    chosen = configuration(settings.algorithm)
    total = _budget(settings)
    limit = settings.time_limit
    began = time.perf_counter()
    from parley_core.quotient.improve import improver_for  # the compiled kernels load only when a search uses them

    # one improver serves the walks and the polishing (building it reads the whole relaxation)
    # its scores on as many threads as the evaluator has workers: they wait while the walks and
    # the polishing compute scores (a campaign's one-worker runs stay on one core each)
    threads = max(1, evaluator.workers)
    quotient = evaluator.quotient if isinstance(evaluator, QuotientBacked) else None
    improver = improver_for(family, quotient, threads) if chosen.guided or chosen.polish else ""
    polished = None
    if chosen.polish:
        reason = unavailable(family, improver, constrained=bool(settings.constraints))
        if reason:
            polished = Polished(evaluations=0, expanded=0, seconds=0.0, skipped=reason)
    polishing = chosen.polish if polished is None else 0.0
    if polishing:  # the pymoo search gets its share, polishing the rest
        if total is not None:
            settings = attrs.evolve(settings, generations=None, max_evaluations=max(1, round((1 - polishing) * total)))
        if limit is not None:
            settings = attrs.evolve(settings, time_limit=(1 - polishing) * limit)
    walked = None
    if chosen.guided:  # the walks' policies are in the archive (whose front a mating may draw on)
        walked = guided_start(family, archive, improver, settings.max_evaluations, seconds=settings.time_limit)
        if chosen.guided == "population" and len(walked.policies):
            warm = walked.policies if warm is None or not len(warm) else np.vstack([warm, walked.policies])
    if settings.time_limit is not None:  # the improver's and the walks' time count against the limit
        settings = attrs.evolve(settings, time_limit=max(1e-3, settings.time_limit - (time.perf_counter() - began)))
    problem = PolicyProblem(family, archive, constraints=settings.constraints, budget=settings.max_evaluations)
    algorithm = chosen.build(settings.population, initial_population(family, settings, blend=chosen.blend, warm=warm))
    criteria = termination(settings, archive)
    algorithm.setup(problem, termination=TerminateIfAny(*criteria.values()), seed=settings.seed, verbose=False)
    generation = 0
    stopped_by = None
    try:
        while algorithm.has_next():
            algorithm.next()
            generation += 1
            if progress:
                progress(1)
        if polishing:
            assert not isinstance(improver, str)  # unavailable() said so
            left = None if limit is None else max(0.0, limit - (time.perf_counter() - began))
            budget = total if total is not None else sys.maxsize
            polished = polish(family, archive, improver, budget, settings.seed, seconds=left, progress=progress)
    except KeyboardInterrupt:
        stopped_by = Stop.INTERRUPTED
    finally:
        if not isinstance(improver, str):
            improver.close()  # its threads
    if stopped_by is None and polished is not None and not polished.skipped:
        stopped_by = _polish_stop(polished, archive, total, limit, time.perf_counter() - began)
    if stopped_by is None:
        stopped_by = next((stop for stop, c in criteria.items() if c.has_terminated()), Stop.GENERATIONS)
    return SearchResult(
        policies=archive.policies,
        values=archive.values,
        evaluations=len(archive),
        generations=generation,
        seconds=time.perf_counter() - began,
        stopped_by=stopped_by,
        walked=walked,
        polished=polished,
    )


def _budget(settings: SearchSettings) -> int | None:
    """The evaluations a search may spend: the budget, or what the generations would
    evaluate (None: only a time limit)."""
    generations = None if settings.generations is None else settings.population * settings.generations
    budgets = [b for b in (settings.max_evaluations, generations) if b is not None]
    return min(budgets) if budgets else None


def _polish_stop(polished: Polished, archive: CachingEvaluator, total: int | None, limit, seconds: float) -> Stop:
    if total is not None and len(archive) >= total:
        return Stop.EVALUATIONS
    if limit is not None and seconds >= limit:
        return Stop.TIME
    return Stop.EXHAUSTED
