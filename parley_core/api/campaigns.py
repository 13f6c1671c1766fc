"""``parley experiment run`` as a function: :func:`experiment` runs (or resumes) a campaign
into a SQLite store and returns its :class:`Campaign` outcome."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from attrs import field, frozen

from parley_core.api.commands import DEFAULT_POPULATION, assignments_of, search_settings
from parley_core.evaluate import EvaluatorKind
from parley_core.progress import Reporter
from parley_core.views.richprogress import reporting


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

    def bound(self, **how: Any) -> int:
        """:func:`campaign_bounds` of this campaign."""
        return campaign_bounds(self.store, name=self.name, **how)

    def check(self, **how: Any) -> int:
        """:func:`campaign_check` of this campaign."""
        return campaign_check(self.store, name=self.name, **how)

    def report(self, out: str | Path, **how: Any) -> CampaignReport:
        """:func:`campaign_report` of this campaign."""
        return campaign_report(self.store, out, name=self.name, **how)


@frozen(kw_only=True)
class CampaignReport:
    """What ``parley experiment report`` wrote."""

    directory: Path
    table2: str
    """table2.md's text: per requirement setting, better/worse/same than the baseline."""
    files: tuple[Path, ...] = field(converter=tuple[Path, ...])

    @property
    def page(self) -> Path:
        """The interactive report.html (Table 2 and the box plots per setting)."""
        return self.directory / "report.html"

    def _repr_html_(self) -> str:
        from parley_core.views import inline

        return inline(self.page.read_text(encoding="utf-8"), 900)


def existing_store(store: str | Path) -> Path:
    """A campaign store that exists (reading one must not create an empty store)."""
    from parley_core.errors import OptionError

    path = Path(store)
    if not path.is_file():
        raise OptionError(f"store {store} does not exist; give the file of `parley experiment run --store`")
    return path


def campaign_bounds(
    store: str | Path,
    *,
    name: str | None = None,
    method: str = "pareto",
    again: bool = False,
    workers: int | None = None,
    progress: bool | Reporter = True,
) -> int:
    """``parley experiment bound``: each instance's certified outer bound, computed once and
    stored (instances that have one are skipped unless ``again``); the number computed now.
    The campaign report then gives the median gap to the bound per requirement setting."""
    from parley_core.experiment import bounds
    from parley_core.experiment.store import Store

    with Store(existing_store(store)) as results, reporting(progress) as reporter:
        chosen, case_name, _settings = results.campaign(name)
        tasks = bounds.plan(results, chosen, case_name, method, again)
        reporter.stage(f"bounds of {chosen}", len(tasks))
        return bounds.run(tasks, results, workers=workers, progress=reporter.advance)


def campaign_check(
    store: str | Path,
    *,
    name: str | None = None,
    settings: Sequence[str | Sequence[float]] = (),
    seconds: float = 30.0,
    again: bool = False,
    workers: int | None = None,
    progress: bool | Reporter = True,
) -> int:
    """``parley experiment check``: per instance and requirement setting (default: the case
    study's), whether a policy of the family meets the setting's box
    (:mod:`parley_core.experiment.answers`), stored; cells already answered are skipped unless
    ``again``. Returns the number of cells answered now; the report then counts them per setting."""
    from parley_core.experiment import answers
    from parley_core.experiment import report as reports
    from parley_core.experiment.store import Store
    from parley_core.plugin.manager import load_registry

    with Store(existing_store(store)) as results, reporting(progress) as reporter:
        chosen, case_name, _settings = results.campaign(name)
        case = load_registry().get(case_name)
        records = list(results.runs(chosen))
        n = len(records[0].objectives) if records else 0
        wanted = [
            reports.parse_setting(s if isinstance(s, str) else ",".join(map(str, s)), n) for s in settings
        ] or list(case.requirement_settings)
        tasks = answers.plan(results, chosen, case_name, wanted, seconds, again)
        reporter.stage(f"requirement answers of {chosen}", len(tasks))
        return answers.run(tasks, results, workers=workers, progress=reporter.advance)


def campaign_report(
    store: str | Path,
    out: str | Path,
    *,
    name: str | None = None,
    settings: Sequence[str | Sequence[float]] = (),
    figure_setting: str | Sequence[float] | None = None,
    published: str | Path | None = None,
    force: bool = False,
) -> CampaignReport:
    """``parley experiment report``: Table 2, its CSV, the box plots and report.html of a
    campaign in ``out``. ``settings``: requirement settings, each one worst acceptable value
    per objective (``"0.7,80"`` or ``(0.7, 80)``; default: the case study's)."""
    from parley_core.errors import OptionError
    from parley_core.experiment import report as reports
    from parley_core.experiment.store import Store
    from parley_core.plugin.manager import load_registry
    from parley_core.rundir.write import check_output

    store, out = existing_store(store), Path(out)
    if published is not None and not Path(published).is_dir():
        raise OptionError(f"--published {published} is not a directory")
    check_output(out, force)
    with Store(store) as results:
        chosen, case_name, settings_record = results.campaign(name)
        records = list(results.runs(chosen))
        stored_bounds = results.bounds(chosen)
        stored_answers = results.answers(chosen)
    if not records:
        raise OptionError(f"campaign {chosen} in {store} has no finished run yet")
    n = len(records[0].objectives)

    def setting(value: str | Sequence[float]) -> tuple[float, ...]:
        return reports.parse_setting(value if isinstance(value, str) else ",".join(map(str, value)), n)

    text, written = reports.write_report(
        records,
        out,
        campaign=chosen,
        case=load_registry().get(case_name),
        settings_record=settings_record,
        settings=[setting(s) for s in settings],
        figure_setting=setting(figure_setting) if figure_setting is not None else None,
        published=Path(published) if published is not None else None,
        bounds=stored_bounds,
        answers=stored_answers,
    )
    return CampaignReport(directory=out, table2=text, files=written)


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
    from parley_core.plugin.manager import load_registry

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
