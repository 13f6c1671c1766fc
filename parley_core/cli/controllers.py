"""Commands about controllers: select one from a front, simulate one."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from parley_core.cli.app import app
from parley_core.cli.common import constraints, user_errors
from parley_core.cli.console import fmt
from parley_core.cli.options import ConstraintOption, JsonOption
from parley_core.errors import OptionError


@app.command("select")
@user_errors
def select_command(
    run_dir: Annotated[Path, typer.Argument(help="A run directory of `parley run` or `parley synthesize`.")],
    constraint: ConstraintOption = None,
    prefer: Annotated[
        str | None, typer.Option(help="Take the best policy on this objective (among those meeting the constraints).")
    ] = None,
    knee: Annotated[
        bool, typer.Option("--knee", help="Take the knee point (the default when --prefer is not given).")
    ] = False,
    out: Annotated[
        Path | None, typer.Option(help="Controller file to write (default: RUN_DIR/controller.json).")
    ] = None,
    json_: JsonOption = False,
) -> None:
    """Pick one policy from a front (best on an objective under constraints, or the knee) and write it as a
    controller."""
    from parley_core import rundir
    from parley_core.selection import controller, select

    if prefer is not None and knee:
        raise OptionError("give --prefer NAME or --knee, not both")
    run = rundir.load(run_dir)
    chosen = select(run, constraints(constraint), prefer)
    urc = controller(run, chosen)
    target = out or run_dir / "controller.json"
    urc.save(target)
    if json_:
        print(json.dumps({"policy": chosen, "values": dict(urc.values), "controller": str(target)}, indent=2))
    else:
        values = ", ".join(f"{k} {fmt(v)}" for k, v in urc.values.items())
        Console().print(f"selected {chosen} ({values}); wrote the controller to {target}")


@app.command("simulate")
@user_errors
def simulate_command(
    target: Annotated[
        Path,
        typer.Argument(
            help="A run directory (of `parley run` or `parley synthesize`), or your PRISM model with --props."
        ),
    ],
    policy: Annotated[
        list[Path],
        typer.Option(
            help="A controller file (`parley select`) or a policies CSV holding one policy; with --drift, "
            "repeat it for each controller to compare (plain or adaptive: `parley adapt`)."
        ),
    ],
    props: Annotated[
        Path | None,
        typer.Option(
            help="With a PRISM model: the properties to simulate, each after a '// name: NAME, max|min' comment."
        ),
    ] = None,
    episodes: Annotated[
        int | None, typer.Option(min=2, help="Simulated runs (default 10000); with --drift, systems (default 200).")
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of Storm's simulator.")] = 1,
    max_steps: Annotated[int, typer.Option(min=1, help="Longest episode for unbounded reachability.")] = 10_000,
    drift: Annotated[
        str | None,
        typer.Option(
            metavar="NAME=FROM:TO@MISSION",
            help="A drifting environment: the model constant NAME goes from FROM to TO at mission MISSION "
            "(or linearly over missions BEGIN-END); each system runs --missions missions and every controller is "
            "compared; writes drift.json and drift.png (in --out, default the run directory).",
        ),
    ] = None,
    missions: Annotated[
        int | None, typer.Option(min=2, help="With --drift: missions per system (default: twice the drift's end).")
    ] = None,
    out: Annotated[Path | None, typer.Option(help="With --drift: where to write drift.json and drift.png.")] = None,
    json_: JsonOption = False,
) -> None:
    """Simulate a policy with Storm's simulator; print empirical values with 99% intervals next to the
    model-checked ones. With --drift: fixed, robust and adaptive controllers mission after mission while a
    parameter drifts."""
    from parley_core.policies import policy_from_file
    from parley_core.simulate import simulate

    if drift is not None:
        _simulate_drift(target, policy, drift, missions, episodes or 200, seed, max_steps, out, json_)
        return
    if missions is not None or out is not None:
        raise OptionError("--missions and --out are for --drift; give --drift NAME=FROM:TO@MISSION")
    if len(policy) != 1:
        raise OptionError(f"give one --policy (got {len(policy)}); several are for --drift")
    episodes = episodes or 10_000
    family = _simulated_family(target, policy[0], props)
    values = policy_from_file(policy[0], family).values
    results = simulate(family, values, episodes, seed, max_steps)
    if json_:
        document = [
            r
            if isinstance(r, str)
            else {
                "objective": r.objective,
                "kind": r.kind,
                "simulated": r.mean,
                "interval99": [r.low, r.high],
                "model_checked": r.checked,
                "episodes": r.episodes,
                "cut": r.cut,
                "within_interval": bool(r.agrees),
            }
            for r in results
        ]
        print(json.dumps(document, indent=2))
        return
    table = Table(
        title=f"{episodes} episodes of Storm's simulator (seed {seed}) against model checking", title_justify="left"
    )
    for column in ("objective", "simulated", "99% interval", "model-checked", "within"):
        table.add_column(column, justify="right" if column != "objective" else "left")
    for r in results:
        if isinstance(r, str):
            table.add_row(r, "", "", "", "")
        else:
            table.add_row(
                r.objective, fmt(r.mean), f"{fmt(r.low)} .. {fmt(r.high)}", fmt(r.checked), "yes" if r.agrees else "NO"
            )
    Console().print(table)


def _simulate_drift(
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
    from parley_core import rundir
    from parley_core.adaptive import AdaptiveController, is_adaptive
    from parley_core.cli.common import registry
    from parley_core.cli.console import RichReporter, stderr
    from parley_core.drift import Drift, plot, simulate_drift, to_json
    from parley_core.urc import URC
    from parley_core.usermodel import family_of_run

    drift = Drift.parse(spec)
    if not target.is_dir():
        raise OptionError(f"--drift simulates the controllers on a run directory's model; {target} is not one")
    run = rundir.load(target)
    family = family_of_run(run)
    controllers = []
    for path in policies:
        controller = AdaptiveController.load(path) if is_adaptive(path) else URC.load(path)
        controllers.append((path.stem, controller))
    if len({name for name, _ in controllers}) != len(controllers):
        raise OptionError("two --policy files have the same name; give each controller its own file name")
    case = registry().case_studies.get(str(run.summary.get("case_study", "")))
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
    from parley_core import rundir
    from parley_core.adaptive import AdaptiveController, Estimator
    from parley_core.selection import controller, select

    if len(runs) < 2:
        raise OptionError("give two or more run directories, one per value of the parameter")
    if forgetting <= 0:
        raise OptionError("--forgetting must be above 0 (1: never forget)")
    loaded = [rundir.load(path) for path in runs]
    first = loaded[0]
    values = []
    for path, run in zip(runs, loaded):
        options = run.summary.get("options", {})
        if parameter not in options:
            raise OptionError(f"run {path} has no option {parameter!r}; its options: {', '.join(options) or 'none'}")
        if run.summary.get("case_study") != first.summary.get("case_study") or run.decisions != first.decisions:
            raise OptionError(f"run {path} is of another case study or decides other things than {runs[0]}")
        others = {k: v for k, v in options.items() if k != parameter}
        base = {k: v for k, v in first.summary.get("options", {}).items() if k != parameter}
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
        from parley_core.drift import calibrate
        from parley_core.usermodel import family_of_run

        case = registry().case_studies.get(str(first.summary.get("case_study", "")))
        events = case.events.get(parameter) if case is not None else None
        if events is None:
            raise OptionError(
                f"no event model for {parameter} (the case study's plugin says what the system observes about it); "
                "an adaptive controller cannot estimate it"
            )
        with RichReporter(stderr()) as reporter:
            found = calibrate(
                [family_of_run(loaded[i]) for i in order],
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


def _simulated_family(target: Path, policy: Path, props: Path | None):
    """The family a simulation runs on: a run directory's, or a user's model augmented
    with the controller file's services and observation."""
    from parley_core import rundir
    from parley_core.simulate import family_for_controller
    from parley_core.urc import URC
    from parley_core.usermodel import family_of_run

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
    return family_for_controller(target, URC.load(policy), props)


@app.command("validate")
@user_errors
def validate_command(
    run_dir: Annotated[Path, typer.Argument(help="A run directory of `parley run` for a case study with a simulator.")],
    policy: Annotated[
        str,
        typer.Option(
            help="The front policy to run: 'knee' (the knee point), its name in front.csv (p12) or its row there (1: the first)."
        ),
    ] = "knee",
    episodes: Annotated[int, typer.Option(min=2, help="Closed-loop episodes per policy.")] = 1000,
    seed: Annotated[int, typer.Option(help="Seed of the simulator.")] = 1,
    baselines: Annotated[bool, typer.Option(help="Run the run's baselines too.")] = True,
    json_: JsonOption = False,
) -> None:
    """Run a policy (and the baselines) in closed loop on the case study's simulator (turtlebot: MuJoCo) and set
    the empirical values with 99% intervals next to Storm's; writes RUN_DIR/validation.json and validation.png."""
    from parley_core.cli.console import RichReporter, stderr
    from parley_core.validate import plot, validate

    with RichReporter(stderr()) as reporter:
        result = validate(run_dir, policy, episodes, seed, baselines, reporter)
        reporter.stage("write report")
        document = result.to_json()
        (run_dir / "validation.json").write_text(json.dumps(document, indent=2) + "\n")
        plot(result, run_dir / "validation.png")
    if json_:
        print(json.dumps(document, indent=2))
        return
    table = Table(
        title=f"{episodes} closed-loop episodes a policy ({result.simulator}, seed {seed}) against Storm",
        title_justify="left",
    )
    for column in ("policy", "objective", "closed loop", "99% interval", "Storm", "Storm within"):
        table.add_column(column, justify="left" if column in ("policy", "objective") else "right")
    outside = []
    for p in result.policies:
        for e in p.estimates:
            table.add_row(
                p.policy if p.role == "baseline" else f"{p.policy} (chosen)",
                e.objective,
                fmt(e.mean),
                f"{fmt(e.low)} .. {fmt(e.high)}",
                fmt(e.checked),
                "yes" if e.agrees else "NO",
            )
            if not e.agrees:
                outside.append(f"{p.policy} {e.objective}")
    console = Console()
    console.print(table)
    for p in result.policies:
        for note in p.notes:
            console.print(f"{p.policy}: {note}")
    if outside:
        console.print(
            f"Storm's value lies outside the closed-loop interval for {len(outside)} of "
            f"{sum(len(p.estimates) for p in result.policies)} estimates ({', '.join(outside[:6])}"
            f"{', ...' if len(outside) > 6 else ''}): the model's abstraction differs from the simulated system there"
        )
    console.print(f"wrote {run_dir / 'validation.json'} and {run_dir / 'validation.png'}")
