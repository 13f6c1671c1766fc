"""Commands that synthesize: run (a case study), synthesize (a user's model), augment."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console

from parley_core.cli.app import app
from parley_core.cli.common import user_errors
from parley_core.cli.console import RichReporter, fmt, front_table, stderr
from parley_core.cli.options import (
    ALGORITHM,
    BOUND_SECONDS,
    POPULATION,
    SEED,
    AlgorithmOption,
    BoundOption,
    BoundTimeOption,
    CaseArgument,
    ConstraintOption,
    DecisionOption,
    EvaluatorOption,
    ExactOption,
    ForceOption,
    GenerationsOption,
    MaxEvaluationsOption,
    ObserveOption,
    OutOption,
    PopulationOption,
    ScenariosOption,
    SeedOption,
    SetOption,
    TimeLimitOption,
    VerifyWithOption,
    WarmStartOption,
    WorkersOption,
)
from parley_core.errors import OptionError
from parley_core.evaluate import EvaluatorKind
from parley_core.model import Direction
from parley_core.optimality.records import Stopped

if TYPE_CHECKING:
    from parley_core.model import Family
    from parley_core.pipeline import RunResult
    from parley_core.rundir.summary import RunSummary


@app.command("run")
@user_errors
def run_command(
    case: CaseArgument,
    set_: SetOption = None,
    seed: SeedOption = SEED,
    algorithm: AlgorithmOption = ALGORITHM,
    population: PopulationOption = POPULATION,
    generations: GenerationsOption = None,
    max_evaluations: MaxEvaluationsOption = None,
    time_limit: TimeLimitOption = None,
    out: OutOption = None,
    force: ForceOption = False,
    evaluator: EvaluatorOption = EvaluatorKind.QUOTIENT.value,
    constraint: ConstraintOption = None,
    workers: WorkersOption = None,
    bound: BoundOption = "pareto",
    bound_time: BoundTimeOption = None,
    verify_with: VerifyWithOption = "batch",
    scenarios: ScenariosOption = None,
    warm_start: WarmStartOption = None,
) -> None:
    """Synthesize a URC: search for Pareto-optimal policies, verify them with Storm, write a run directory."""
    from parley_core.api.commands import run
    from parley_core.plugin.options import parse_assignments

    options = parse_assignments(set_ or [])
    _synthesize(
        lambda reporter: run(
            case,
            seed=seed,
            population=population,
            generations=generations,
            max_evaluations=max_evaluations,
            time_limit=time_limit,
            algorithm=algorithm,
            constraints=constraint or (),
            evaluator=evaluator,
            workers=workers,
            bound=bound,
            bound_time=BOUND_SECONDS if bound_time is None else bound_time,
            verify_with=verify_with,
            scenarios=scenarios,
            warm_start=warm_start,
            out=out,
            force=force,
            progress=reporter,
            options=options,
        ),
        warm_start,
    )


@app.command("exact")
@user_errors
def exact_command(
    case: CaseArgument,
    set_: SetOption = None,
    seed: SeedOption = SEED,
    time_limit: Annotated[
        float | None,
        typer.Option(
            "--time-limit",
            min=0.001,
            help="Stop branch and bound after this many seconds (default: none); building the model and quotient before it and verifying the front with Storm after it are not counted.",
        ),
    ] = None,
    out: OutOption = None,
    force: ForceOption = False,
    workers: WorkersOption = None,
) -> None:
    """The whole Pareto front of a case study's family: a search, then branch and bound over the
    decisions' ranges until no sub-family can hold a better policy (or --time-limit: the front
    and bound so far, with the gap); a run directory like `parley run`'s."""
    from parley_core.api.commands import exact
    from parley_core.plugin.options import parse_assignments

    options = parse_assignments(set_ or [])
    _synthesize(
        lambda reporter: exact(
            case,
            seed=seed,
            time_limit=time_limit,
            workers=workers,
            out=out,
            force=force,
            progress=reporter,
            options=options,
        )
    )


@app.command("synthesize")
@user_errors
def synthesize_command(
    model: Annotated[Path, typer.Argument(help="A PRISM DTMC.")],
    props: Annotated[
        Path,
        typer.Option(
            help="PCTL properties, each after a '// name: NAME, max|min' comment (or use --maximize/--minimize)."
        ),
    ],
    decision: DecisionOption,
    observe: ObserveOption = None,
    maximize: Annotated[
        list[str] | None, typer.Option("--maximize", metavar="NAME", help="Maximize this objective.")
    ] = None,
    minimize: Annotated[
        list[str] | None, typer.Option("--minimize", metavar="NAME", help="Minimize this objective.")
    ] = None,
    constraint: ConstraintOption = None,
    seed: SeedOption = SEED,
    algorithm: AlgorithmOption = ALGORITHM,
    population: PopulationOption = POPULATION,
    generations: GenerationsOption = None,
    max_evaluations: MaxEvaluationsOption = None,
    time_limit: TimeLimitOption = None,
    out: OutOption = None,
    force: ForceOption = False,
    evaluator: EvaluatorOption = EvaluatorKind.QUOTIENT.value,
    workers: WorkersOption = None,
    bound: BoundOption = "pareto",
    bound_time: BoundTimeOption = None,
    exact: ExactOption = False,
    verify_with: VerifyWithOption = "batch",
    scenarios: ScenariosOption = None,
    warm_start: WarmStartOption = None,
) -> None:
    """Synthesize a URC for your own PRISM model: the same pipeline and run directory as `parley run`
    (with --exact, the family's whole Pareto front, as `parley exact` gives a case study's)."""
    from parley_core.api.commands import synthesize

    if exact and bound not in ("pareto", "refine"):
        raise OptionError(f"--exact runs branch and bound (--bound refine); it takes no --bound {bound}")
    if exact:
        bound = "refine"
    seconds = bound_time if bound_time is not None else None if exact else BOUND_SECONDS

    _synthesize(
        lambda reporter: synthesize(
            model,
            props=props,
            decisions=decision,
            observe=observe or (),
            maximize=maximize or (),
            minimize=minimize or (),
            seed=seed,
            population=population,
            generations=generations,
            max_evaluations=max_evaluations,
            time_limit=time_limit,
            algorithm=algorithm,
            constraints=constraint or (),
            evaluator=evaluator,
            workers=workers,
            bound=bound,
            bound_time=seconds,
            verify_with=verify_with,
            scenarios=scenarios,
            warm_start=warm_start,
            out=out,
            force=force,
            progress=reporter,
        ),
        warm_start,
    )


def _stopped(by: Stopped) -> str:
    return "interrupted (Ctrl-C)" if by is Stopped.INTERRUPTED else f"stopped by {by.value}"


def _synthesize(make, warm_start: Path | None = None) -> None:
    """Make a run with ``make(reporter)`` (the API's ``run``, ``exact`` or ``synthesize``)
    under progress bars, then print it."""
    console = Console()
    with RichReporter(stderr()) as reporter:
        made = make(reporter)
    result = made.result
    assert result is not None  # made in this process
    _print_warnings(console, made.directory)
    _print_sets(console, result)
    _print_quality(console, made.files.summary, result.family)
    _print_looseness(console, made.files.summary, result)
    _print_search(console, made.files.summary, result, warm_start)
    _print_verification(console, result)
    console.print(f"wrote {made.directory}/")
    if result.search.interrupted:
        raise typer.Exit(130)


def _print_warnings(console: Console, out: Path) -> None:
    """What a run wrote instead of a picture or page a plugin or Bokeh could not make."""
    from parley_core.rundir.write import MAP_ERROR, PLOT_ERROR, REPORT_ERROR

    for missing, what in (
        (PLOT_ERROR, "the policy plot"),
        (MAP_ERROR, "the plugin's map"),
        (REPORT_ERROR, "report.html"),
    ):
        if (out / missing).is_file():
            console.print(
                f"[yellow]warning:[/] {what} failed; the run is complete without it ({out / missing} says why)"
            )


def _print_sets(console: Console, result: RunResult) -> None:
    """The front (a row per point) and the baseline, as tables."""
    import numpy as np

    from parley_core import metrics

    family = result.family
    constants = [s.constant for s in family.services]
    robust = result.scenarios
    checked = f"worst case over {len(robust)} scenarios, each checked by Storm" if robust else "values checked by Storm"
    directions = [o.direction for o in family.objectives]
    points = metrics.tie_points(np.array(result.front.values), directions)
    count = f"{len(result.front)} policies at {points.max() if len(points) else 0} points"
    if len(points) and points.max() < len(points):
        tolerance = f"{metrics.TIE_TOLERANCE:.0e}".replace("e-0", "e-")
        count += f" (policies within a relative {tolerance} of each other are ties and share one)"
    console.print(front_table(f"Pareto front: {count}, {checked}", result.front, points=points))
    console.print(
        front_table("Baseline", result.baseline, {c: [b.values[c] for b in family.baselines] for c in constants})
    )


LOOSE = 0.05
"""A gap above this gets a line saying where the bound is loose, objective by objective."""


def _print_looseness(console: Console, info: RunSummary, result: RunResult) -> None:
    """Where a large gap comes from: each objective's best on the front against the bound's
    best, and, for a front of one or two points, that the gap then mostly measures the
    hypervolume reference point's distance from them (the reference is derived from the
    front and the baseline, and an infinite baseline adds nothing to it)."""
    optimality, bound = info.optimality, result.bound
    if optimality is None or optimality.exact or optimality.gap is None or optimality.gap <= LOOSE or bound is None:
        return
    import numpy as np

    front = np.array(result.front.values, dtype=float)
    points = np.array(bound.points, dtype=float).reshape(-1, front.shape[1])
    if not len(front) or not len(points):
        return
    parts = []
    for i, objective in enumerate(result.family.objectives):
        pick = np.max if objective.direction is Direction.MAX else np.min
        ours, best = float(pick(front[:, i])), float(pick(points[:, i]))
        share = abs(best - ours) / max(abs(best), 1e-12) if np.isfinite(best) else float("inf")
        parts.append(f"{objective.name} {fmt(ours)} against {fmt(best)} ({100 * share:.1f}%)")
    line = "where the bound is loose: the front's best and the bound's, " + "; ".join(parts)
    line += (
        ". The bound's schedulers see the whole state, the URC only its observation; branch and bound "
        "(--bound refine, or --exact) narrows the gap on the URC's own policies"
    )
    count = info.front.points or len(front)
    if count <= 2:
        line += (
            f". The front has {count} point(s), so the gap mostly measures how far the "
            "hypervolume's reference point (derived from the front and the baseline) lies from it"
        )
    console.print(line)


def _print_quality(console: Console, info: RunSummary, family: Family) -> None:
    """Hypervolumes, the certified bound (or exactness) and a robust run's scenarios."""
    gain = info.hypervolume_gain_percent
    optimality = info.optimality
    reference = ", ".join(f"{o.name}={fmt(r)}" for o, r in zip(family.objectives, info.hypervolume_reference))
    console.print(
        f"hypervolume: front {fmt(info.front.hypervolume)}, baseline {fmt(info.baseline.hypervolume)}"
        + (f" (gain {gain:+.1f}%)" if gain is not None else "")
        + f"; reference point {reference}"
    )
    counts = optimality.search if optimality is not None else None
    if optimality is not None and optimality.exact:
        assert counts is not None  # only branch and bound proves a front exact
        console.print(
            f"exact: the front is the family's whole Pareto front (branch and bound: {counts.nodes} nodes, "
            f"{counts.pruned} pruned, {counts.evaluated} policies evaluated, {optimality.seconds:.1f} s)"
        )
    elif optimality is not None:
        gap = optimality.gap
        if counts is not None:
            console.print(
                f"branch and bound {_stopped(counts.stopped_by)} after {counts.nodes} nodes "
                f"({counts.pruned} pruned, {counts.evaluated} policies evaluated, {counts.open} open)"
            )
        console.print(
            "optimality: "
            + (
                f"the front covers {100 * (1 - gap):.1f}% of the bound's hypervolume (gap {100 * gap:.1f}%)"
                if gap is not None
                else "no finite bound"
            )
            + f"; bound: {optimality.method_name} (bound.csv)"
        )
    if info.robust is not None:
        console.print(
            "robust: each value is the worst over the scenarios; the front's hypervolume in each: "
            + ", ".join(f"{s.label} {fmt(s.front_hypervolume)}" for s in info.robust.scenarios)
            + " (scenarios.csv)"
        )


def _print_search(console: Console, info: RunSummary, result: RunResult, warm_start: Path | None) -> None:
    """What the search did: its budget, where it started, what guided or polished it."""
    search = result.search
    if result.warm_start:
        console.print(f"warm start: the search started from {result.warm_start} policies of {warm_start}")
    console.print(
        f"{search.evaluations} policies evaluated in {search.generations} generations of "
        f"{result.settings.algorithm} "
        f"({result.timings.get('search', 0):.1f} s, stopped by {search.stopped_by.value}); "
        f"selected {info.selected} (knee)"
    )
    if search.walked is not None:
        walked = search.walked
        console.print(
            f"guided: the search started from {len(walked.policies)} policies found by policy improvement "
            f"on the relaxation ({walked.seconds:.1f} s)"
            if not walked.skipped
            else f"guided: no policy improvement ({walked.skipped}); the search started without it"
        )
    if search.polished is not None:
        polished = search.polished
        console.print(
            f"polished: {polished.evaluations} of the evaluations were one-decision changes of the front, "
            f"chosen by the hypervolume the relaxation predicts for them ({polished.expanded} front policies "
            f"scored, {polished.seconds:.1f} s)"
            if not polished.skipped
            else f"polished: not polished ({polished.skipped}); the search had the whole budget"
        )
    for name, count in info.infinite_values.items():
        console.print(
            f"{count} of {search.evaluations} evaluated policies have an infinite {name} "
            "(the goal may never be reached); none is on the front unless all are"
        )


def _print_verification(console: Console, result: RunResult) -> None:
    """How Storm re-checked the values (what makes them a guarantee)."""
    from parley_core.verify import TOLERANCE, Verified

    verification = result.verification
    if verification.by is Verified.STORM_RECHECK:
        where = f" in each of {verification.scenarios} scenarios" if verification.scenarios > 1 else ""
        console.print(
            f"every front policy and baseline re-checked by Storm{where} ({verification.path}, "
            f"{verification.seconds:.1f} s): largest difference from the {result.evaluator.value} "
            f"evaluator {verification.max_difference:.1e} (relative {verification.max_relative_difference:.1e}, "
            f"within the tolerance {TOLERANCE:g})"
        )


@app.command("augment")
@user_errors
def augment_command(
    model: Annotated[Path, typer.Argument(help="A PRISM DTMC.")],
    decision: DecisionOption,
    observe: ObserveOption = None,
    out: Annotated[Path | None, typer.Option(help="Write the parametric model here (default: stdout).")] = None,
    format_: Annotated[
        str, typer.Option("--format", help="prism (undefined const int), evochecker (evolve int) or paynt (hole).")
    ] = "prism",
    force: Annotated[bool, typer.Option(help="Replace an existing --out file.")] = False,
) -> None:
    """Write the parametric model: one decision constant per service and reachable observation valuation."""
    from parley_core.api.evaluation import augmented_family, check_format
    from parley_core.family.augment import export

    check_format(format_)
    if out is not None and out.exists() and not force:
        raise OptionError(f"output {out} exists; choose another --out or add --force")
    family = augmented_family(model, decision, observe or [])
    text = export(family, format_)
    total = len(family.valuations) + len(family.left_out)
    print(
        f"{len(family.valuations)} of {total} observation valuations of ({', '.join(family.observation)}) "
        f"consult a service in some reachable state; {len(family.left_out)} left out; "
        f"{len(family.decisions)} decision constants",
        file=sys.stderr,
    )
    if out is None:
        sys.stdout.write(text)
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
        print(f"wrote {out}", file=sys.stderr)
