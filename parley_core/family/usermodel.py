"""A user's own PRISM model as a SystemModel: the input of `parley augment` and `parley synthesize`.

- ``--decision NAME=LOW..HIGH[:frequency|threshold]`` names a constant of the model that
  sets when a service runs, and the values the URC may give it. A constant the model
  defines (``const int c = 1;``) is accepted; its value becomes a baseline policy.
- ``--observe VAR,...`` names the variables the URC may read (bounded integers or booleans).
- Objectives come from a properties file: each property may be preceded by a comment
  ``// name: NAME, max`` (or ``min``), or by a comment ending in the direction alone
  (``//Objective, max``, as in the paper's files), or be named PRISM-style
  (``"NAME": P=? [...]``); unnamed ones are called objective1, objective2, ...
  ``--maximize NAME`` / ``--minimize NAME`` set or override directions.

Every problem is a ParleyError with one line saying what to do.
"""

from __future__ import annotations

import signal
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import attrs
from attrs import field, frozen

from parley_core.errors import ModelError, OptionError, ParleyDefect
from parley_core.files import read_text
from parley_core.model import Baseline, DecisionKind, Direction, Objective, Service, SystemModel, identifier
from parley_core.plugin.casestudy import CaseStudy
from parley_core.prism import program as prism
from parley_core.prism import rewrite, sandbox


def parse_decision(text: str) -> Service:
    """``c=1..10``, ``c=0..5:threshold`` or a set of values, ``P=2,4`` (as PAYNT's holes
    have them) -> a Service (frequency by default)."""
    name, sep, rest = text.partition("=")
    name = name.strip()
    span, _, kind = rest.partition(":")
    low_text, dots, high_text = span.partition("..")
    if not sep or not name or not span.strip():
        raise OptionError(
            f"malformed --decision {text!r}; write NAME=LOW..HIGH[:frequency|threshold] or NAME=V1,V2,..., "
            "e.g. c=1..10 or P=2,4"
        )
    kind = kind.strip() or "frequency"
    if kind not in ("frequency", "threshold"):
        raise OptionError(f"--decision {text!r}: kind {kind!r} is neither frequency nor threshold")
    if not name.isidentifier():
        raise OptionError(f"--decision {text!r}: {name!r} is not a constant name")
    if dots:
        try:
            low, high = int(low_text), int(high_text)
        except ValueError:
            raise OptionError(f"--decision {text!r}: LOW and HIGH must be integers, e.g. c=1..10") from None
        if high < low:
            raise OptionError(f"--decision {text!r}: the range {low}..{high} is empty; give LOW <= HIGH")
        return Service(name=name, constant=name, kind=DecisionKind(kind), low=low, high=high)
    try:
        values = [int(v) for v in span.strip().strip("{}").split(",")]
    except ValueError:
        raise OptionError(f"--decision {text!r}: the values must be integers, e.g. P=2,4") from None
    if len(values) != len(set(values)):
        raise OptionError(f"--decision {text!r} gives a value twice; give each once")
    return Service.of_values(name=name, constant=name, kind=DecisionKind(kind), values=values)


def parse_observation(items: Sequence[str]) -> tuple[str, ...]:
    """The observation variables of ``--observe`` (none: a URC that reads nothing, one value
    per decision constant)."""
    names = tuple(n.strip() for item in items for n in item.split(",") if n.strip())
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise OptionError(f"--observe names {', '.join(duplicates)} twice; give each variable once")
    return names


def read_objectives(path: Path, maximize: Sequence[str] = (), minimize: Sequence[str] = ()) -> list[Objective]:
    """Objectives from a properties file (see the module docstring)."""
    text = read_text(path, "properties file", "give a file of PCTL properties (one per line)", OptionError)
    pending: tuple[str | None, str | None] | None = None
    found: list[tuple[str, str, str | None]] = []  # name, formula, direction
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("//"):
            comment = line[2:].strip()
            parts = [p.strip() for p in comment.split(",")]
            if comment.lower().startswith("name:"):
                parts = [p.strip() for p in comment[5:].split(",")]
                direction = parts[1].lower() if len(parts) > 1 and parts[1] else None
                if direction not in (None, "max", "min"):
                    raise OptionError(f"{path}, line {number}: direction {parts[1]!r} is neither max nor min")
                pending = (parts[0], direction)
            elif parts[-1].lower() in ("max", "min"):  # a direction alone, e.g. "//Objective, max"
                pending = (None, parts[-1].lower())
            continue
        name, direction = pending if pending else (None, None)
        formula = line
        if line.startswith('"'):
            label, _, rest = line[1:].partition('"')
            if rest.lstrip().startswith(":"):
                name = name or label
                formula = rest.lstrip()[1:].strip()
        found.append((name or f"objective{len(found) + 1}", formula.rstrip(";"), direction))
        pending = None
    if not found:
        raise OptionError(f"properties file {path} holds no property; write one PCTL property per line")
    names = [n for n, _, _ in found]
    for flag, chosen in (("--maximize", maximize), ("--minimize", minimize)):
        unknown = [n for n in chosen if n not in names]
        if unknown:
            raise OptionError(f"{flag} {unknown[0]}: no objective of that name; objectives: {', '.join(names)}")
    objectives = []
    for name, formula, direction in found:
        if name in maximize and name in minimize:
            raise OptionError(f"objective {name} is given to both --maximize and --minimize")
        direction = "max" if name in maximize else "min" if name in minimize else direction
        if direction is None:
            raise OptionError(
                f"objective {name} has no direction; put '// name: {name}, max' (or min) before it, "
                f"or use --maximize/--minimize {name}"
            )
        if not name.isidentifier():
            raise OptionError(f"objective name {name!r} is not an identifier; use letters, digits and underscores")
        objectives.append(Objective(name=name, formula=formula, direction=Direction(direction)))
    return objectives


def system_from_file(
    path: Path,
    decisions: Sequence[str | Service],
    observe: Sequence[str],
    properties: Path | None = None,
    maximize: Sequence[str] = (),
    minimize: Sequence[str] = (),
    define: Mapping[str, str] | None = None,
) -> SystemModel:
    """The SystemModel of a user's PRISM file; checks everything a user can get wrong.
    ``define`` sets constants of the model (defined or not) to values (a scenario of a
    robust run); the run's model.prism then declares them with these values."""
    text = read_text(path, "model file", "give the path of a PRISM model (.prism)", OptionError)
    if not decisions:
        raise OptionError("give at least one --decision NAME=LOW..HIGH (the constant that sets when a service runs)")
    services = [d if isinstance(d, Service) else parse_decision(d) for d in decisions]
    if define:
        text = rewrite.override_constants(text, define, services=[s.constant for s in services])
    observation = parse_observation(observe)
    program = prism.parse_program(text, origin=f"model {path}")
    constants = {c.name: c for c in program.constants}
    for constant in program.constants:  # Storm crashes (SIGFPE) simplifying `const int k = 1/0;`
        if constant.defined and constant.type.is_integer and not constant.definition.get_variables():
            if prism.fixed_int(constant.definition) is None:
                raise ModelError(
                    f"constant {constant.name} = {constant.definition} is not a finite integer; fix its definition"
                )
    if program.has_initial_states_expression:  # Storm's builder crashes on it with undefined constants
        raise ModelError(
            f"model {path} has an init ... endinit block; parley needs exactly one initial state: "
            "give each variable an init value instead"
        )
    _check_storm_survives(path, lambda: program, {s.constant: s.low for s in services})
    baselines = []
    for service in services:
        if service.constant not in constants:
            names = ", ".join(sorted(constants)) or "none"
            raise ModelError(
                f"--decision {service.constant}: the model declares no constant of that name; constants: {names}"
            )
        constant = constants[service.constant]
        if not constant.type.is_integer:
            raise ModelError(f"--decision {service.constant}: the constant is not an int; decisions are integers")
        if constant.defined:
            value = prism.fixed_int(constant.definition)
            if value is not None and value in service.values and len(services) == 1:
                baselines.append(Baseline(name=f"model ({service.constant}={value})", values={service.constant: value}))
    for name in observation:
        prism.variable_domain(program, name, origin="--observe variable")  # exists and is bounded
    highest = prism.integer_constants(program, {s.constant: s.high for s in services})
    definitions = prism.constant_definitions(program)
    for variable in prism.integer_variables(program):  # Storm's builder crashes on a bound like [0..1/0]
        for bound in prism.closed_bounds(program, variable, highest, definitions):
            if not bound.get_variables() and prism.fixed_int(bound) is None:
                raise ModelError(f"variable {variable.name} has a bound {bound} that is not a finite integer; fix it")

    objectives = read_objectives(properties, maximize, minimize) if properties is not None else []
    if objectives:
        prism.parse_properties([o.formula for o in objectives], program, origin="property")
    if len(services) == 1:
        service = services[0]
        baselines += [Baseline(name=f"{service.constant}={v}", values={service.constant: v}) for v in service.values]
    else:
        lows = {s.constant: s.low for s in services}
        for service in services:
            baselines += [
                Baseline(name=f"{service.constant}={v}", values={**lows, service.constant: v}) for v in service.values
            ]
    seen, unique = set(), []
    for baseline in baselines:  # the model's own value may repeat a fixed one
        key = tuple(sorted(baseline.values.items()))
        if key not in seen:
            seen.add(key)
            unique.append(baseline)
    system = SystemModel(
        name=identifier(path.stem),
        prism=text,
        services=services,
        observation=observation,
        objectives=objectives,
        baselines=unique,
        description=f"user model {path}",
    )
    # the lowest values are built above; the quotient holds every value (and is what parley builds next)
    _check_storm_survives(path, lambda: _quotient_program(system), {})
    return system


def _quotient_program(system: SystemModel):
    return prism.parse_program(rewrite.quotient_program(system)[0])


def _check_storm_survives(path: Path, make, values) -> None:
    """Storm kills the whole process with SIGFPE on an integer division by zero in a guard,
    update or probability, also one that only some decision values or states reach: build
    ``make()`` in a forked child first."""
    crash = sandbox.build_crashes(make, values)
    if crash == signal.SIGFPE:
        raise ModelError(
            f"Storm crashes (SIGFPE) building model {path}, on an integer division by zero "
            "in a guard, update or probability (for some decision value); fix the expression"
        )
    if crash is not None:
        raise ParleyDefect(
            f"Storm crashes (signal {crash}) building model {path}; please report it with the model "
            "(parley refused to go on rather than crash)"
        )


@frozen(kw_only=True)
class FileOptions:
    model: str = field(default="", metadata={"help": "the PRISM file"})


def case_study_for(system: SystemModel, path: Path, rebuild: Callable[[dict[str, str]], SystemModel] | None = None):
    """A one-off CaseStudy around a user's model, so that runs report like plugin runs.

    With ``rebuild`` (``rebuild({constant: value})`` reads the model with those constants
    set), its options are ``model`` and every constant of the model that is not a decision
    (empty: the model's own value), so that a robust run's scenarios can set them."""
    if rebuild is None:
        return CaseStudy(
            name=system.name,
            description=f"user model {path}",
            options_type=FileOptions,
            build=lambda _options: system,
            prune=True,
        )
    program = prism.parse_program(system.prism, origin=f"model {path}")
    decisions = {s.constant for s in system.services}
    names = [c.name for c in program.constants if c.name not in decisions and c.name != "model"]
    fields = {"model": attrs.field(default=str(path), type=str, metadata={"help": "the PRISM file"})}
    for name in names:
        help_text = f"constant {name} of the model (empty: its own value)"
        fields[name] = attrs.field(default="", type=str, metadata={"help": help_text})
    options_type = attrs.make_class("ModelConstants", fields, frozen=True, kw_only=True)

    def build(options) -> SystemModel:
        values = {name: getattr(options, name) for name in names if getattr(options, name) != ""}
        return rebuild(values) if values else system

    return CaseStudy(
        name=system.name, description=f"user model {path}", options_type=options_type, build=build, prune=True
    )
