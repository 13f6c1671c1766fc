"""Commands that answer requirements: check (a case study), check-model (your own model),
recheck (a certificate again)."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console

from parley_core.cli.app import app
from parley_core.cli.common import user_errors
from parley_core.cli.console import RichReporter, fmt, stderr
from parley_core.cli.options import (
    SEED,
    CaseArgument,
    DecisionOption,
    ForceOption,
    JsonOption,
    ObserveOption,
    OutOption,
    SeedOption,
    SetOption,
    WorkersOption,
)

if TYPE_CHECKING:
    from parley_core.api.runs import Check

RequireOption = Annotated[
    list[str],
    typer.Option(
        "--require",
        metavar="NAME>=LEVEL|NAME<=LEVEL",
        help="A requirement, in the objective's direction: success>=0.8, cost<=60 (repeatable; all must hold).",
    ),
]
CheckTimeOption = Annotated[
    float,
    typer.Option(
        "--time-limit",
        min=0.001,
        help="Seconds for the answer, search and branch and bound together (building the model and Storm's "
        "verification of a feasible policy not counted); then the answer is unknown, with the share left open.",
    ),
]


CheckGenerationsOption = Annotated[
    int | None,
    typer.Option(
        "--generations",
        min=1,
        show_default=False,
        help="Generations of the first search (default: 40); if it finds nothing inside the box, the search goes "
        "on from the closest policies for the rest of its share (a quarter of --time-limit).",
    ),
]


def _command() -> str:
    return shlex.join(["parley", *sys.argv[1:]])


def _print(found: Check, json_: bool) -> None:
    document = found.document
    if json_:
        print(json.dumps(dict(document), indent=2))
    else:
        _print_answer(found)
    if document.get("branch_and_bound", {}).get("stopped_by") == "interrupted":
        raise typer.Exit(130)


def _print_answer(found: Check) -> None:
    console = Console()
    requirement = " and ".join(found.requirement)
    document = found.document
    if found.answer == "feasible":
        values = ", ".join(f"{k} {fmt(v)}" for k, v in (found.values or {}).items())
        console.print(
            f"[green]feasible[/]: {found.policy} meets {requirement} ({values}; Storm's values); "
            f"the run holds {document.get('policies_inside', 1)} policies inside the box"
        )
        console.print(f"controller: {found.directory / 'controller.json'}")
    elif found.answer == "infeasible":
        console.print(
            f"[red]infeasible[/]: no policy of the family meets {requirement}; the certificate "
            f"({document.get('sub_families')} sub-families, each bounded away from the box or evaluated) is "
            f"{found.certificate} (`parley recheck {found.directory}` checks it again)"
        )
    else:
        best = ", ".join(
            f"{k} {fmt(v)}" for k, v in (document.get("open_best") or {}).items() if isinstance(v, (int, float))
        )
        share = 100 * float(found.open_share or 0.0)
        console.print(
            f"[yellow]unknown[/] within the time limit: {share:.3g} % of the family is still open"
            + (f"; its bounds still allow at best {best}" if best else "")
            + "; give a longer --time-limit"
        )
    console.print(f"wrote {found.directory}/")


@app.command("check")
@user_errors
def check_command(
    case: CaseArgument,
    require: RequireOption,
    set_: SetOption = None,
    time_limit: CheckTimeOption = 300.0,
    seed: SeedOption = SEED,
    generations: CheckGenerationsOption = None,
    workers: WorkersOption = None,
    out: OutOption = None,
    force: ForceOption = False,
    json_: JsonOption = False,
) -> None:
    """Is there a policy that meets the requirements? feasible (a Storm-verified policy inside the box, with its
    controller), infeasible (a certificate that no policy of the family is), or unknown within --time-limit."""
    from parley_core.api.commands import check
    from parley_core.plugin.options import parse_assignments

    options = parse_assignments(set_ or [])
    with RichReporter(stderr()) as reporter:
        found = check(
            case,
            require,
            time_limit=time_limit,
            seed=seed,
            generations=generations,
            workers=workers,
            out=out,
            force=force,
            progress=reporter,
            options=options,
            command=_command(),
        )
    _print(found, json_)


@app.command("check-model")
@user_errors
def check_model_command(
    model: Annotated[Path, typer.Argument(help="A PRISM DTMC.")],
    props: Annotated[Path, typer.Option(help="PCTL properties, each after a '// name: NAME, max|min' comment.")],
    decision: DecisionOption,
    require: RequireOption,
    observe: ObserveOption = None,
    maximize: Annotated[
        list[str] | None, typer.Option("--maximize", metavar="NAME", help="Maximize this objective.")
    ] = None,
    minimize: Annotated[
        list[str] | None, typer.Option("--minimize", metavar="NAME", help="Minimize this objective.")
    ] = None,
    time_limit: CheckTimeOption = 300.0,
    seed: SeedOption = SEED,
    generations: CheckGenerationsOption = None,
    workers: WorkersOption = None,
    out: OutOption = None,
    force: ForceOption = False,
    json_: JsonOption = False,
) -> None:
    """`parley check` for your own PRISM model, with `parley synthesize`'s model options."""
    from parley_core.api.commands import check_model

    with RichReporter(stderr()) as reporter:
        found = check_model(
            model,
            require,
            props=props,
            decisions=decision,
            observe=observe or (),
            maximize=maximize or (),
            minimize=minimize or (),
            time_limit=time_limit,
            seed=seed,
            generations=generations,
            workers=workers,
            out=out,
            force=force,
            progress=reporter,
            command=_command(),
        )
    _print(found, json_)


@app.command("recheck")
@user_errors
def recheck_command(
    check_dir: Annotated[Path, typer.Argument(help="A directory `parley check` wrote with an infeasible answer.")],
) -> None:
    """Check an infeasibility certificate again from the family alone: its sub-families cover the family, each
    one's bound (computed again) misses the box or its policies (evaluated again) are outside it."""
    from parley_core.api.commands import recheck

    count = recheck(check_dir)
    Console().print(f"certificate holds: {count} sub-families cover the family and none reaches the box")
