"""A case study prepared for a run: its system model built and augmented (pruned where the
case study asks), once, or once per scenario of a robust run.

Every stage that needs a family starts here (:func:`make_family`): the pipeline, Storm's
simulator, closed-loop validation, the test kit and campaigns' scalability runs.
"""

from __future__ import annotations

from typing import Any

from attrs import field, frozen

from parley_core.family.augment import augment
from parley_core.family.scenarios import ScenarioModel, ScenarioSet, scenario_options
from parley_core.model import Family, SystemModel
from parley_core.plugin.casestudy import CaseStudy
from parley_core.progress import NullReporter, Reporter, timed


@frozen(kw_only=True)
class Prepared:
    case: CaseStudy
    options: Any
    system: SystemModel
    family: Family
    timings: dict[str, float] = field(factory=dict)
    scenarios: tuple[ScenarioModel, ...] = ()
    """A robust run's scenarios (:mod:`parley_core.robust`); ``options``, ``system`` and
    ``family`` are then the first scenario's. Empty: an ordinary run."""


def make_family(system: SystemModel, *, prune: bool = False) -> Family:
    """Augment ``system``; with ``prune``, only at the observation valuations where some
    reachable state of some policy consults a service (found on the quotient MDP)."""
    from parley_core.prism import program as prism
    from parley_core.prism.properties import check_objectives, name_unnamed_rewards

    parsed = prism.parse_program(system.prism, origin=f"the {system.name} model")
    check_objectives(system, parsed)
    system = name_unnamed_rewards(system, parsed)
    family = augment(system)  # also checks the model before Storm builds its quotient
    if prune:
        from parley_core.quotient.mdp import build_mdp, consulted_valuations

        kept = consulted_valuations(build_mdp(system))
        if len(kept) < len(family.valuations):
            family = augment(system, valuations=kept)
    return family


def prepare(case: CaseStudy, options: Any, reporter: Reporter | None = None) -> Prepared:
    """Build the case study's system model and augment it (pruned if the case study asks)."""
    reporter = reporter or NullReporter()
    timings: dict[str, float] = {}
    system, family = _build(case, options, reporter, timings)
    if family.left_out:
        reporter.note(f"{len(family.left_out)} observation valuations never consult a service and are left out")
    for note in family.system.notes if family.system else ():
        reporter.note(note)
    return Prepared(case=case, options=options, system=system, family=family, timings=timings)


def prepare_scenarios(
    case: CaseStudy, assignments: dict[str, str], scenarios: ScenarioSet, reporter: Reporter | None = None
) -> Prepared:
    """A robust run's models: the case study built and augmented once per scenario (each
    scenario's option values over ``assignments``, the run's ``--set``)."""
    reporter = reporter or NullReporter()
    timings: dict[str, float] = {}
    models = []
    for scenario, options in scenario_options(case, assignments, scenarios):
        system, family = _build(case, options, reporter, timings, f" ({scenario.label})")
        models.append(ScenarioModel(scenario=scenario, options=options, system=system, family=family))
    first = models[0]
    if first.family.left_out:
        reporter.note(f"{len(first.family.left_out)} observation valuations never consult a service and are left out")
    return Prepared(
        case=case,
        options=first.options,
        system=first.system,
        family=first.family,
        timings=timings,
        scenarios=tuple(models),
    )


def _build(
    case: CaseStudy, options: Any, reporter: Reporter, timings: dict[str, float], label: str = ""
) -> tuple[SystemModel, Family]:
    """The case study's system model for ``options`` (the augmented one's, with named
    rewards) and its family."""
    with timed(timings, "build"):
        if case.warm_up is not None:
            case.warm_up(options, reporter)
        reporter.stage("build model" + label)
        system = case.build(options)
    reporter.stage("augment" + label)
    with timed(timings, "augment"):
        family = make_family(system, prune=case.prune)
    return family.system or system, family
