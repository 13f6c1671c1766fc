"""The one place that writes PRISM text.

Plugins build their DTMC from these small value objects instead of formatting strings
themselves; augmentation renders new commands with :func:`command_line`. Expressions are
PRISM expression strings; the result is always parsed back by stormpy before it is used.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

from attrs import field, frozen

Number = int | float | str


def _text(value: Number | None) -> str:
    if isinstance(value, float):
        return repr(value)
    return str(value)


@frozen(kw_only=True)
class Constant:
    name: str
    type: str = "int"
    value: Number | None = None
    comment: str = ""

    def render(self) -> str:
        body = f"const {self.type} {self.name}" + ("" if self.value is None else f" = {_text(self.value)}") + ";"
        return body + (f" // {self.comment}" if self.comment else "")


@frozen(kw_only=True)
class Formula:
    name: str
    expression: str

    def render(self) -> str:
        return f"formula {self.name} = {self.expression};"


@frozen(kw_only=True)
class Variable:
    """An integer variable ``name : [low..high] init init`` (or ``bool`` when ``boolean``)."""

    name: str
    low: Number = 0
    high: Number = 1
    init: Number | bool = 0
    boolean: bool = False
    comment: str = ""

    def render(self) -> str:
        if self.boolean:
            body = f"{self.name} : bool init {str(bool(self.init)).lower()};"
        else:
            body = f"{self.name} : [{_text(self.low)}..{_text(self.high)}] init {_text(self.init)};"
        return body + (f" // {self.comment}" if self.comment else "")


@frozen(kw_only=True)
class Update:
    """``probability : (v'=e) & ...``; no assignments renders as ``true``."""

    assignments: tuple[tuple[str, str], ...] = field(
        factory=tuple, converter=lambda a: tuple(a.items()) if isinstance(a, Mapping) else tuple(a)
    )
    probability: Number | None = None

    def render(self) -> str:
        body = " & ".join(f"({name}'={_text(expr)})" for name, expr in self.assignments) or "true"
        return body if self.probability is None else f"{_text(self.probability)} : {body}"


@frozen(kw_only=True)
class Command:
    action: str = ""
    guard: str = "true"
    updates: tuple[Update, ...] = field(factory=lambda: (Update(),), converter=tuple[Update, ...])

    def render(self) -> str:
        return command_line(self.action, self.guard, [u.render() for u in self.updates])


def command_line(action: str, guard: str, updates: Iterable[str]) -> str:
    """``[action] guard -> u1 + u2;`` from already rendered parts."""
    return f"[{action}] {guard} -> {' + '.join(updates)};"


@frozen(kw_only=True)
class Module:
    name: str
    variables: tuple[Variable, ...] = field(factory=tuple, converter=tuple[Variable, ...])
    commands: tuple[Command, ...] = field(factory=tuple, converter=tuple[Command, ...])

    def render(self) -> str:
        lines = [f"module {self.name}"]
        lines += [f"  {v.render()}" for v in self.variables]
        if self.variables and self.commands:
            lines.append("")
        lines += [f"  {c.render()}" for c in self.commands]
        lines.append("endmodule")
        return "\n".join(lines)


@frozen(kw_only=True)
class RewardItem:
    """``[action] guard : value;`` (a transition reward) or ``guard : value;`` (a state reward)."""

    guard: str = "true"
    value: Number = 1
    action: str | None = None

    def render(self) -> str:
        prefix = "" if self.action is None else f"[{self.action}] "
        return f"{prefix}{self.guard} : {_text(self.value)};"


@frozen(kw_only=True)
class Rewards:
    name: str
    items: tuple[RewardItem, ...] = field(converter=tuple[RewardItem, ...])

    def render(self) -> str:
        return "\n".join([f'rewards "{self.name}"', *(f"  {i.render()}" for i in self.items), "endrewards"])


@frozen(kw_only=True)
class Label:
    name: str
    expression: str

    def render(self) -> str:
        return f'label "{self.name}" = {self.expression};'


@frozen(kw_only=True)
class Program:
    """A whole PRISM model; ``render()`` gives its text."""

    kind: str = "dtmc"
    header: str = ""
    constants: tuple[Constant, ...] = field(factory=tuple, converter=tuple[Constant, ...])
    formulas: tuple[Formula, ...] = field(factory=tuple, converter=tuple[Formula, ...])
    modules: tuple[Module, ...] = field(factory=tuple, converter=tuple[Module, ...])
    rewards: tuple[Rewards, ...] = field(factory=tuple, converter=tuple[Rewards, ...])
    labels: tuple[Label, ...] = field(factory=tuple, converter=tuple[Label, ...])

    def render(self) -> str:
        blocks = []
        if self.header:
            blocks.append("\n".join(f"// {line}".rstrip() for line in self.header.splitlines()))
        blocks.append(self.kind)
        for group in (self.constants, self.formulas):
            if group:
                blocks.append("\n".join(item.render() for item in group))
        blocks += [m.render() for m in self.modules]
        blocks += [r.render() for r in self.rewards]
        if self.labels:
            blocks.append("\n".join(label.render() for label in self.labels))
        return "\n\n".join(blocks) + "\n"


def conjunction(parts: Iterable[str]) -> str:
    """``(a) & (b)``; ``true`` for no parts."""
    parts = [p for p in parts if p]
    if not parts:
        return "true"
    if len(parts) == 1:
        return parts[0]
    return " & ".join(f"({p})" for p in parts)


def disjunction(parts: Iterable[str]) -> str:
    """``(a) | (b)``; ``false`` for no parts."""
    parts = [p for p in parts if p]
    if not parts:
        return "false"
    if len(parts) == 1:
        return parts[0]
    return " | ".join(f"({p})" for p in parts)


FORMATS = ("prism", "evochecker", "paynt")
"""The syntaxes a decision constant can be declared in (``parley augment --format``)."""


def declaration(name: str, values: Sequence[int], form: str = "prism") -> str:
    """A decision constant's declaration: PRISM's undefined ``const int``, EvoChecker's
    ``evolve int`` with its range, or PAYNT's ``hole`` with its values (in increasing order)."""
    if form == "prism":
        return f"const int {name};"
    if form == "evochecker":
        if list(values) != list(range(values[0], values[-1] + 1)):
            raise ValueError(f"EvoChecker's evolve int needs a range, and {name} takes {list(values)}")
        return f"evolve int {name} [{values[0]}..{values[-1]}];"
    if form == "paynt":
        return f"hole int {name} in {{{','.join(str(v) for v in values)}}};"
    raise ValueError(f"unknown declaration form {form!r}; valid: {', '.join(FORMATS)}")
