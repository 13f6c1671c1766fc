"""Augmentation: SystemModel -> Family, in the canonical form of DESIGN.md.

Every command that consults a service constant ``c`` is copied once per observation
valuation, with the valuation conjoined to its guard and ``c`` replaced by that valuation's
decision constant (``c_3_4`` at ``xhat=3, yhat=4``). The decision constants are declared as
undefined ``const int``; an assignment of them is a policy. No states or steps are added,
so step-bounded properties keep their meaning.
"""

from __future__ import annotations

import itertools

from stormpy.developer.storage import Expression, PrismModelType

from parley_core.errors import ModelError
from parley_core.model import Decision, Family, SystemModel, decision_name
from parley_core.prism import program as prism
from parley_core.prism.writer import command_line


FORMATS = ("prism", "evochecker", "paynt")


def _declaration(name: str, low: int, high: int, form: str) -> str:
    if form == "prism":
        return f"const int {name};"
    if form == "evochecker":
        return f"evolve int {name} [{low}..{high}];"
    if form == "paynt":
        return f"hole int {name} in {{{','.join(str(v) for v in range(low, high + 1))}}};"
    raise ModelError(f"unknown format {form!r}; valid: {', '.join(FORMATS)}")


def augment(system: SystemModel, *, prune: bool = False) -> Family:
    """The parametric model of ``system`` with one decision constant per service and observation valuation.

    With ``prune``, valuations at which no service is ever consulted (in no reachable state of
    any policy, found on the quotient MDP) are left out and listed in ``Family.left_out``.
    """
    family = _augment(system, None, "prism")
    if prune:
        from parley_core.evaluate.quotient import consulted_valuations

        kept = consulted_valuations(family)
        if len(kept) < len(family.valuations):
            pruned = _augment(system, [v for v in family.valuations if v in kept], "prism")
            family = Family(
                system=system, prism=pruned.prism, decisions=pruned.decisions, valuations=pruned.valuations,
                left_out=tuple(v for v in family.valuations if v not in kept),
            )
    _validate(family, f"the {system.name} model")
    return family


def export(family: Family, form: str) -> str:
    """The family's parametric model in another tool's syntax: EvoChecker's ``evolve int`` or PAYNT's ``hole``."""
    if form == "prism":
        return family.prism
    return _augment(family.system, list(family.valuations), form).prism


def _augment(system: SystemModel, only: list[tuple[int, ...]] | None, form: str) -> Family:
    origin = f"the {system.name} model"
    program = prism.parse_program(system.prism, origin=origin)
    if program.model_type != PrismModelType.DTMC:
        raise ModelError(f"{origin} is a {program.model_type.name} but parley needs a DTMC; declare it with `dtmc`")

    constants = {c.name: c for c in program.constants}
    service_vars = {}
    for service in system.services:
        if service.constant not in constants:
            raise ModelError(
                f"service {service.name!r}: constant {service.constant!r} is not declared in {origin}; "
                f"declare `const int {service.constant};`"
            )
        service_vars[service.constant] = constants[service.constant].expression_variable
    undefined = sorted(c.name for c in program.constants if not c.defined and c.name not in service_vars)
    if undefined:
        raise ModelError(f"{origin} leaves constants {', '.join(undefined)} undefined; give them values")

    domains = observation_domains(program, system)
    valuations = tuple(itertools.product(*domains)) if only is None else tuple(only)
    manager = program.expression_manager

    # Decision constants, valuation-major, in the order of the services.
    decisions: list[Decision] = []
    substitutions: list[tuple[tuple[int, ...], dict]] = []
    for valuation in valuations:
        mapping = {}
        for service in system.services:
            name = decision_name(service.constant, valuation)
            if manager.has_variable(name):
                raise ModelError(f"{origin} already has an identifier {name!r}; rename it, parley needs that name")
            variable = manager.declare_integer_variable(name)
            mapping[service_vars[service.constant]] = variable.get_expression()
            decisions.append(Decision(name=name, service=service, valuation=valuation))
        substitutions.append((valuation, mapping))

    wanted = set(service_vars.values())
    observed = [prism.find_variable(program, name).expression_variable for name in system.observation]
    booleans = {name for name in system.observation if prism.is_boolean(program, name)}
    new_modules: dict[str, str] = {}
    used_by: set[str] = set()
    for module in program.modules:
        replacements: dict[int, list[str]] = {}
        for command in module.commands:
            if not prism.command_uses(command, wanted):
                continue
            used_by.update(c for c, v in service_vars.items() if prism.command_uses(command, {v}))
            lines = []
            for valuation, mapping in substitutions:
                condition = _valuation_expression(manager, observed, valuation, system.observation, booleans)
                guard = Expression.And(condition, command.guard_expression.substitute(mapping))
                updates = [str(update.substitute(mapping)) for update in command.updates]
                lines.append(command_line(command.action_name, str(guard), updates))
            replacements[command.global_index] = lines
        widened = widen_bounds(module, service_vars, system, manager, origin)
        if replacements or widened:
            new_modules[module.name] = prism.module_with_commands(module, replacements, widened)

    unused = [s.constant for s in system.services if s.constant not in used_by]
    if unused:
        raise ModelError(
            f"constant(s) {', '.join(unused)} are used in no command of {origin}; "
            "a service constant must appear in the guard or update of the commands that invoke or skip the service"
        )

    declarations = {}
    for service in system.services:
        names = [d.name for d in decisions if d.service == service]
        lines = [f"// {service.name} ({service.kind.value}): {service.constant} in {service.low}..{service.high} per observation valuation"]
        lines += [_declaration(name, service.low, service.high, form) for name in names]
        declarations[service.constant] = "\n".join(lines)

    header = (
        f"Augmented by parley from the {system.name} model: one decision constant per service and "
        f"valuation of ({', '.join(system.observation)}).\n"
        "Every policy is an assignment of the undefined constants below."
    )
    text = prism.splice(program, modules=new_modules, constants=declarations, header=header)
    return Family(system=system, prism=text, decisions=tuple(decisions), valuations=valuations)


def _valuation_expression(manager, variables, valuation, names, booleans) -> Expression:
    parts = []
    for variable, value, name in zip(variables, valuation, names):
        expression = variable.get_expression()
        if name in booleans:
            parts.append(Expression.Iff(expression, manager.boolean(bool(value))))
        else:
            parts.append(Expression.Eq(expression, manager.integer(value)))
    result = parts[0]
    for part in parts[1:]:
        result = Expression.And(result, part)
    return result


def observation_domains(program, system: SystemModel) -> list[range]:
    """The values of each observation variable, with bounds that use a service constant
    widened to its largest value (as :func:`widen_bounds` writes them)."""
    highest = prism.integer_constants(program, {s.constant: s.high for s in system.services})
    return [prism.variable_domain(program, name, overrides=highest) for name in system.observation]


def widen_bounds(module, service_vars: dict, system: SystemModel, manager, origin: str) -> dict[str, str]:
    """New declarations for variables whose upper bound uses a service constant: the bound
    becomes the constant's largest value, so a counter can reach whatever a decision allows
    (``step : [0..c]`` with c in 1..10 becomes ``step : [0..10]``). A service constant in a
    lower bound or an initial value is an error."""
    wanted = set(service_vars.values())
    highest = {service_vars[s.constant]: manager.integer(s.high) for s in system.services}
    widened = {}
    for variable in module.integer_variables:
        for what, expression in (("lower bound", variable.lower_bound_expression), ("initial value", variable.initial_value_expression)):
            if expression is not None and expression.contains_variable(wanted):
                raise ModelError(
                    f"the {what} of variable {variable.name} in {origin} uses a service constant; "
                    "give it a fixed value"
                )
        if variable.upper_bound_expression.contains_variable(wanted):
            upper = variable.upper_bound_expression.substitute(highest)
            widened[variable.name] = (
                f"{variable.name}: [{variable.lower_bound_expression}..{upper}] init {variable.initial_value_expression};"
            )
    return widened


def _validate(family: Family, origin: str) -> None:
    program = prism.parse_program(family.prism, origin=f"the augmented {origin}")
    undefined = {c.name for c in program.get_undefined_constants()}
    expected = set(family.names)
    if undefined != expected:
        extra = sorted(undefined - expected)
        raise ModelError(
            f"augmenting {origin} left constants {', '.join(extra) or 'none'} undefined "
            "(a service constant used outside commands, e.g. in a formula, label or reward?); "
            "use service constants only in command guards and updates"
        )
