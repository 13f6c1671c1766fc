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
ConstraintOption = Annotated[
    list[str] | None,
    typer.Option("--constraint", metavar="NAME>=BOUND", help="A requirement the policies must meet, e.g. success>=0.8 (repeatable)."),
]
DecisionOption = Annotated[
    list[str],
    typer.Option("--decision", metavar="NAME=LOW..HIGH[:KIND]", help="A constant that sets when a service runs, and its values (repeatable)."),
]
ObserveOption = Annotated[list[str], typer.Option("--observe", metavar="VAR,...", help="Variables the URC may read.")]
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
        self.progress = _progress(console, "{task.description:<18}")
        self.task = None

    def __enter__(self) -> RichReporter:
        self.progress.start()
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is None:
            self._finish()
        else:  # an error: leave nothing behind but its message (not even rich's last newline)
            self.progress.live.transient = True
            self.console.quiet = True
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


def _progress(console: Console | None = None, description: str = "{task.description}") -> Progress:
    """The progress bars of every command: spinner, what, bar, done of total, time (on stderr)."""
    return Progress(
        SpinnerColumn(), TextColumn(description), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
        console=console or _stderr(),
    )


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
    constraint: ConstraintOption = None,
    workers: WorkersOption = None,
) -> None:
    """Synthesise a URC: search for Pareto-optimal policies, verify them with Storm, write a run directory."""
    from parley_core.search import SearchSettings

    out = out or Path("runs") / f"{case}-{time.strftime('%Y%m%d-%H%M%S')}"
    settings = SearchSettings(population=population, generations=generations, seed=seed, constraints=_constraints(constraint))
    _synthesise(lambda reporter: _prepare(case, set_, reporter), settings, out, force, evaluator, workers)


def _constraints(texts: list[str] | None):
    from parley_core.search import Constraint

    return tuple(Constraint.parse(t) for t in texts or [])


def _synthesise(prepare_with, settings, out: Path, force: bool, evaluator: str, workers: int | None) -> None:
    """Prepare, search, verify, write and print a run (shared by `run` and `synthesize`)."""
    from parley_core.pipeline import run
    from parley_core.report import PLOT_ERROR, check_output, summary, write_run

    console = Console()
    check_output(out, force)
    with RichReporter(_stderr()) as reporter:
        prepared = prepare_with(reporter)
        result = run(prepared, settings, evaluator=evaluator, workers=workers, reporter=reporter)
        reporter.stage("write report")
        written = write_run(result, out, force=force)
    if out / PLOT_ERROR in written:
        console.print(f"[yellow]warning:[/] the policy plot failed; the run is complete without it ({out / PLOT_ERROR} says why)")
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


@app.command("augment")
@_user_errors
def augment_command(
    model: Annotated[Path, typer.Argument(help="A PRISM DTMC.")],
    decision: DecisionOption,
    observe: ObserveOption,
    out: Annotated[Path | None, typer.Option(help="Write the parametric model here (default: stdout).")] = None,
    format_: Annotated[str, typer.Option("--format", help="prism (undefined const int), evochecker (evolve int) or paynt (hole).")] = "prism",
    force: Annotated[bool, typer.Option(help="Replace an existing --out file.")] = False,
) -> None:
    """Write the parametric model: one decision constant per service and reachable observation valuation."""
    from parley_core.augment import FORMATS, augment, export
    from parley_core.usermodel import system_from_file

    if format_ not in FORMATS:
        raise OptionError(f"unknown --format {format_!r}; valid: {', '.join(FORMATS)}")
    if out is not None and out.exists() and not force:
        raise OptionError(f"output {out} exists; choose another --out or add --force")
    system = system_from_file(model, decision, observe)
    family = augment(system, prune=True)
    text = export(family, format_)
    total = len(family.valuations) + len(family.left_out)
    print(
        f"{len(family.valuations)} of {total} observation valuations of ({', '.join(system.observation)}) consult a service "
        f"in some reachable state; {len(family.left_out)} left out; {len(family.decisions)} decision constants",
        file=sys.stderr,
    )
    if out is None:
        sys.stdout.write(text)
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
        print(f"wrote {out}", file=sys.stderr)


@app.command("synthesize")
@_user_errors
def synthesize_command(
    model: Annotated[Path, typer.Argument(help="A PRISM DTMC.")],
    props: Annotated[Path, typer.Option(help="PCTL properties, each after a '// name: NAME, max|min' comment (or use --maximize/--minimize).")],
    decision: DecisionOption,
    observe: ObserveOption,
    maximize: Annotated[list[str] | None, typer.Option("--maximize", metavar="NAME", help="Maximise this objective.")] = None,
    minimize: Annotated[list[str] | None, typer.Option("--minimize", metavar="NAME", help="Minimise this objective.")] = None,
    constraint: ConstraintOption = None,
    seed: Annotated[int, typer.Option(help="Seed of the search.")] = 1,
    population: Annotated[int, typer.Option(min=2)] = 100,
    generations: Annotated[int, typer.Option(min=1)] = 40,
    out: Annotated[Path | None, typer.Option(help="Run directory (default: runs/MODEL-TIMESTAMP).")] = None,
    force: Annotated[bool, typer.Option(help="Replace the files of an existing --out directory.")] = False,
    evaluator: EvaluatorOption = "quotient",
    workers: WorkersOption = None,
) -> None:
    """Synthesise a URC for your own PRISM model: the same pipeline and run directory as `parley run`."""
    from parley_core.pipeline import prepare
    from parley_core.search import SearchSettings
    from parley_core.usermodel import FileOptions, case_study_for, system_from_file

    def prepare_with(reporter):
        reporter.stage("read model")
        system = system_from_file(model, decision, observe, props, maximize or [], minimize or [])
        return prepare(case_study_for(system, model), FileOptions(model=str(model)), reporter)

    settings = SearchSettings(population=population, generations=generations, seed=seed, constraints=_constraints(constraint))
    out = out or Path("runs") / f"{model.stem}-{time.strftime('%Y%m%d-%H%M%S')}"
    _synthesise(prepare_with, settings, out, force, evaluator, workers)


@app.command("select")
@_user_errors
def select_command(
    run_dir: Annotated[Path, typer.Argument(help="A run directory of `parley run` or `parley synthesize`.")],
    constraint: ConstraintOption = None,
    prefer: Annotated[str | None, typer.Option(help="Take the best policy on this objective (among those meeting the constraints).")] = None,
    knee: Annotated[bool, typer.Option("--knee", help="Take the knee point (the default when --prefer is not given).")] = False,
    out: Annotated[Path | None, typer.Option(help="Controller file to write (default: RUN_DIR/controller.json).")] = None,
    json_: JsonOption = False,
) -> None:
    """Pick one policy from a front (best on an objective under constraints, or the knee) and write it as a controller."""
    from parley_core import rundir
    from parley_core.selection import controller, select

    if prefer is not None and knee:
        raise OptionError("give --prefer NAME or --knee, not both")
    run = rundir.load(run_dir)
    chosen = select(run, _constraints(constraint), prefer)
    urc = controller(run, chosen)
    target = out or run_dir / "controller.json"
    urc.save(target)
    if json_:
        print(json.dumps({"policy": chosen, "values": dict(urc.values), "controller": str(target)}, indent=2))
    else:
        values = ", ".join(f"{k} {_fmt(v)}" for k, v in urc.values.items())
        Console().print(f"selected {chosen} ({values}); wrote the controller to {target}")


@app.command("simulate")
@_user_errors
def simulate_command(
    target: Annotated[Path, typer.Argument(help="A run directory (of `parley run` or `parley synthesize`), or your PRISM model with --props.")],
    policy: Annotated[Path, typer.Option(help="A controller file (`parley select`) or a policies CSV holding one policy.")],
    props: Annotated[
        Path | None, typer.Option(help="With a PRISM model: the properties to simulate, each after a '// name: NAME, max|min' comment.")
    ] = None,
    episodes: Annotated[int, typer.Option(min=1, help="Simulated runs.")] = 10_000,
    seed: Annotated[int, typer.Option(help="Seed of Storm's simulator.")] = 1,
    max_steps: Annotated[int, typer.Option(min=1, help="Longest episode for unbounded reachability.")] = 10_000,
    json_: JsonOption = False,
) -> None:
    """Simulate a policy with Storm's simulator; print empirical values with 99% intervals next to the model-checked ones."""
    from parley_core.simulate import simulate

    family = _simulated_family(target, policy, props)
    values = _policy_values(policy, family)
    results = simulate(family, values, episodes, seed, max_steps)
    if json_:
        print(json.dumps([r if isinstance(r, str) else {
            "objective": r.objective, "kind": r.kind, "simulated": r.mean, "interval99": [r.low, r.high],
            "model_checked": r.checked, "episodes": r.episodes, "cut": r.cut, "within_interval": bool(r.agrees),
        } for r in results], indent=2))
        return
    table = Table(title=f"{episodes} episodes of Storm's simulator (seed {seed}) against model checking", title_justify="left")
    for column in ("objective", "simulated", "99% interval", "model-checked", "within"):
        table.add_column(column, justify="right" if column != "objective" else "left")
    for r in results:
        if isinstance(r, str):
            table.add_row(r, "", "", "", "")
        else:
            table.add_row(r.objective, _fmt(r.mean), f"{_fmt(r.low)} .. {_fmt(r.high)}", _fmt(r.checked), "yes" if r.agrees else "NO")
    Console().print(table)


def _simulated_family(target: Path, policy: Path, props: Path | None):
    """The family a simulation runs on: a run directory's, or a user's model augmented
    with the controller file's services and observation."""
    from parley_core import rundir
    from parley_core.augment import augment
    from parley_core.runtime import URC
    from parley_core.usermodel import family_of_run, system_from_file

    if target.is_dir():
        if props is not None:
            raise OptionError("--props is for a PRISM model; a run directory has its own properties.pctl")
        return family_of_run(rundir.load(target))
    if not target.is_file():
        raise OptionError(f"{target} does not exist; give a run directory or a PRISM model file")
    if props is None:
        raise OptionError(f"simulating the model {target} needs --props FILE.pctl (the objectives to estimate)")
    if policy.suffix != ".json":
        raise OptionError(f"with a PRISM model, --policy must be a controller file of `parley select` (got {policy})")
    urc = URC.load(policy)
    decisions = [f"{s['constant']}={s['range'][0]}..{s['range'][1]}:{s['kind']}" for s in urc.services]
    system = system_from_file(target, decisions, [",".join(urc.observation)], props)
    return augment(system, prune=True)


def _policy_values(path: Path, family) -> list[int]:
    from parley_core.policies import read_policies
    from parley_core.runtime import URC

    if path.suffix == ".json":
        urc = URC.load(path)
        if tuple(urc.observation) != tuple(family.system.observation):
            raise OptionError(f"controller {path} reads {', '.join(urc.observation)}, the model {', '.join(family.system.observation)}")
        return [urc.decide(d.valuation)[d.service.constant] for d in family.decisions]
    policies = read_policies(path, family)
    if len(policies) != 1:
        raise OptionError(f"policies file {path} holds {len(policies)} policies; give a file with one (or a controller file)")
    return list(policies[0].values)


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



experiment_app = typer.Typer(
    no_args_is_help=True,
    rich_markup_mode=None,
    help="Campaigns: many instances x repetitions, a resumable store, reports (Tables 2 and 3, Fig. 4).",
)
app.add_typer(experiment_app, name="experiment")


@experiment_app.command("run")
@_user_errors
def experiment_run(
    case: Annotated[str, typer.Argument(help="Case study name (see `parley list`).")],
    store: Annotated[Path, typer.Option(help="SQLite results file (created if missing; resumed if present).")],
    reps: Annotated[int, typer.Option(min=1, help="Repetitions per instance (seeds first-seed, first-seed+1, ...).")] = 10,
    grid: Annotated[
        list[str] | None, typer.Option("--grid", metavar="KEY=V1,V2,...", help="Instances: the product of these option values.")
    ] = None,
    instances: Annotated[
        str | None, typer.Option(help="Instances: one per file of a directory or glob (e.g. 'maps/map_*.csv').")
    ] = None,
    instance_option: Annotated[
        str | None, typer.Option(help="The option that receives each --instances file (default: the first file option).")
    ] = None,
    set_: SetOption = None,
    name: Annotated[str | None, typer.Option(help="Campaign name inside the store (default: the case study's name).")] = None,
    population: Annotated[int, typer.Option(min=2)] = 100,
    generations: Annotated[int, typer.Option(min=1)] = 40,
    first_seed: Annotated[int, typer.Option(help="Seed of the first repetition.")] = 1,
    evaluator: EvaluatorOption = "quotient",
    verify: Annotated[
        bool, typer.Option(help="Re-check every front policy with Storm (--no-verify keeps the search's values, and says so).")
    ] = True,
    workers: Annotated[int | None, typer.Option("--workers", "-j", min=1, help="Runs at once on this machine (default: one per core).")] = None,
    scheduler: Annotated[str | None, typer.Option(help="Dask scheduler address (e.g. tcp://host:8786) to run on a cluster.")] = None,
) -> None:
    """Run a campaign; rerunning the same command resumes it, skipping finished runs."""
    from parley_core.experiment.campaign import Budget, describe, execute, instances_from, plan
    from parley_core.experiment.store import Store

    study = _case(case)
    budget = Budget(population=population, generations=generations, evaluator=evaluator, verify=verify)
    chosen = instances_from(study, grid or [], instances, instance_option)
    campaign = name or study.name
    specs = plan(campaign, study, chosen, set_ or [], reps, budget, first_seed)
    with Store(store) as results:
        results.begin_campaign(campaign, study.name, {**describe(budget, set_ or []), "first_seed": first_seed})
        already = len(results.done(campaign) & {(s.instance, s.repetition) for s in specs})
        with _progress() as progress:
            task = progress.add_task(f"campaign {campaign}", total=len(specs), completed=already)
            outcome = execute(specs, results, workers=workers, scheduler=scheduler, on_done=lambda _spec: progress.advance(task))
    Console().print(
        f"campaign {campaign}: {outcome.planned} runs planned, {outcome.skipped} already stored, "
        f"{outcome.stored} stored now, {len(outcome.failures)} failed; results in {store}"
    )
    for instance, repetition, message in outcome.failures[:10]:
        print(f"failed: {instance} repetition {repetition}: {message}", file=sys.stderr)
    if outcome.failures:
        raise typer.Exit(1)


@experiment_app.command("verify")
@_user_errors
def experiment_verify(
    store: Annotated[Path, typer.Option(help="SQLite results file of `parley experiment run`.")],
    name: Annotated[str | None, typer.Option(help="Campaign name (default: the store's only campaign).")] = None,
    workers: Annotated[int | None, typer.Option("--workers", "-j", min=1, help="Processes at once (default: one per core).")] = None,
    repetition: Annotated[
        list[int] | None,
        typer.Option("--repetition", min=0, help="Only these repetitions (repeatable), e.g. 0 for a sample of one per instance."),
    ] = None,
) -> None:
    """Re-check with Storm every stored front not yet checked (runs of --no-verify); resumable."""
    from parley_core.experiment.campaign import is_verified, verify_stored
    from parley_core.experiment.store import Store

    if not store.is_file():
        raise OptionError(f"store {store} does not exist; give the file of `parley experiment run --store`")
    wanted = set(repetition) if repetition else None
    with Store(store) as results:
        campaign, case_name = _pick_campaign(results, store, name)
        selected = [r for r in results.runs(campaign) if wanted is None or r.repetition in wanted]
        with _progress() as progress:
            task = progress.add_task(f"verify {campaign}", total=len(selected))
            progress.update(task, completed=sum(is_verified(r) for r in selected))
            now, before, worst = verify_stored(
                results, campaign, case_name, workers=workers, repetitions=wanted, on_done=lambda _r: progress.advance(task)
            )
    Console().print(
        f"campaign {campaign}: {now} fronts re-checked by Storm now, {before} already were; "
        f"largest difference from the stored values {worst:.1e}"
    )


def _pick_campaign(results, store: Path, name: str | None) -> tuple[str, str]:
    campaigns = results.campaigns()
    if not campaigns:
        raise OptionError(f"store {store} holds no campaign")
    names = [c[0] for c in campaigns]
    chosen = name or (names[0] if len(names) == 1 else None)
    if chosen not in names:
        raise OptionError(f"give --name: store {store} holds campaigns {', '.join(names)}")
    return chosen, next(c[1] for c in campaigns if c[0] == chosen)


@experiment_app.command("report")
@_user_errors
def experiment_report(
    store: Annotated[Path, typer.Option(help="SQLite results file of `parley experiment run`.")],
    out: Annotated[Path, typer.Option(help="Directory for the tables and figures.")],
    name: Annotated[str | None, typer.Option(help="Campaign name (default: the store's only campaign).")] = None,
    setting: Annotated[
        list[str] | None,
        typer.Option("--setting", metavar="B1,B2", help="Requirement setting: worst acceptable value per objective (repeatable)."),
    ] = None,
    published: Annotated[
        Path | None, typer.Option(help="Directory of published fronts ({instance}_rep{R}.front.tsv) to compare with.")
    ] = None,
    figure_setting: Annotated[str | None, typer.Option(metavar="B1,B2", help="Setting of the box plots (default: the paper's 0.7,80 if present, else the first).")] = None,
    force: Annotated[bool, typer.Option(help="Replace the files of an existing --out directory.")] = False,
) -> None:
    """Report a campaign: Table 2 (per setting: better/worse/same than the baseline), box plots, CSV."""
    from parley_core.experiment import report as campaign_report
    from parley_core.experiment.store import Store
    from parley_core.report import check_output

    if not store.is_file():
        raise OptionError(f"store {store} does not exist; give the file of `parley experiment run --store`")
    if published is not None and not published.is_dir():
        raise OptionError(f"--published {published} is not a directory")
    check_output(out, force)
    with Store(store) as results:
        chosen, case_name = _pick_campaign(results, store, name)
        settings_record = next(c[2] for c in results.campaigns() if c[0] == chosen)
        records = list(results.runs(chosen))
    if not records:
        raise OptionError(f"campaign {chosen} in {store} has no finished run yet")
    objectives = [o["name"] for o in records[0].objectives]
    directions = [o["direction"] for o in records[0].objectives]
    if setting:
        settings = [campaign_report.parse_setting(s, len(objectives)) for s in setting]
    else:
        settings = list(_case(case_name).requirement_settings)
        if not settings:
            raise OptionError(f"{case_name} declares no requirement settings; give --setting (one bound per objective)")
    figure = campaign_report.parse_setting(figure_setting, len(objectives)) if figure_setting else (
        (0.7, 80.0) if (0.7, 80.0) in settings else settings[0]
    )
    rows = campaign_report.analyse(records, settings, published)
    header = [f"{n} {'>=' if d == 'max' else '<='}" for n, d in zip(objectives, directions)]
    text = campaign_report.table2_document(chosen, case_name, settings_record, records, rows, settings, header, published is not None)
    out.mkdir(parents=True, exist_ok=True)
    (out / "table2.md").write_text(text)
    (out / "table2.csv").write_text(campaign_report.rows_csv(rows, objectives))
    caption = ", ".join(f"{h} {b:g}" for h, b in zip(header, figure))
    figures = campaign_report.box_plots(rows, figure, caption, out / "gains")
    Console().print(text)
    Console().print(f"wrote {out}/table2.md, table2.csv and {len(figures)} figures")


@experiment_app.command("scalability")
@_user_errors
def experiment_scalability(
    case: Annotated[str, typer.Argument(help="Case study name (see `parley list`).")],
    sizes: Annotated[str, typer.Option(help="Comma-separated values of the size option, e.g. 5,10,15,20,30,50.")] = "5,10,15,20,30,50",
    option: Annotated[str, typer.Option(help="The option the sizes go to.")] = "size",
    set_: SetOption = None,
    storm_policies: Annotated[
        int, typer.Option(min=1, help="Policies timed with the Storm evaluator per size (a 50x50 robot_grid policy takes about 30 s).")
    ] = 10,
    out: Annotated[Path | None, typer.Option(help="Directory for table3.md and table3.json.")] = None,
) -> None:
    """Table 3: model size, per-policy time of both evaluators, search time and search space per size."""
    from parley_core.experiment.scalability import measure_isolated, table3_markdown

    study = _case(case)
    try:
        values = [int(v) for v in sizes.split(",")]
    except ValueError:
        raise OptionError(f"malformed --sizes {sizes!r}; give integers such as 5,10,20") from None
    for v in values:
        study.options([*(set_ or []), f"{option}={v}"])
    rows = []
    with _progress() as progress:
        task = progress.add_task("scalability", total=len(values))
        for v in values:
            row = measure_isolated(study.name, [*(set_ or []), f"{option}={v}"], storm_policies=storm_policies)
            row["instance"] = f"{option}={v}"
            rows.append(row)
            progress.advance(task)
    table = table3_markdown(rows)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "table3.md").write_text(table)
        (out / "table3.json").write_text(json.dumps(rows, indent=2))
    Console().print(table)
