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
    from parley_core.rundir import read
    from parley_core.rundir.select import controller, select

    if prefer is not None and knee:
        raise OptionError("give --prefer NAME or --knee, not both")
    run = read.load(run_dir)
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
    from parley_core.rundir.policies import policy_from_file
    from parley_core.simulation.storm import simulate

    if drift is not None:
        from parley_core.cli.adaptation import simulate_drift_command

        simulate_drift_command(target, policy, drift, missions, episodes or 200, seed, max_steps, out, json_)
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


def _simulated_family(target: Path, policy: Path, props: Path | None):
    """The family a simulation runs on: a run directory's, or a user's model augmented
    with the controller file's services and observation."""
    from parley_core.rundir import read
    from parley_core.simulation.storm import family_for_controller
    from parley_core.urc.controller import URC

    if target.is_dir():
        if props is not None:
            raise OptionError("--props is for a PRISM model; a run directory has its own properties.pctl")
        return read.load(target).family()
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
    from parley_core.simulation.validate import plot, validate

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


@app.command("report")
@user_errors
def report_command(
    run_dir: Annotated[Path, typer.Argument(help="A run directory of `parley run`, `exact` or `synthesize`.")],
    out: Annotated[Path | None, typer.Option(help="Page to write (default: RUN_DIR/report.html).")] = None,
) -> None:
    """Write the interactive report.html of a run directory (again, or for one written before it existed)."""
    from parley_core.rundir.page import REPORT, render
    from parley_core.rundir.read import load

    target = out or run_dir / REPORT
    page = render(load(run_dir))
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(page, encoding="utf-8")
    Console().print(f"wrote {target}")
