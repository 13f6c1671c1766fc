"""Reading PRISM through stormpy's program API: parse, inspect, and splice rendered parts.

Nothing here reads PRISM text with regular expressions: programs are parsed by Storm,
inspected through the API, and printed by Storm's own printer. :func:`splice` replaces the
printed form of whole modules and constant declarations by new text and checks that each
replaced part occurs exactly once. (Only an error message's hint, :func:`_undeclared`,
looks for the words of a text that failed to parse.)
"""

from __future__ import annotations

import math
import os
import re
import tempfile
from collections.abc import Iterable, Mapping

import stormpy
import stormpy.developer as storm_dev
from stormpy.developer.storage import PrismBooleanVariable, PrismModelType, PrismProgram

from parley_core.errors import ModelError
from parley_core.model import IDENTIFIER


def quiet_storm() -> None:
    """Stop Storm from logging its own errors to stderr; parley reports them as exceptions.

    Storm's log level is process-wide, so the entry points set it once: the ``parley``
    command and every worker process parley starts. A library user who wants Storm quiet
    too calls it once."""
    storm_dev.set_log_level(storm_dev.LogLevel.OFF)


def storm_message(exc: BaseException) -> str:
    """Storm's exception text on one line, without the C++ exception class name."""
    text = str(exc)
    head, sep, rest = text.partition(": ")
    if sep and head.endswith("Exception") and " " not in head:
        text = rest
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


def parse_program(text: str, *, origin: str = "model") -> PrismProgram:
    """Parse PRISM text as written (no simplification), or raise ModelError with Storm's message."""
    fd, path = tempfile.mkstemp(suffix=".prism", prefix="parley-")
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        return stormpy.parse_prism_program(path, simplify=False)
    except RuntimeError as exc:
        message = storm_message(exc)
        if "The input model is a CTMC" in message:  # Storm's parser refuses before parley can say it
            raise ModelError(f"{origin} is a CTMC but parley needs a DTMC; declare it with `dtmc`") from None
        raise ModelError(f"{origin} does not parse: {_hinted(_undeclared_at(text, message), message)}") from None
    finally:
        os.unlink(path)


def parse_properties(formulas: Iterable[str], program: PrismProgram, *, origin: str = "property") -> list:
    """Parse each formula against the program; an error names the formula and Storm's message."""
    parsed = []
    for formula in formulas:
        try:
            properties = stormpy.parse_properties(formula, program)
        except RuntimeError as exc:
            hint = _undeclared(_words(formula, outside_quotes=True) - _KEYWORDS, str(program))
            raise ModelError(f"{origin} {formula!r} does not parse: {_hinted(hint, storm_message(exc))}") from None
        if len(properties) != 1:
            raise ModelError(f"{origin} {formula!r} holds {len(properties)} properties; give exactly one")
        parsed.append(properties[0])
    return parsed


_KEYWORDS = frozenset(
    "A bool clock const ctmc C double dtmc E endinit endinvariant endmodule endobservables endrewards endsystem "
    "false formula filter func F global G init invariant I int label max mdp min module X nondeterministic "
    "observable observables of Pmax Pmin P pomdp popta probabilistic prob pta rate rewards Rmax Rmin R S "
    "stochastic system true U W floor ceil round pow mod log deadlock".split()
)
"""PRISM's keywords and functions: never an undeclared name."""


def _words(text: str, outside_quotes: bool = False) -> set[str]:
    if outside_quotes:
        text = "".join(text.split('"')[::2])  # labels are quoted
    return set(IDENTIFIER.findall(text))


def _hinted(hint: str, message: str) -> str:
    return f"{hint}; Storm says: {message}" if hint else message


def _undeclared(names: set[str], model: str) -> str:
    """The hint of a parse error: which of ``names`` the model's text never mentions (so
    declares nowhere), as ``"'zz' is not declared in the model"``, or ""."""
    missing = sorted(names - _words(model))
    if not missing:
        return ""
    listed = ", ".join(repr(name) for name in missing)
    return f"{listed} {'is' if len(missing) == 1 else 'are'} not declared in the model"


def _undeclared_at(text: str, message: str) -> str:
    """The hint of a program's parse error: the word at (else just before) Storm's error
    position, if it occurs nowhere else in the text (used once, so declared nowhere)."""
    where = re.search(r"at (\d+):(\d+)", message)
    lines = text.splitlines()
    if not where or not 0 < int(where[1]) <= len(lines):
        return ""
    column = int(where[2]) - 1
    words = [m for m in IDENTIFIER.finditer(lines[int(where[1]) - 1]) if m.start() <= column]
    if not words or words[-1][0] in _KEYWORDS or len(re.findall(rf"\b{words[-1][0]}\b", text)) != 1:
        return ""
    return f"{words[-1][0]!r} (line {where[1]}) is not declared"


def is_dtmc(program: PrismProgram) -> bool:
    """Whether the program declares a DTMC (``dtmc``, or PRISM's older ``probabilistic``)."""
    return program.model_type == PrismModelType.DTMC


def reward_structures(program: PrismProgram, ignore: Iterable[str] = ()) -> list[str]:
    """The names of the program's reward structures, in order (``""`` for an unnamed one),
    without those in ``ignore`` (parley's own)."""
    left_out = set(ignore)
    return [r.name for r in program.reward_models if r.name not in left_out]


def check_property_references(prop, program: PrismProgram, *, origin: str, ignore: Iterable[str] = ()) -> None:
    """Reject a reward property naming a reward structure the program lacks, or naming none
    when the program has several (labels are checked by Storm when building). ``ignore``:
    reward structures of parley's own, which the user's properties cannot mean."""
    formula = prop.get_raw_formula()
    if not (formula.is_probability_operator_formula or formula.is_reward_operator_formula):
        raise ModelError(f"{origin} is {formula}, not a P=? or R=? query; objectives are P=? [...] or R=? [...]")
    if formula.has_bound:
        raise ModelError(
            f"{origin} is {formula}, a bounded query with a yes/no answer; write it as P=? [...] (or R=? [...]) "
            "and give the bound as a requirement, --constraint NAME<=BOUND"
        )
    if formula.is_reward_operator_formula:
        structures = reward_structures(program, ignore)
        if formula.has_reward_model_name():
            if formula.reward_name not in structures:
                names = ", ".join(f'"{name}"' if name else "an unnamed one" for name in structures) or "none"
                raise ModelError(
                    f'{origin} uses reward structure "{formula.reward_name}", which the model lacks; it has: {names}'
                )
        elif len(structures) != 1:
            raise ModelError(
                f'{origin} names no reward structure and the model has {len(structures)}; write R{{"name"}}=? [...]'
            )


def find_variable(program: PrismProgram, name: str):
    """The integer or boolean variable called ``name`` (global or in a module), or None."""
    for variable in list(program.global_integer_variables) + list(program.global_boolean_variables):
        if variable.name == name:
            return variable
    for module in program.modules:
        for variable in list(module.integer_variables) + list(module.boolean_variables):
            if variable.name == name:
                return variable
    return None


def integer_constants(program: PrismProgram, values: Mapping[str, int]) -> dict:
    """``{expression variable: integer expression}`` for the named constants of ``program``
    (names it does not declare are left out), as ``substitute`` and
    ``define_undefined_constants`` take them."""
    by_name = {c.name: c.expression_variable for c in program.constants}
    manager = program.expression_manager
    return {by_name[name]: manager.integer(int(value)) for name, value in values.items() if name in by_name}


def define_constants(program: PrismProgram, values: Mapping[str, int]) -> PrismProgram:
    """``program`` with the named undefined constants set to the given integers."""
    return program.define_undefined_constants(integer_constants(program, values))


def constant_definitions(program: PrismProgram) -> dict:
    """Every defined constant's definition in terms of numbers alone (for ``substitute``).
    Check integer definitions with :func:`fixed_int` first: Storm's substitution crashes on
    ``const int k = 1/0;``."""
    return {c.expression_variable: c.definition for c in program.substitute_constants().constants if c.defined}


def closed_bounds(
    program: PrismProgram, variable, overrides: Mapping | None = None, definitions: Mapping | None = None
) -> tuple:
    """An integer variable's lower and upper bound with ``overrides`` (constants to
    expressions, applied first) and then the program's constant definitions substituted."""
    definitions = constant_definitions(program) if definitions is None else definitions
    bounds = (variable.lower_bound_expression, variable.upper_bound_expression)
    if overrides:
        bounds = tuple(b.substitute(dict(overrides)) for b in bounds)
    return tuple(b.substitute(dict(definitions)) for b in bounds)


def fixed_int(expression) -> int | None:
    """The value of a closed integer expression, or None if it has variables or its value is
    not a finite integer. Evaluated as a double: Storm's integer evaluation kills the process
    (SIGFPE) on a division by zero such as ``[0..1/0]``, found by the fuzz test."""
    if expression.get_variables():
        return None
    try:
        value = expression.evaluate_as_double()
    except RuntimeError:
        return None
    if not math.isfinite(value) or value != int(value):
        return None
    return int(value)


def variable_domain(
    program: PrismProgram, name: str, *, origin: str = "observation variable", overrides: Mapping | None = None
) -> range:
    """All values of a bounded integer or boolean variable (booleans as 0 and 1).

    ``overrides`` maps constants (expression variables) to expressions that replace them in
    the bounds before the program's own definitions do (augmentation widens bounds that use
    a service constant to the constant's largest value)."""
    variable = find_variable(program, name)
    if variable is None:
        known = sorted(v.name for v in all_variables(program))
        raise ModelError(f"{origin} {name!r} is not a variable of the model; variables: {', '.join(known)}")
    if isinstance(variable, PrismBooleanVariable) or not hasattr(variable, "lower_bound_expression"):
        return range(0, 2)
    low, high = (fixed_int(b) for b in closed_bounds(program, variable, overrides))
    if low is None or high is None:
        raise ModelError(
            f"{origin} {name!r} has bounds [{variable.lower_bound_expression}..{variable.upper_bound_expression}] "
            "that are not fixed integers; define the constants its bounds use and keep them integers"
        )
    return range(low, high + 1)


def is_boolean(program: PrismProgram, name: str) -> bool:
    return any(v.name == name for v in boolean_variables(program))


def integer_variables(program: PrismProgram) -> list:
    result = list(program.global_integer_variables)
    for module in program.modules:
        result += list(module.integer_variables)
    return result


def boolean_variables(program: PrismProgram) -> list:
    result = list(program.global_boolean_variables)
    for module in program.modules:
        result += list(module.boolean_variables)
    return result


def all_variables(program: PrismProgram) -> list:
    return integer_variables(program) + boolean_variables(program)


def command_uses(command, variables: set) -> bool:
    """Whether the command's guard or any of its updates mentions one of ``variables``."""
    if command.guard_expression.contains_variable(variables):
        return True
    for update in command.updates:
        if update.probability_expression.contains_variable(variables):
            return True
        for assignment in update.assignments:
            if assignment.expression.contains_variable(variables):
                return True
    return False


def constant_declaration(constant) -> str:
    """A constant's declaration exactly as Storm prints it (a double's type, rational inside
    Storm, printed as ``double``)."""
    value = f" = {constant.definition}" if constant.defined else ""
    kind = "bool" if constant.type.is_boolean else "int" if constant.type.is_integer else "double"
    return f"const {kind} {constant.name}{value};"


def splice(
    program: PrismProgram,
    *,
    modules: Mapping[str, str] = {},
    constants: Mapping[str, str] = {},
    header: str = "",
    model_type: str | None = None,
) -> str:
    """Storm's printing of ``program`` with whole modules and constant declarations replaced.

    ``modules`` maps a module name to its new text, ``constants`` maps a constant name to the
    lines replacing its declaration (an empty string drops it); ``model_type`` (e.g. "mdp")
    replaces the model type keyword Storm prints first.
    """
    text = str(program)
    if model_type is not None:
        keyword, newline, rest = text.partition("\n")
        if keyword != program.model_type.name.lower():
            raise RuntimeError(f"Storm's printing starts with {keyword!r}, not the model type")
        text = model_type + newline + rest
    for module in program.modules:
        if module.name in modules:
            old = str(module)
            if text.count(old) != 1:
                raise RuntimeError(f"module {module.name} is not printed exactly once; cannot splice it")
            text = text.replace(old, modules[module.name].rstrip("\n") + "\n")
    lines = text.split("\n")
    for constant in program.constants:
        if constant.name in constants:
            old = constant_declaration(constant)
            positions = [i for i, line in enumerate(lines) if line == old]
            if len(positions) != 1:
                raise RuntimeError(f"constant {constant.name} is not printed exactly once as {old!r}; cannot splice it")
            lines[positions[0]] = constants[constant.name]
    text = "\n".join(lines)
    if header:
        text = "\n".join(f"// {line}".rstrip() for line in header.splitlines()) + "\n" + text
    return text


def variable_line(variable) -> str:
    """An integer or boolean variable's declaration exactly as Storm prints it in a module."""
    if isinstance(variable, PrismBooleanVariable) or not hasattr(variable, "lower_bound_expression"):
        return f"{variable.name}: bool init {variable.initial_value_expression};"
    return (
        f"{variable.name}: [{variable.lower_bound_expression}..{variable.upper_bound_expression}] "
        f"init {variable.initial_value_expression};"
    )


def module_with_commands(
    module, replacements: Mapping[int, list[str]], variables: Mapping[str, str] | None = None
) -> str:
    """Storm's printing of ``module`` with the commands of the given global indices replaced
    by new lines, and the declarations of the named ``variables`` by new ones."""
    by_line: dict[str, list[str]] = {}
    for command in module.commands:
        if command.global_index in replacements:
            by_line[f"\t{command}"] = replacements[command.global_index]
    for variable in list(module.integer_variables) + list(module.boolean_variables):
        if variables and variable.name in variables:
            by_line[f"\t{variable_line(variable)}"] = [variables[variable.name]]
    out = []
    seen = set()
    for line in str(module).split("\n"):
        if line in by_line:
            out += [f"\t{new}" for new in by_line[line]]
            seen.add(line)
        else:
            out.append(line)
    missing = set(by_line) - seen
    if missing:
        raise RuntimeError(f"could not find {sorted(missing)} in Storm's printing of module {module.name}")
    return "\n".join(out)
