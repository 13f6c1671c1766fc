"""Commands about a drifting model: adapt (an adaptive controller from runs) and the drift
mode of simulate (`parley simulate RUN_DIR --drift ...`, dispatched from :mod:`.controllers`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from parley_core.cli.app import app
from parley_core.cli.common import constraints, user_errors
from parley_core.cli.options import ConstraintOption
from parley_core.errors import OptionError


def simulate_drift_command(
    target: Path,
    policies: list[Path],
    spec: str,
    missions: int | None,
    episodes: int,
    seed: int,
    max_steps: int,
    out: Path | None,
    json_: bool,
) -> None:
    from parley_core.cli.common import registry
    from parley_core.cli.console import RichReporter, stderr
    from parley_core.rundir import read
    from parley_core.simulation.drift import Drift, simulate_drift
    from parley_core.simulation.drift_report import plot, to_json
    from parley_core.urc.adaptive import load_controller

    drift = Drift.parse(spec)
    if not target.is_dir():
        raise OptionError(f"--drift simulates the controllers on a run directory's model; {target} is not one")
    run = read.load(target)
    family = run.family()
    controllers = []
    for path in policies:
        controllers.append((path.stem, load_controller(path)))
    if len({name for name, _ in controllers}) != len(controllers):
        raise OptionError("two --policy files have the same name; give each controller its own file name")
    case = registry().case_studies.get(run.case_study)
    events = case.events.get(drift.parameter) if case is not None else None
    missions = missions or max(2, 2 * drift.end)
    with RichReporter(stderr()) as reporter:
        result = simulate_drift(
            family,
            drift,
            controllers,
            events,
            missions=missions,
            episodes=episodes,
            seed=seed,
            max_steps=max_steps,
            reporter=reporter,
        )
        reporter.stage("write report")
        out = out or target
        out.mkdir(parents=True, exist_ok=True)
        document = to_json(result)
        (out / "drift.json").write_text(json.dumps(document, indent=2) + "\n")
        plot(result, out / "drift.png")
    if json_:
        print(json.dumps(document, indent=2))
        return
    table = Table(
        title=f"{episodes} systems x {missions} missions, drift {drift} (seed {seed}): means with 99% intervals",
        title_justify="left",
    )
    for column in ("controller", "missions", *result.objectives):
        table.add_column(column, justify="left" if column == "controller" else "right")
    for entry in document["controllers"]:
        for phase, found in entry["phases"].items():
            first, last = found["missions"]
            cells = [
                f"{found[o]['mean']:.4g} [{found[o]['low']:.4g}, {found[o]['high']:.4g}]" for o in result.objectives
            ]
            table.add_row(entry["name"], f"{phase} the drift ({first}-{last - 1})", *cells)
    storm = Table(title="Storm's values of the controllers' policies", title_justify="left")
    for column in ("controller", "policy", drift.parameter, *result.objectives):
        storm.add_column(column, justify="left" if column in ("controller", "policy") else "right")
    for series in result.series:
        for (policy, level), values in series.checked.items():
            if level in (result.levels[0], result.levels[-1]):
                storm.add_row(series.name, policy, f"{level:g}", *(f"{v:.4g}" for v in values))
    console = Console()
    console.print(table)
    console.print(storm)
    for series in result.series:
        if series.in_force.shape[1] > 1:
            final = series.in_force[-1] / episodes
            shares = ", ".join(f"{p} {100 * f:.0f}%" for p, f in zip(series.policies, final))
            console.print(f"{series.name}: policies in force at the last mission: {shares}")
        if series.cut:
            console.print(f"{series.name}: {series.cut} episodes stopped at --max-steps {max_steps} before a sink")
    console.print(f"wrote {out / 'drift.json'} and {out / 'drift.png'}")


@app.command("adapt")
@user_errors
def adapt_command(
    runs: Annotated[
        list[Path], typer.Argument(help="Run directories of one case study that differ in one option's value.")
    ],
    parameter: Annotated[str, typer.Option(help="The option (a model constant) the runs differ in, e.g. p.")],
    constraint: ConstraintOption = None,
    prefer: Annotated[
        str | None,
        typer.Option(help="Per run, take the best policy on this objective (among those meeting the constraints)."),
    ] = None,
    forgetting: Annotated[
        float, typer.Option(min=0.0, max=1.0, help="Each mission's end multiplies the log-likelihoods by this.")
    ] = 0.9,
    hysteresis: Annotated[
        float, typer.Option(min=0.0, help="Switch when another value is this much more likely (log-likelihood).")
    ] = 2.0,
    calibration: Annotated[
        int,
        typer.Option(
            min=0,
            help="Missions per policy and value that calibrate the estimator on the model (0: use the event model's "
            "own probabilities).",
        ),
    ] = 1000,
    out: Annotated[Path, typer.Option(help="Adaptive controller file to write.")] = Path("adaptive.json"),
) -> None:
    """An adaptive URC: from each run (one value of a drifting parameter each) the policy `parley select` would
    pick, switched at runtime to the most likely value's; the first run's value is in force at the start."""
    from parley_core.rundir import read
    from parley_core.rundir.select import controller, select
    from parley_core.urc.adaptive import AdaptiveController, Estimator

    if len(runs) < 2:
        raise OptionError("give two or more run directories, one per value of the parameter")
    if forgetting <= 0:
        raise OptionError("--forgetting must be above 0 (1: never forget)")
    loaded = [read.load(path) for path in runs]
    first = loaded[0]
    values = []
    for path, run in zip(runs, loaded):
        options = run.summary.options
        if parameter not in options:
            raise OptionError(f"run {path} has no option {parameter!r}; its options: {', '.join(options) or 'none'}")
        if run.case_study != first.case_study or run.decisions != first.decisions:
            raise OptionError(f"run {path} is of another case study or decides other things than {runs[0]}")
        others = {k: v for k, v in options.items() if k != parameter}
        base = {k: v for k, v in first.summary.options.items() if k != parameter}
        if others != base:
            differ = sorted(k for k in set(others) | set(base) if others.get(k) != base.get(k))
            raise OptionError(
                f"run {path} differs from {runs[0]} in {', '.join(differ)} too; only {parameter} may differ"
            )
        try:
            values.append(float(options[parameter]))
        except (TypeError, ValueError):
            raise OptionError(f"run {path}: option {parameter}={options[parameter]!r} is not a number") from None
    urcs = [controller(run, select(run, constraints(constraint), prefer)) for run in loaded]
    order = sorted(range(len(values)), key=lambda i: values[i])
    found = None
    if calibration:
        from parley_core.cli.common import registry
        from parley_core.cli.console import RichReporter, stderr
        from parley_core.simulation.drift import calibrate

        case = registry().case_studies.get(first.case_study)
        events = case.events.get(parameter) if case is not None else None
        if events is None:
            raise OptionError(
                f"no event model for {parameter} (the case study's plugin says what the system observes about it); "
                "an adaptive controller cannot estimate it"
            )
        with RichReporter(stderr()) as reporter:
            found = calibrate(
                [loaded[i].family() for i in order],
                parameter,
                [values[i] for i in order],
                [urcs[i] for i in order],
                events,
                missions=calibration,
                reporter=reporter,
            )
    adaptive = AdaptiveController(
        parameter=parameter,
        values=[values[i] for i in order],
        controllers=[urcs[i] for i in order],
        estimator=Estimator(forgetting=forgetting, hysteresis=hysteresis),
        start=order.index(0),
        calibration=found,
    )
    adaptive.save(out)
    chosen = ", ".join(f"{parameter}={values[i]:g}: {urcs[i].policy}" for i in order)
    Console().print(
        f"adaptive controller over {parameter} ({chosen}); starts with {parameter}={values[0]:g}; wrote {out}"
    )
