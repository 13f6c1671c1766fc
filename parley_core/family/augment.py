"""Augmentation: SystemModel -> Family, in the canonical form of DESIGN.md.

Every command that consults a service constant ``c`` is copied once per observation
valuation, with the valuation conjoined to its guard and ``c`` replaced by that valuation's
decision constant (``c_3_4`` at ``xhat=3, yhat=4``). The decision constants are declared as
undefined ``const int``; an assignment of them is a policy. No states or steps are added,
so step-bounded properties keep their meaning.

Augmentation is pure: which valuations to keep is the caller's choice (``valuations``); the
pipeline finds the consulted ones on the quotient (:func:`parley_core.quotient.mdp.consulted_valuations`)
before it augments.
"""

from __future__ import annotations

from collections.abc import Iterable

from parley_core.errors import ModelError
from parley_core.model import Decision, Family, SystemModel, decision_name
from parley_core.prism import program as prism
from parley_core.prism import rewrite
from parley_core.prism.writer import FORMATS, declaration


def augment(system: SystemModel, *, valuations: Iterable[tuple[int, ...]] | None = None) -> Family:
    """The parametric model of ``system`` with one decision constant per service and observation valuation.

    ``valuations`` (default: every valuation in the observation variables' ranges) are the
    ones that get decisions; the others are listed in ``Family.left_out``.
    """
    family = _augment(system, None if valuations is None else set(valuations), "prism")
    _validate(family, f"the {system.name} model")
    return family


def export(family: Family, form: str) -> str:
    """The family's parametric model in another tool's syntax: EvoChecker's ``evolve int`` or PAYNT's ``hole``."""
    if form not in FORMATS:
        raise ModelError(f"unknown format {form!r}; valid: {', '.join(FORMATS)}")
    if form == "prism":
        return family.prism
    try:
        return _augment(family.origin(), set(family.valuations), form).prism
    except ValueError as exc:
        raise ModelError(f"{exc}; export it with --format paynt or prism") from None


def _augment(system: SystemModel, kept: set[tuple[int, ...]] | None, form: str) -> Family:
    origin = f"the {system.name} model"
    program = prism.parse_program(system.prism, origin=origin)
    if not prism.is_dtmc(program):
        raise ModelError(f"{origin} is a {program.model_type.name} but parley needs a DTMC; declare it with `dtmc`")
    if program.has_initial_states_expression:
        raise ModelError(
            f"{origin} has an init ... endinit block; parley needs exactly one initial state: "
            "give each variable an init value instead"
        )

    service_vars = rewrite.service_variables(program, system.services, origin)
    undefined = sorted(c.name for c in program.constants if not c.defined and c.name not in service_vars)
    if undefined:
        raise ModelError(f"{origin} leaves constants {', '.join(undefined)} undefined; give them values")

    every = rewrite.observation_valuations(program, system)
    valuations = tuple(every) if kept is None else tuple(v for v in every if v in kept)
    left_out = () if kept is None else tuple(v for v in every if v not in kept)
    manager = program.expression_manager

    # Decision constants, valuation-major, in the order of the services.
    decisions: list[Decision] = []
    copies: list[rewrite.Copy] = []
    for valuation in valuations:
        mapping = {}
        for service in system.services:
            name = decision_name(service.constant, valuation)
            if not valuation:  # no observation: the service constant is its own decision
                variable = service_vars[service.constant]
            elif manager.has_variable(name):
                raise ModelError(f"{origin} already has an identifier {name!r}; rename it, parley needs that name")
            else:
                variable = manager.declare_integer_variable(name)
            mapping[service_vars[service.constant]] = variable.get_expression()
            decisions.append(Decision(name=name, service=service, valuation=valuation))
        copies.append(rewrite.Copy(mapping=mapping, condition=rewrite.valuation_condition(program, system, valuation)))

    rewritten = rewrite.copy_service_commands(program, system, service_vars, lambda _command, _used: copies, origin)
    unused = [s.constant for s in system.services if s.constant not in rewritten.used]
    through = {
        name: [c.name for c in program.constants if c.defined and c.definition.contains_variable({service_vars[name]})]
        for name in unused
    }
    indirect = [f"{name} (through {', '.join(others)})" for name, others in through.items() if others]
    if indirect:
        raise ModelError(
            f"{origin} uses service constant(s) {', '.join(indirect)} only through other constants; parley needs "
            "the service constant itself in the commands' guards or updates: write the other constant's definition there"
        )
    if unused:
        raise ModelError(
            f"constant(s) {', '.join(unused)} are used in no command of {origin}; "
            "a service constant must appear in the guard or update of the commands that invoke or skip the service"
        )

    declarations = {}
    for service in system.services:
        names = [d.name for d in decisions if d.service == service]
        lines = [
            f"// {service.name} ({service.kind.value}): {service.constant} in {service.domain_text()} "
            "per observation valuation"
        ]
        lines += [declaration(name, service.values, form) for name in names]
        declarations[service.constant] = "\n".join(lines)

    header = (
        f"Augmented by parley from the {system.name} model: one decision constant per service and "
        f"valuation of ({', '.join(system.observation)}).\n"
        "Every policy is an assignment of the undefined constants below."
    )
    text = prism.splice(program, modules=rewritten.modules, constants=declarations, header=header)
    return Family.of(system, prism=text, decisions=tuple(decisions), valuations=valuations, left_out=left_out)


def _validate(family: Family, origin: str) -> None:
    try:
        program = prism.parse_program(family.prism, origin=f"the augmented {origin}")
    except ModelError as exc:
        raise ModelError(
            f"augmenting {origin} gives a model that does not parse ({exc}); most likely a service constant is "
            "used outside the commands' guards and updates (in a formula, label or reward): use it only there"
        ) from None
    undefined = {c.name for c in program.get_undefined_constants()}
    expected = set(family.names)
    if undefined != expected:
        extra = sorted(undefined - expected)
        raise ModelError(
            f"augmenting {origin} left constants {', '.join(extra) or 'none'} undefined "
            "(a service constant used outside commands, e.g. in a formula, label or reward?); "
            "use service constants only in command guards and updates"
        )
