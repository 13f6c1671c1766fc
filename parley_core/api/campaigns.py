"""``parley experiment run`` as a function: :func:`experiment` runs (or resumes) a campaign
into a SQLite store and returns its :class:`Campaign` outcome."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from attrs import field, frozen

from parley_core.api.commands import DEFAULT_POPULATION, assignments_of, reporting, search_settings
from parley_core.evaluate import EvaluatorKind
from parley_core.progress import Reporter


@frozen(kw_only=True)
class Campaign:
    """What one call of :func:`experiment` did."""

    store: Path
    name: str
    planned: int
    skipped: int
    """Runs the store already held (a resumed campaign)."""
    stored: int
    failures: tuple[tuple[str, int, str], ...] = field(converter=lambda rows: tuple(tuple(r) for r in rows))
    """(instance, repetition, error) of each failed run; rerunning retries them."""


def experiment(
    case: str,
    *,
    store: str | Path,
    reps: int = 10,
    grid: Sequence[str] = (),
    instances: str | None = None,
    instance_option: str | None = None,
    options: Mapping[str, Any] | None = None,
    name: str | None = None,
    algorithm: str | None = None,
    population: int = DEFAULT_POPULATION,
    generations: int | None = None,
    max_evaluations: int | None = None,
    time_limit: float | None = None,
    first_seed: int = 1,
    evaluator: str = EvaluatorKind.QUOTIENT.value,
    verify: bool = True,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool | Reporter = True,
) -> Campaign:
    """Run a campaign: ``reps`` repetitions of every instance (``grid``: ``KEY=V1,V2`` products;
    ``instances``: a directory or glob of files), stored in ``store`` as each finishes; calling
    it again resumes, skipping finished runs."""
    from parley_core.experiment.campaign import Budget, describe, execute, instances_from, plan
    from parley_core.experiment.store import Store
    from parley_core.plugins import load_registry

    study = load_registry().get(case)
    fixed = assignments_of(options or {})
    limits = search_settings(
        population=population,
        generations=generations,
        max_evaluations=max_evaluations,
        time_limit=time_limit,
        seed=first_seed,
        algorithm=algorithm,
    )
    budget = Budget(
        algorithm=limits.algorithm,
        population=limits.population,
        generations=limits.generations,
        max_evaluations=limits.max_evaluations,
        time_limit=limits.time_limit,
        evaluator=evaluator,
        verify=verify,
    )
    chosen = instances_from(study, list(grid), instances, instance_option)
    campaign = name or study.name
    specs = plan(campaign, study, chosen, fixed, reps, budget, first_seed)
    with Store(Path(store)) as results, reporting(progress) as reporter:
        results.begin_campaign(campaign, study.name, {**describe(budget, fixed), "first_seed": first_seed})
        already = len(results.done(campaign) & {(s.instance, s.repetition) for s in specs})
        reporter.stage(f"campaign {campaign}", len(specs))
        reporter.advance(already)
        outcome = execute(specs, results, workers=workers, scheduler=scheduler, progress=reporter.advance)
    return Campaign(
        store=Path(store),
        name=campaign,
        planned=outcome.planned,
        skipped=outcome.skipped,
        stored=outcome.stored,
        failures=outcome.failures,
    )
