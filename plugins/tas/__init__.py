"""tas: the Tele Assistance System exemplar (Weyns & Calinescu, SEAMS 2015).

A patient's device asks a medical analysis service to analyze vital parameters (or the
panic button raises an alarm); the analysis may ask the drug service to change the drug or
the dose, or the alarm service to send an alarm. When the primary analysis provider fails,
the workflow fails over to a backup provider, whose health drifts unseen; the
uncertainty-aware controller (UAC) picks the backup or a dearer, stable alternative by its
*estimate* of the backup's health. A probe (a test invocation of the backup, at a cost)
makes the estimate exact (or, with ``probe_error``, misreports the level now and then). The
URC decides, per estimated backup level and load phase, after how many executions to probe
(or never). See docs/tas.md.
"""

from __future__ import annotations

from pathlib import Path

from attrs import frozen, validators

from parley_core import (
    Baseline,
    CaseStudy,
    DecisionKind,
    Direction,
    Objective,
    OptionError,
    PolicyTable,
    Service,
    SystemModel,
    hookimpl,
    option,
    positive,
    probability,
)
from parley_plugins.tas.generator import PROVIDERS, Scenario, prism_model

MAS1, MAS5 = PROVIDERS["MAS1"], PROVIDERS["MAS5"]


@frozen(kw_only=True)
class TasOptions:
    rounds: int = option(30, "workflow executions the objectives average over", positive)
    max_interval: int = option(
        10, "largest probing interval (executions); the URC may also choose max_interval+1: never probe", positive
    )
    backup_levels: str = option(
        f"{MAS5.failure_rate:g},0.3,1.0",
        "failure rate of the backup (MAS5) per health level, comma-separated, from healthy (the table's) to worst",
    )
    degrade: float = option(0.05, "per execution, probability that the backup gets one level worse", probability)
    recover: float = option(0.1, "per execution, probability that the backup gets one level better", probability)
    peak_start: float = option(0.1, "per execution, probability that normal load turns to peak load", probability)
    peak_end: float = option(0.2, "per execution, probability that peak load turns to normal", probability)
    primary_failure: float = option(
        MAS1.failure_rate, "failure rate of the primary provider (MAS1) at normal load", probability
    )
    primary_failure_peak: float = option(
        2 * MAS1.failure_rate,
        "failure rate of the primary provider at peak load (assumed: twice the table's)",
        probability,
    )
    p_vital: float = option(
        0.75,
        "probability that an execution analyzes vital parameters, else it is a panic-button alarm (TAS: 0.75)",
        probability,
    )
    p_alarm: float = option(1 / 3, "probability that an analysis asks for an alarm (TAS: 1/3)", probability)
    p_drug: float = option(1 / 3, "probability that an analysis asks for a drug change (TAS: 1/3)", probability)
    p_dose: float = option(
        1 / 3, "probability that an analysis asks for a dose change (TAS: 1/3); the rest: patient ok", probability
    )
    probe_cost: float = option(MAS5.cost, "cost of a probe (a test invocation of the backup)", validators.ge(0.0))
    probe_error: float = option(
        0.0,
        "probability that a probe misreports the backup's level (then each other level equally likely)",
        probability,
    )
    response_time: bool = option(False, "add a third objective: expected response time per execution (ms)")


def scenario(options: TasOptions) -> Scenario:
    """The checked scenario of ``options``; OptionError says what to change."""
    try:
        levels = tuple(float(part) for part in options.backup_levels.split(","))
    except ValueError:
        raise OptionError(
            f"backup_levels={options.backup_levels!r}: give failure rates separated by commas, e.g. 0.05,0.3,1.0"
        ) from None
    if not 2 <= len(levels) <= 6 or not all(0.0 <= rate <= 1.0 for rate in levels):
        raise OptionError(f"backup_levels={options.backup_levels!r}: give 2 to 6 failure rates, each in 0..1")
    if options.degrade + options.recover > 1.0:
        raise OptionError(f"degrade + recover = {options.degrade + options.recover:g} exceeds 1; lower one of them")
    if options.p_alarm + options.p_drug + options.p_dose > 1.0 + 1e-12:
        raise OptionError("p_alarm + p_drug + p_dose exceeds 1; they are probabilities of distinct analysis results")
    return Scenario(
        rounds=options.rounds,
        max_interval=options.max_interval,
        backup_levels=levels,
        degrade=options.degrade,
        recover=options.recover,
        peak_start=options.peak_start,
        peak_end=options.peak_end,
        primary_failure=options.primary_failure,
        primary_failure_peak=options.primary_failure_peak,
        p_vital=options.p_vital,
        p_alarm=options.p_alarm,
        p_drug=options.p_drug,
        p_dose=options.p_dose,
        probe_cost=options.probe_cost,
        probe_error=options.probe_error,
    )


def build(options: TasOptions) -> SystemModel:
    s = scenario(options)
    horizon = s.horizon
    never = s.max_interval + 1
    objectives = [
        Objective(
            name="failure",
            formula=f'R{{"failures"}}=? [C<={horizon}]',
            direction=Direction.MIN,
            description=f"probability that a workflow execution fails, averaged over the first {s.rounds} executions",
        ),
        Objective(
            name="cost",
            formula=f'R{{"cost"}}=? [C<={horizon}]',
            direction=Direction.MIN,
            description=f"expected cost per execution (provider invocations and probes), over the first {s.rounds} executions",
        ),
    ]
    if options.response_time:
        objectives.append(
            Objective(
                name="response_time",
                formula=f'R{{"time"}}=? [C<={horizon}]',
                direction=Direction.MIN,
                description="expected response time per execution (ms), over the same executions",
            )
        )
    return SystemModel(
        name="tas",
        description=f"TAS, {s.rounds} executions, backup levels {','.join(f'{r:g}' for r in s.backup_levels)}",
        prism=prism_model(s),
        services=[
            Service(
                name="probe",
                constant="c",
                kind=DecisionKind.FREQUENCY,
                low=1,
                high=never,
                description=f"probe the backup once the execution counter reaches c (every c-th execution); {never} = never",
            )
        ],
        observation=("bhat", "load"),
        objectives=objectives,
        baselines=[
            *Baseline.sweep("c", range(1, s.max_interval + 1), "every-{}"),
            Baseline(name="never", values={"c": never}),
        ],
        context=s,
    )


def plot_policy(system: SystemModel, table: PolicyTable, path: Path) -> None:
    from parley_plugins.tas.plot import draw_policy

    draw_policy(system.context, table.values_of("c"), path)


CASE_STUDY = CaseStudy(
    name="tas",
    description="Tele Assistance System: how often to probe a drifting backup service (Weyns & Calinescu 2015)",
    options_type=TasOptions,
    build=build,
    plot_policy=plot_policy,
    quick={"rounds": "6", "max_interval": "3"},
)


@hookimpl
def parley_case_studies() -> list[CaseStudy]:
    return [CASE_STUDY]
