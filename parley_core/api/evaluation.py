"""The commands that look at given policies, as functions: :func:`case_studies`
(``parley list``), :func:`evaluate` (``parley evaluate``), :func:`baseline` (``parley
baseline``) and :func:`augment` (``parley augment``). A run's own policies are simulated and
validated from the :class:`~parley_core.api.runs.Run` (``run.simulate()``, ``run.validate()``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from parley_core.api.commands import assignments_of, decision_specs, prepare_case
from parley_core.evaluate import EvaluatorKind
from parley_core.model import Family, Policy, Valued
from parley_core.plugin.casestudy import CaseStudy
from parley_core.progress import Reporter
from parley_core.views.richprogress import reporting


def case_studies() -> dict[str, CaseStudy]:
    """Every registered case study by name (built in and from installed plugins)."""
    from parley_core.plugin.manager import load_registry

    found = load_registry()
    return {name: found.case_studies[name] for name in found.names}


def evaluate(
    case: str,
    *,
    policies: str | Path | Sequence[Policy] | None = None,
    constant: int | None = None,
    evaluator: str = EvaluatorKind.QUOTIENT.value,
    workers: int | None = None,
    progress: bool | Reporter = True,
    options: Mapping[str, Any] | None = None,
    **more_options: Any,
) -> Valued:
    """The objective values of ``policies`` (a policies CSV, such as a run's policies.csv, or
    :class:`~parley_core.model.Policy` objects of the case study's family) or of the one
    policy that uses ``constant`` everywhere."""
    from parley_core.evaluate import evaluate_policies, make_evaluator
    from parley_core.rundir.policies import policies_or_constant

    kind = EvaluatorKind.of(evaluator)
    assignments = assignments_of({**(options or {}), **more_options})
    with reporting(progress) as reporter:
        prepared = prepare_case(case, assignments, reporter)
        if policies is not None and not isinstance(policies, (str, Path)):
            chosen = list(policies)
            if constant is not None:
                from parley_core.errors import PolicyError

                raise PolicyError("give exactly one of policies and constant")
        else:
            chosen = policies_or_constant(prepared.family, None if policies is None else Path(policies), constant)
        reporter.stage(f"{kind.value} evaluator")
        engine = make_evaluator(prepared.family, kind, workers)
        try:
            values = evaluate_policies(prepared.family, chosen, engine, reporter, stage=f"evaluate ({kind.value})")
        except BaseException:
            engine.close(abort=True)
            raise
        engine.close()
        return values


def baseline(
    case: str,
    *,
    workers: int | None = None,
    progress: bool | Reporter = True,
    options: Mapping[str, Any] | None = None,
    **more_options: Any,
) -> Valued:
    """The case study's baseline policies (fixed frequency or threshold), checked by Storm."""
    from parley_core.evaluate import evaluate_policies
    from parley_core.evaluate.storm import StormEvaluator

    assignments = assignments_of({**(options or {}), **more_options})
    with reporting(progress) as reporter:
        family = prepare_case(case, assignments, reporter).family
        with StormEvaluator(family, workers=workers) as storm:
            return evaluate_policies(family, family.baseline_policies(), storm, reporter, stage="baselines (Storm)")


def check_format(format: str) -> None:
    """Refuse an export format other than prism, evochecker or paynt (before any model is read)."""
    from parley_core.errors import OptionError
    from parley_core.prism.writer import FORMATS

    if format not in FORMATS:
        raise OptionError(f"unknown --format {format!r}; valid: {', '.join(FORMATS)}")


def augmented_family(
    model: str | Path, decisions: Mapping[str, tuple[int, int] | str] | Sequence[str], observe: Sequence[str] = ()
) -> Family:
    """A PRISM DTMC's family, kept to the observation valuations that consult a service."""
    from parley_core.family.prepare import make_family
    from parley_core.family.usermodel import system_from_file

    return make_family(system_from_file(Path(model), decision_specs(decisions), list(observe)), prune=True)


def augment(
    model: str | Path,
    *,
    decisions: Mapping[str, tuple[int, int] | str] | Sequence[str],
    observe: Sequence[str] = (),
    format: str = "prism",
) -> str:
    """The parametric model of a PRISM DTMC: one decision constant per service and
    reachable observation valuation (``format``: prism, evochecker or paynt)."""
    from parley_core.family.augment import export

    check_format(format)
    return export(augmented_family(model, decisions, observe), format)
