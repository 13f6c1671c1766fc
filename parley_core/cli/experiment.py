"""Campaign commands: experiment run, verify, report, scalability."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from parley_core.cli.app import experiment_app
from parley_core.cli.common import case_study, user_errors
from parley_core.cli.console import progress_bars
from parley_core.cli.options import (
    ALGORITHM,
    POPULATION,
    AlgorithmOption,
    CaseArgument,
    EvaluatorOption,
    GenerationsOption,
    MaxEvaluationsOption,
    SetOption,
    TimeLimitOption,
)
from parley_core.errors import OptionError
from parley_core.evaluate import EvaluatorKind

StoreOption = Annotated[Path, typer.Option(help="SQLite results file of `parley experiment run`.")]
NameOption = Annotated[str | None, typer.Option(help="Campaign name (default: the store's only campaign).")]


@experiment_app.command("run")
@user_errors
def experiment_run(
    case: CaseArgument,
    store: Annotated[Path, typer.Option(help="SQLite results file (created if missing; resumed if present).")],
    reps: Annotated[
        int, typer.Option(min=1, help="Repetitions per instance (seeds first-seed, first-seed+1, ...).")
    ] = 10,
    grid: Annotated[
        list[str] | None,
        typer.Option("--grid", metavar="KEY=V1,V2,...", help="Instances: the product of these option values."),
    ] = None,
    instances: Annotated[
        str | None, typer.Option(help="Instances: one per file of a directory or glob (e.g. 'maps/map_*.csv').")
    ] = None,
    instance_option: Annotated[
        str | None,
        typer.Option(help="The option that receives each --instances file (default: the first file option)."),
    ] = None,
    set_: SetOption = None,
    name: Annotated[
        str | None, typer.Option(help="Campaign name inside the store (default: the case study's name).")
    ] = None,
    algorithm: AlgorithmOption = ALGORITHM,
    population: Annotated[int, typer.Option(min=2, help="NSGA-II population size.")] = POPULATION,
    generations: GenerationsOption = None,
    max_evaluations: MaxEvaluationsOption = None,
    time_limit: TimeLimitOption = None,
    first_seed: Annotated[int, typer.Option(help="Seed of the first repetition.")] = 1,
    evaluator: EvaluatorOption = EvaluatorKind.QUOTIENT.value,
    verify: Annotated[
        bool,
        typer.Option(
            help="Re-check every front policy with Storm (--no-verify keeps the search's values, and says so)."
        ),
    ] = True,
    workers: Annotated[
        int | None, typer.Option("--workers", "-j", min=1, help="Runs at once on this machine (default: one per core).")
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option(help="Dask scheduler address (e.g. tcp://host:8786) to run on a cluster.")
    ] = None,
) -> None:
    """Run a campaign; rerunning the same command resumes it, skipping finished runs."""
    from parley_core.api.campaigns import experiment
    from parley_core.plugin.options import parse_assignments

    outcome = experiment(
        case,
        store=store,
        reps=reps,
        grid=grid or [],
        instances=instances,
        instance_option=instance_option,
        options=parse_assignments(set_ or []),
        name=name,
        algorithm=algorithm,
        population=population,
        generations=generations,
        max_evaluations=max_evaluations,
        time_limit=time_limit,
        first_seed=first_seed,
        evaluator=evaluator,
        verify=verify,
        workers=workers,
        scheduler=scheduler,
    )
    Console().print(
        f"campaign {outcome.name}: {outcome.planned} runs planned, {outcome.skipped} already stored, "
        f"{outcome.stored} stored now, {len(outcome.failures)} failed; results in {store}"
    )
    for instance, repetition, message in outcome.failures[:10]:
        print(f"failed: {instance} repetition {repetition}: {message}", file=sys.stderr)
    if outcome.failures:
        raise typer.Exit(1)


@experiment_app.command("verify")
@user_errors
def experiment_verify(
    store: StoreOption,
    name: NameOption = None,
    workers: Annotated[
        int | None, typer.Option("--workers", "-j", min=1, help="Processes at once (default: one per core).")
    ] = None,
    repetition: Annotated[
        list[int] | None,
        typer.Option(
            "--repetition", min=0, help="Only these repetitions (repeatable), e.g. 0 for a sample of one per instance."
        ),
    ] = None,
) -> None:
    """Re-check with Storm every stored front not yet checked (runs of --no-verify); resumable."""
    from parley_core.api.campaigns import existing_store
    from parley_core.experiment.campaign import verify_stored
    from parley_core.experiment.store import Store

    existing_store(store)
    wanted = set(repetition) if repetition else None
    with Store(store) as results:
        campaign, case_name, _settings = results.campaign(name)
        selected = [r for r in results.runs(campaign) if wanted is None or r.repetition in wanted]
        with progress_bars() as progress:
            task = progress.add_task(f"verify {campaign}", total=len(selected))
            progress.update(task, completed=sum(r.verified for r in selected))
            now, before, worst = verify_stored(
                results,
                campaign,
                case_name,
                workers=workers,
                repetitions=wanted,
                progress=lambda n: progress.advance(task, n),
            )
    Console().print(
        f"campaign {campaign}: {now} fronts re-checked by Storm now, {before} already were; "
        f"largest difference from the stored values {worst:.1e}"
    )


@experiment_app.command("bound")
@user_errors
def experiment_bound(
    store: StoreOption,
    name: NameOption = None,
    method: Annotated[
        str,
        typer.Option(
            help="pareto (the outer approximation of a run's default bound), ideal (its ideal point) or belief (pareto on the ideal point of the relaxation read as a POMDP)."
        ),
    ] = "pareto",
    again: Annotated[bool, typer.Option(help="Compute the bounds of instances that have one again.")] = False,
    workers: Annotated[
        int | None, typer.Option("--workers", "-j", min=1, help="Instances at once (default: one per core).")
    ] = None,
) -> None:
    """Compute each instance's certified outer bound once and store it; `experiment report` then gives the
    median gap to the bound per requirement setting."""
    from parley_core.api.campaigns import campaign_bounds

    stored = campaign_bounds(store, name=name, method=method, again=again, workers=workers)
    Console().print(f"{stored} instance bounds computed and stored in {store}")


@experiment_app.command("check")
@user_errors
def experiment_check(
    store: StoreOption,
    name: NameOption = None,
    setting: Annotated[
        list[str] | None,
        typer.Option(
            "--setting",
            metavar="B1,B2",
            help="Requirement setting: worst acceptable value per objective (repeatable; default: the case study's).",
        ),
    ] = None,
    seconds: Annotated[
        float,
        typer.Option(
            "--cell-time",
            min=0.001,
            help="Seconds of branch and bound per cell that neither a stored front nor the stored bound answers.",
        ),
    ] = 30.0,
    again: Annotated[bool, typer.Option(help="Answer the cells that have an answer again.")] = False,
    workers: Annotated[
        int | None, typer.Option("--workers", "-j", min=1, help="Instances at once (default: one per core).")
    ] = None,
) -> None:
    """Answer each instance x requirement setting: is there a policy of the family inside the box? feasible (a
    stored front's policy, checked by Storm), infeasible (the stored bound or branch and bound proves none is), or
    unknown; stored, and counted per setting by `experiment report`."""
    from parley_core.api.campaigns import campaign_check

    answered = campaign_check(store, name=name, settings=setting or (), seconds=seconds, again=again, workers=workers)
    Console().print(f"{answered} cells answered and stored in {store}")


@experiment_app.command("report")
@user_errors
def experiment_report(
    store: StoreOption,
    out: Annotated[Path, typer.Option(help="Directory for the tables and figures.")],
    name: NameOption = None,
    setting: Annotated[
        list[str] | None,
        typer.Option(
            "--setting", metavar="B1,B2", help="Requirement setting: worst acceptable value per objective (repeatable)."
        ),
    ] = None,
    published: Annotated[
        Path | None, typer.Option(help="Directory of published fronts ({instance}_rep{R}.front.tsv) to compare with.")
    ] = None,
    figure_setting: Annotated[
        str | None,
        typer.Option(
            metavar="B1,B2", help="Setting of the box plots (default: the case study's, if reported, else the first)."
        ),
    ] = None,
    force: Annotated[bool, typer.Option(help="Replace the files of an existing --out directory.")] = False,
) -> None:
    """Report a campaign: Table 2 (per setting: better/worse/same than the baseline), box plots, CSV."""
    from parley_core.api.campaigns import campaign_report

    made = campaign_report(
        store,
        out,
        name=name,
        settings=setting or (),
        figure_setting=figure_setting,
        published=published,
        force=force,
    )
    text, written = made.table2, made.files
    Console().print(text)
    Console().print(f"wrote {out}/table2.md, table2.csv, report.html and {len(written) - 3} figures")


@experiment_app.command("scalability")
@user_errors
def experiment_scalability(
    case: CaseArgument,
    sizes: Annotated[
        str, typer.Option(help="Comma-separated values of the size option, e.g. 5,10,15,20,30,50.")
    ] = "5,10,15,20,30,50",
    option: Annotated[str, typer.Option(help="The option the sizes go to.")] = "size",
    set_: SetOption = None,
    storm_policies: Annotated[
        int,
        typer.Option(
            min=1, help="Policies timed with the Storm evaluator per size (a 50x50 robot_grid policy takes about 30 s)."
        ),
    ] = 10,
    out: Annotated[Path | None, typer.Option(help="Directory for table3.md and table3.json.")] = None,
) -> None:
    """Table 3: model size, per-policy time of both evaluators, search time and search space per size."""
    from parley_core.experiment.scalability import write_table3

    study = case_study(case)
    try:
        values = [int(v) for v in sizes.split(",")]
    except ValueError:
        raise OptionError(f"malformed --sizes {sizes!r}; give integers such as 5,10,20") from None
    with progress_bars() as progress:
        task = progress.add_task("scalability", total=len(values))
        table = write_table3(
            study,
            values,
            option,
            set_ or [],
            storm_policies=storm_policies,
            out=out,
            progress=lambda n: progress.advance(task, n),
        )
    Console().print(table)
