"""Commands that evaluate given policies: evaluate, baseline."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from parley_core.cli.app import app
from parley_core.cli.common import case_study, prepare_case, user_errors
from parley_core.cli.console import RichReporter, front_table, stderr, values_json
from parley_core.cli.options import CaseArgument, EvaluatorOption, JsonOption, SetOption, WorkersOption
from parley_core.evaluate import EvaluatorKind


@app.command("evaluate")
@user_errors
def evaluate_command(
    case: CaseArgument,
    set_: SetOption = None,
    policies: Annotated[
        Path | None,
        typer.Option(help="CSV: policy, observation variables, one column per service (or a run's policies.csv)."),
    ] = None,
    constant: Annotated[int | None, typer.Option(help="Evaluate the policy that uses this value everywhere.")] = None,
    evaluator: EvaluatorOption = EvaluatorKind.QUOTIENT.value,
    json_: JsonOption = False,
    workers: WorkersOption = None,
) -> None:
    """Evaluate policies and print their objective values."""
    from parley_core.api.evaluation import evaluate
    from parley_core.plugin.options import parse_assignments

    kind = EvaluatorKind.of(evaluator)
    options = parse_assignments(set_ or [])
    with RichReporter(stderr()) as reporter:
        front = evaluate(
            case,
            policies=policies,
            constant=constant,
            evaluator=evaluator,
            workers=workers,
            progress=reporter,
            options=options,
        )
    study = case_study(case)
    chosen = study.options_from(options)
    if json_:
        document = values_json(study, chosen, front)
        document["evaluator"] = kind.value
        print(json.dumps(document, indent=2))
    else:
        Console().print(front_table(f"values ({kind.value} evaluator)", front, limit=10_000))


@app.command("baseline")
@user_errors
def baseline_command(
    case: CaseArgument,
    set_: SetOption = None,
    json_: JsonOption = False,
    workers: WorkersOption = None,
) -> None:
    """Evaluate the case study's baseline policies (fixed frequency or threshold) with Storm."""
    from parley_core.evaluate import evaluate_policies
    from parley_core.evaluate.storm import StormEvaluator

    with RichReporter(stderr()) as reporter:
        prepared = prepare_case(case, set_, reporter)
        family = prepared.family
        with StormEvaluator(family, workers=workers) as storm:
            front = evaluate_policies(family, family.baseline_policies(), storm, reporter, stage="baselines (Storm)")
    decisions = [dict(b.values) for b in family.baselines]
    if json_:
        print(json.dumps(values_json(prepared.case, prepared.options, front, decisions), indent=2))
    else:
        constants = [s.constant for s in family.services]
        columns = {c: [d[c] for d in decisions] for c in constants}
        Console().print(front_table("Baseline", front, columns, limit=10_000))
