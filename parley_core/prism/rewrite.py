"""Edits of a parsed program that augmentation and the quotient share: copying the commands
that consult a service constant, widening bounds that use one, observation domains.

Both rewrites copy every command that mentions a service constant; they differ only in what
a copy stands for. Augmentation writes one copy per observation valuation (the valuation
conjoined to the guard, the constant replaced by that valuation's decision constant); the
quotient writes one copy per value of the constants the command uses (the constant replaced
by the value, the copy tagged with it). :func:`copy_service_commands` does the walk once.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from attrs import field, frozen
from stormpy.developer.storage import Expression, PrismProgram

from parley_core.errors import ModelError, OptionError
from parley_core.model import Service, SystemModel
from parley_core.prism import program as prism
from parley_core.prism.writer import RewardItem, Rewards, command_line

OBSERVATION_REWARD = "__parley_obs"
"""The quotient's state reward that numbers each state's observation valuation."""

Tag = tuple[tuple[int, int], ...]
"""What a quotient command stands for: (service position, value) pairs."""


@frozen(kw_only=True)
class Copy:
    """One copy of a command: the substitution of service constants, an optional condition
    conjoined before the guard, and a tag that the caller gets back in command order."""

    mapping: Mapping = field(eq=False)
    condition: Expression | None = field(default=None, eq=False)
    tag: Tag = ()


@frozen(kw_only=True)
class Rewritten:
    """The new text of each changed module, and per module the tag of every command of the
    rewritten module in order (``()`` for a command left as it was)."""

    modules: Mapping[str, str]
    tags: Mapping[str, tuple[Tag, ...]]
    used: frozenset[str]
    """The service constants some command uses."""


def service_variables(program: PrismProgram, services: Sequence[Service], origin: str) -> dict[str, Any]:
    """``{constant name: expression variable}`` of the services, in the services' order; a
    constant the program does not declare is an error."""
    constants = {c.name: c for c in program.constants}
    result = {}
    for service in services:
        if service.constant not in constants:
            raise ModelError(
                f"service {service.name!r}: constant {service.constant!r} is not declared in {origin}; "
                f"declare `const int {service.constant};`"
            )
        result[service.constant] = constants[service.constant].expression_variable
    return result


def copy_service_commands(
    program: PrismProgram,
    system: SystemModel,
    constants: Mapping[str, object],
    copies: Callable[[object, list[str]], Sequence[Copy]],
    origin: str,
    drop_false: bool = False,
) -> Rewritten:
    """Replace every command that uses one of ``constants`` (name -> expression variable,
    in the order that ``copies`` receives the used ones) by ``copies(command, used)``; widen
    the bounds that use a service constant (:func:`widen_bounds`). With ``drop_false``, a
    copy whose guard simplifies to false is left out (a model that tests a constant in its
    guards, ``c=3 -> ...``, gets one copy per value, not one per value and command)."""
    manager = program.expression_manager
    modules: dict[str, str] = {}
    tags_by_module: dict[str, tuple[Tag, ...]] = {}
    used_anywhere: set[str] = set()
    for module in program.modules:
        replacements: dict[int, list[str]] = {}
        tags: list[Tag] = []
        for command in module.commands:
            used = [name for name, variable in constants.items() if prism.command_uses(command, {variable})]
            if not used:
                tags.append(())
                continue
            used_anywhere.update(used)
            lines = []
            for copy in copies(command, used):
                guard = command.guard_expression.substitute(copy.mapping)
                if copy.condition is not None:
                    guard = Expression.And(copy.condition, guard)
                if drop_false:
                    simple = guard.simplify()
                    if simple.is_literal() and not simple.evaluate_as_bool():
                        continue
                updates = [str(update.substitute(copy.mapping)) for update in command.updates]
                lines.append(command_line(command.action_name, str(guard), updates))
                tags.append(copy.tag)
            replacements[command.global_index] = lines
        widened = widen_bounds(module, constants, system, manager, origin)
        if replacements or widened:
            modules[module.name] = prism.module_with_commands(module, replacements, widened)
        tags_by_module[module.name] = tuple(tags)
    return Rewritten(modules=modules, tags=tags_by_module, used=frozenset(used_anywhere))


def valuation_condition(program: PrismProgram, system: SystemModel, valuation: tuple[int, ...]) -> Expression | None:
    """``xhat=3 & yhat=4`` (``b <=> true`` for a boolean variable) as a Storm expression;
    None for the empty valuation (no observation variables)."""
    manager = program.expression_manager
    parts = []
    for name, value in zip(system.observation, valuation):
        expression = prism.find_variable(program, name).expression_variable.get_expression()
        if prism.is_boolean(program, name):
            parts.append(Expression.Iff(expression, manager.boolean(bool(value))))
        else:
            parts.append(Expression.Eq(expression, manager.integer(value)))
    if not parts:
        return None
    result = parts[0]
    for part in parts[1:]:
        result = Expression.And(result, part)
    return result


def observation_domains(program: PrismProgram, system: SystemModel) -> list[range]:
    """The values of each observation variable, with bounds that use a service constant
    widened to its largest value (as :func:`widen_bounds` writes them)."""
    highest = prism.integer_constants(program, {s.constant: s.high for s in system.services})
    return [prism.variable_domain(program, name, overrides=highest) for name in system.observation]


def observation_valuations(program: PrismProgram, system: SystemModel) -> list[tuple[int, ...]]:
    """Every valuation of the observation domains, in lexicographic order."""
    return list(itertools.product(*observation_domains(program, system)))


def widen_bounds(module, constants: Mapping[str, object], system: SystemModel, manager, origin: str) -> dict[str, str]:
    """New declarations for variables whose upper bound uses a service constant: the bound
    becomes the constant's largest value, so a counter can reach whatever a decision allows
    (``step : [0..c]`` with c in 1..10 becomes ``step : [0..10]``). A service constant in a
    lower bound or an initial value is an error."""
    wanted = set(constants.values())
    highest = {constants[s.constant]: manager.integer(s.high) for s in system.services if s.constant in constants}
    widened = {}
    for variable in module.integer_variables:
        for what, expression in (
            ("lower bound", variable.lower_bound_expression),
            ("initial value", variable.initial_value_expression),
        ):
            if expression is not None and expression.contains_variable(wanted):
                raise ModelError(
                    f"the {what} of variable {variable.name} in {origin} uses a service constant; give it a fixed value"
                )
        if variable.upper_bound_expression.contains_variable(wanted):
            upper = variable.upper_bound_expression.substitute(highest)
            widened[variable.name] = (
                f"{variable.name}: [{variable.lower_bound_expression}..{upper}] "
                f"init {variable.initial_value_expression};"
            )
    return widened


def quotient_program(system: SystemModel, program: PrismProgram | None = None) -> tuple[str, dict[int, Tag]]:
    """The quotient of a system as PRISM text: its DTMC with every command that consults a
    service constant copied once per value of the constants it uses (the constant replaced
    by the value), declared an ``mdp``, plus the state reward :data:`OBSERVATION_REWARD`;
    and for each command of that text (by global index) the (service position, value)
    pairs it stands for."""
    origin = f"the {system.name} model"
    program = program if program is not None else prism.parse_program(system.prism, origin=origin)
    manager = program.expression_manager
    positions = {s.constant: i for i, s in enumerate(system.services)}
    constants = {c.name: c.expression_variable for c in program.constants if c.name in positions}

    def per_value(_command, used: list[str]) -> list[Copy]:
        services = [system.services[positions[name]] for name in used]
        return [
            Copy(
                mapping={constants[name]: manager.integer(v) for name, v in zip(used, values)},
                tag=tuple((positions[name], v) for name, v in zip(used, values)),
            )
            for values in itertools.product(*(s.values for s in services))
        ]

    rewritten = copy_service_commands(program, system, constants, per_value, origin, drop_false=True)
    text = prism.splice(
        program, modules=rewritten.modules, constants={name: "" for name in constants}, model_type="mdp"
    )
    text += "\n" + observation_rewards(program, system).render() + "\n"
    parsed = prism.parse_program(text, origin="the quotient model")
    by_index: dict[int, Tag] = {}
    for module in parsed.modules:
        tags = rewritten.tags[module.name]
        if len(tags) != len(module.commands):
            raise RuntimeError(f"quotient module {module.name}: {len(module.commands)} commands, expected {len(tags)}")
        for command, tag in zip(module.commands, tags):
            by_index[command.global_index] = tag
    return text, by_index


def observation_rewards(program: PrismProgram, system: SystemModel) -> Rewards:
    """A state reward that is each state's observation valuation's position in
    :func:`observation_valuations` order."""
    terms = []
    stride = 1
    domains = dict(zip(system.observation, observation_domains(program, system)))
    for name in reversed(system.observation):
        domain = domains[name]
        if prism.is_boolean(program, name):
            value = f"({name} ? 1 : 0)"
        else:
            value = f"({name} - {domain.start})"
        terms.append(f"{value} * {stride}")
        stride *= len(domain)
    return Rewards(name=OBSERVATION_REWARD, items=[RewardItem(guard="true", value=" + ".join(terms) or "0")])


def override_constants(
    text: str, values: Mapping[str, str], services: Sequence[str] = (), option: str = "--scenarios"
) -> str:
    """A PRISM program (Storm's printing of ``text``) with each named constant declared with
    the given value: ``const double p = 0.02;`` for ``p=0.02``, whether the model defines
    ``p`` or leaves it undefined. ``option`` names the command-line option the values came
    from, in error messages; ``services`` are the decision constants, which a URC chooses."""
    program = prism.parse_program(text, origin="model")
    declared = {c.name: c for c in program.constants}
    declarations = {}
    for name, value in values.items():
        if name in services:
            raise OptionError(f"{option} {name}=...: {name} is a decision constant; the URC chooses it")
        if name not in declared:
            names = ", ".join(sorted(n for n in declared if n not in services)) or "none"
            raise OptionError(f"{option} {name}=...: the model declares no constant {name}; its constants: {names}")
        constant = declared[name]
        kind = "bool" if constant.type.is_boolean else "int" if constant.type.is_integer else "double"
        declarations[name] = f"const {kind} {name} = {_constant_value(name, value, kind, option)};"
    if not declarations:
        return text
    return prism.splice(program, constants=declarations)


def _constant_value(name: str, value: str, kind: str, option: str) -> str:
    value = value.strip()
    if kind == "bool":
        if value not in ("true", "false"):
            raise OptionError(f"{option} {name}={value}: {name} is a bool constant; give true or false")
        return value
    try:
        number = float(value)
    except ValueError:
        raise OptionError(f"{option} {name}={value}: {name} is a {kind} constant; give a number") from None
    if kind == "int":
        if number != int(number):
            raise OptionError(f"{option} {name}={value}: {name} is an int constant; give an integer")
        return str(int(number))
    if not math.isfinite(number):
        raise OptionError(f"{option} {name}={value}: give a finite number")
    return repr(number)
