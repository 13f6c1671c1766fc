"""The ``parley`` command: the only place that prints, colours or chooses exit codes.

User errors (any :class:`~parley_core.errors.ParleyError`) end as one line on stderr,
``error: ...``, with exit status 2. Progress goes to stderr, so ``--json`` output on stdout
is one JSON document and nothing else.
"""

from __future__ import annotations

import functools
import json
import sys
import time
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from parley_core.casestudy import CaseStudy, options_as_dict
from parley_core.errors import OptionError, ParleyError
from parley_core.model import Front, Policy

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    help="Synthesise uncertainty reduction controllers (URCs) with formal guarantees.",
)

SetOption = Annotated[
    list[str] | None,
    typer.Option("--set", "-s", metavar="KEY=VALUE", help="A case-study option (repeatable); see `parley options CASE`."),
]
WorkersOption = Annotated[
    int | None, typer.Option("--workers", "-j", min=1, help="Worker processes for Storm (default: one per core).")
]
EvaluatorOption = Annotated[
    str,
    typer.Option(
        "--evaluator",
        help="quotient: one MDP for all policies, fast; storm: build and check each policy (the reference).",
    ),
]
JsonOption = Annotated[bool, typer.Option("--json", help="Print one JSON document to stdout and nothing else there.")]


def _user_errors(command):
    """Turn ParleyError into one line on stderr and exit status 2."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except ParleyError as exc:
            message = " ".join(str(exc).split())
            print(f"error: {message}", file=sys.stderr)
            raise typer.Exit(2) from None

    return wrapper


class RichReporter:
    """Draws one progress bar per pipeline stage on stderr."""

    def __init__(self, console: Console) -> None:
        self.console = console
        self.progress = Progress(
            SpinnerColumn(),
            TextColumn("{task.description:<18}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            console=console,
            transient=False,
        )
        self.task = None

    def __enter__(self) -> RichReporter:
        self.progress.start()
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is None:
            self._finish()
        else:  # an error: leave nothing behind but its message
            self.progress.live.transient = True
        self.progress.stop()

    def _finish(self) -> None:
        # a stage without a known size is done when the next starts; a sized one shows
        # how far it got (less than its total if interrupted)
        if self.task is not None and self.progress.tasks[-1].total is None:
            self.progress.update(self.task, total=1, completed=1)

    def stage(self, name: str, total: int | None = None) -> None:
        self._finish()
        self.task = self.progress.add_task(name, total=total)

    def advance(self, n: int = 1) -> None:
        if self.task is not None:
            self.progress.advance(self.task, n)

    def note(self, text: str) -> None:
        self.progress.console.print(f"[yellow]note:[/] {text}")


def _registry():
    from parley_core.plugins import load_registry

    return load_registry()


def _case(name: str) -> CaseStudy:
    return _registry().get(name)


def _prepare(case_name: str, assignments: list[str] | None, reporter=None):
    from parley_core.pipeline import prepare

    case = _case(case_name)
    options = case.options(assignments or [])
    return prepare(case, options, reporter)


def _stderr() -> Console:
    return Console(stderr=True)


def _fmt(value: float) -> str:
    return f"{value:.6g}" if abs(value) >= 1e-3 or value == 0 else f"{value:.3e}"


def _front_table(title: str, front: Front, extra: dict[str, list[Any]] | None = None, limit: int = 40) -> Table:
    table = Table(title=title, title_justify="left")
    table.add_column("policy")
    for name in extra or {}:
        table.add_column(name, justify="right")
    for objective in front.objectives:
        table.add_column(f"{objective.name} ({objective.direction.value})", justify="right")
    rows = list(range(len(front)))
    if len(rows) > limit:
        step = (len(rows) - 1) / (limit - 1)
        rows = sorted({round(i * step) for i in range(limit)})
    for i in rows:
        cells = [front.policies[i].name]
        cells += [str(column[i]) for column in (extra or {}).values()]
        cells += [_fmt(v) for v in front.values[i]]
        table.add_row(*cells)
    if len(rows) < len(front):
        table.caption = f"{len(rows)} of {len(front)} policies shown, evenly spaced; all are in front.csv"
    return table


def _values_json(case: CaseStudy, options: Any, front: Front, decisions: list[dict[str, int]] | None = None) -> dict[str, Any]:
    policies = []
    for i, (policy, row) in enumerate(zip(front.policies, front.values)):
        entry: dict[str, Any] = {"policy": policy.name, "values": {o.name: v for o, v in zip(front.objectives, row)}}
        if decisions is not None:
            entry["decisions"] = decisions[i]
        policies.append(entry)
    return {
        "case_study": case.name,
        "options": options_as_dict(options),
        "objectives": [{"name": o.name, "direction": o.direction.value, "formula": o.formula} for o in front.objectives],
        "policies": policies,
    }


@app.command("list")
@_user_errors
def list_command() -> None:
    """List the registered case studies."""
    registry = _registry()
    table = Table(title="case studies", title_justify="left")
    table.add_column("name", style="bold")
    table.add_column("description")
    table.add_column("plugin", style="dim")
    for name in registry.names:
        table.add_row(name, registry.case_studies[name].description, registry.providers[name])
    Console().print(table)


@app.command("options")
@_user_errors
def options_command(case: Annotated[str, typer.Argument(help="Case study name (see `parley list`).")]) -> None:
    """Show a case study's options (for --set KEY=VALUE) with their defaults."""
    study = _case(case)
    table = Table(title=f"{study.name} options", title_justify="left")
    for column in ("option", "type", "default", "meaning"):
        table.add_column(column)
    for f in study.option_fields():
        kind = str(f.type).replace("pathlib.", "").replace("Path", "path") if not isinstance(f.type, type) else f.type.__name__
        table.add_row(f.name, kind, str(f.default), f.metadata.get("help", ""))
    Console().print(table)


@app.command("run")
@_user_errors
def run_command(
    case: Annotated[str, typer.Argument(help="Case study name (see `parley list`).")],
    set_: SetOption = None,
    seed: Annotated[int, typer.Option(help="Seed of the search; the same seed gives the same front.")] = 1,
    population: Annotated[int, typer.Option(min=2, help="NSGA-II population size.")] = 100,
    generations: Annotated[int, typer.Option(min=1, help="NSGA-II generations.")] = 40,
    out: Annotated[Path | None, typer.Option(help="Run directory (default: runs/CASE-TIMESTAMP).")] = None,
    force: Annotated[bool, typer.Option(help="Replace the files of an existing --out directory.")] = False,
    evaluator: EvaluatorOption = "quotient",
    workers: WorkersOption = None,
) -> None:
    """Synthesise a URC: search for Pareto-optimal policies, verify them with Storm, write a run directory."""
    from parley_core.pipeline import run
    from parley_core.report import check_output, summary, write_run
    from parley_core.search import SearchSettings

    console = Console()
    out = out or Path("runs") / f"{case}-{time.strftime('%Y%m%d-%H%M%S')}"
    check_output(out, force)
    settings = SearchSettings(population=population, generations=generations, seed=seed)
    with RichReporter(_stderr()) as reporter:
        prepared = _prepare(case, set_, reporter)
        result = run(prepared, settings, evaluator=evaluator, workers=workers, reporter=reporter)
        reporter.stage("write report")
        write_run(result, out, force=force)
    info = summary(result)
    constants = [s.constant for s in result.family.system.services]
    console.print(_front_table(f"Pareto front: {len(result.front)} policies, values checked by Storm", result.front))
    console.print(
        _front_table(
            "Baseline",
            result.baseline,
            {c: [b.values[c] for b in result.family.system.baselines] for c in constants},
        )
    )
    gain = info["hypervolume_gain_percent"]
    reference = ", ".join(f"{o.name}={_fmt(r)}" for o, r in zip(result.family.objectives, result.reference))
    console.print(
        f"hypervolume: front {_fmt(info['front']['hypervolume'])}, baseline {_fmt(info['baseline']['hypervolume'])}"
        + (f" (gain {gain:+.1f}%)" if gain is not None else "")
        + f"; reference point {reference}"
    )
    console.print(
        f"{result.search.evaluations} policies evaluated in {result.search.generations} generations "
        f"({result.timings.get('search', 0):.1f} s); selected {info['selected']['policy']} (knee)"
    )
    verification = result.verification
    if verification.by == "storm":
        console.print(
            f"every front policy re-checked by Storm: largest difference from the {result.evaluator} evaluator "
            f"{verification.max_difference:.1e}"
        )
    console.print(f"wrote {out}/")
    if result.search.interrupted:
        raise typer.Exit(130)


def _read_or_constant(family, policies: Path | None, constant: int | None) -> list[Policy]:
    from parley_core.policies import read_policies

    if (policies is None) == (constant is None):
        raise OptionError("give exactly one of --policies FILE and --constant K")
    if policies is not None:
        return read_policies(policies, family)
    policy = family.uniform(f"constant-{constant}", {s.constant: constant for s in family.system.services})
    family.check(policy)
    return [policy]


@app.command("evaluate")
@_user_errors
def evaluate_command(
    case: Annotated[str, typer.Argument(help="Case study name (see `parley list`).")],
    set_: SetOption = None,
    policies: Annotated[
        Path | None,
        typer.Option(help="CSV: policy, observation variables, one column per service (or a run's policies.csv)."),
    ] = None,
    constant: Annotated[int | None, typer.Option(help="Evaluate the policy that uses this value everywhere.")] = None,
    evaluator: EvaluatorOption = "quotient",
    json_: JsonOption = False,
    workers: WorkersOption = None,
) -> None:
    """Evaluate policies and print their objective values."""
    from parley_core.pipeline import evaluate, make_evaluator

    with RichReporter(_stderr()) as reporter:
        prepared = _prepare(case, set_, reporter)
        chosen = _read_or_constant(prepared.family, policies, constant)
        reporter.stage(f"{evaluator} evaluator")
        engine = make_evaluator(prepared.family, evaluator, workers)
        try:
            front = evaluate(prepared.family, chosen, engine, reporter, stage=f"evaluate ({evaluator})")
        finally:
            engine.close()
    if json_:
        document = _values_json(prepared.case, prepared.options, front)
        document["evaluator"] = evaluator
        print(json.dumps(document, indent=2))
    else:
        Console().print(_front_table(f"values ({evaluator} evaluator)", front, limit=10_000))


@app.command("baseline")
@_user_errors
def baseline_command(
    case: Annotated[str, typer.Argument(help="Case study name (see `parley list`).")],
    set_: SetOption = None,
    json_: JsonOption = False,
    workers: WorkersOption = None,
) -> None:
    """Evaluate the case study's baseline policies (fixed frequency or threshold) with Storm."""
    from parley_core.evaluate.storm import StormEvaluator
    from parley_core.pipeline import evaluate

    with RichReporter(_stderr()) as reporter:
        prepared = _prepare(case, set_, reporter)
        family = prepared.family
        with StormEvaluator(family, workers=workers) as storm:
            front = evaluate(family, family.baseline_policies(), storm, reporter, stage="baselines (Storm)")
    decisions = [dict(b.values) for b in family.system.baselines]
    if json_:
        print(json.dumps(_values_json(prepared.case, prepared.options, front, decisions), indent=2))
    else:
        constants = [s.constant for s in family.system.services]
        Console().print(_front_table("Baseline", front, {c: [d[c] for d in decisions] for c in constants}, limit=10_000))


def main() -> None:
    app()

