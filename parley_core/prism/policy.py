"""Policies written into the original program: the fast path to Storm's values.

Augmentation copies every command that consults a service constant once per observation
valuation, and Storm's explicit builder evaluates every copy's guard in every state (100
copies on a 10x10 map, 2,500 on 50x50). A *policy program* says the same with one command:
the service constant becomes a ``formula`` of the observation variables, a balanced
if-then-else tree over their values whose leaves are the policy's decisions. Storm then
builds exactly the DTMC it builds from the augmented program with the decisions defined:

- at a state whose observation valuation ``v`` has decisions, the augmented program enables
  the copy ``v & guard[c := c_v]``; the policy program enables ``guard[c := tree]``, and the
  tree evaluates to ``c_v`` at ``v``;
- at a valuation left out of the family (no decisions, no copies), the augmented program
  enables none of the command's copies; the policy program conjoins a formula that is false
  there (``parley_kept``);
- bounds that use a service constant are widened the same way (:func:`rewrite.widen_bounds`).

Several policies share one program (a *batch*): a global variable ``parley_policy`` numbers
them, and the trees branch on it first. The program starts in a dispatch state
(``parley_policy = K``, every other variable at its initial value) whose one command, in a
module of its own, moves to ``parley_policy = i`` for each policy ``i``; every other command
is disabled there (its guard gets ``parley_policy < K``). So one parse, one Storm build and
one solver run give the values of them all. The variable never changes after that, so the
states of different policies never meet: apart from the dispatch state the model is the
disjoint union of the policies' DTMCs, and the value at policy ``i``'s start is policy
``i``'s. One initial state, not one per policy through an ``init`` construct: Storm
enumerates those with Z3, in an order that depends on the process's history, and the
numbering of the states, and so the last bits of the values, with it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from attrs import frozen

from parley_core.errors import ModelError
from parley_core.model import Family
from parley_core.prism import program as prism
from parley_core.prism import rewrite
from parley_core.prism.writer import command_line

INDEX = "parley_policy"
"""The global variable that numbers the policies of a batch."""

KEPT = "parley_kept"
"""The formula that is true at the observation valuations that have decisions."""

_FORMULAS = "// __parley_formulas__"
_TOP = "__PARLEY_TOP__"
_START = "__PARLEY_START__"
_SPLIT = "__PARLEY_SPLIT__"

DISPATCH = "parley_dispatch"
"""The module whose one command starts each policy of a batch."""


@frozen(kw_only=True)
class PolicyTemplate:
    """A family's policy program with the formulas and the batch size left open (picklable)."""

    text: str
    constants: tuple[str, ...]
    """The service constants, in the order of the family's services."""
    observation: tuple[str, ...]
    domains: tuple[tuple[int, int, bool], ...]
    """Per observation variable: lowest value, highest value, whether it is boolean."""
    positions: tuple[tuple[int, ...], ...]
    """Per service, per valuation position (lexicographic over ``domains``): the column of
    its decision in a policy vector, -1 where the valuation was left out."""
    fills: tuple[int, ...]
    """Per service, the value its formula takes where no decision is (never used: the
    commands are disabled there)."""
    has_kept: bool

    def render(self, policies: np.ndarray) -> str:
        """The program of a batch: policy ``i`` (row ``i``) starts where ``parley_policy = i``."""
        policies = np.asarray(policies, dtype=np.int64)
        if policies.ndim != 2 or not len(policies):
            raise ValueError("render needs a non-empty [policies, decisions] array")
        shape = tuple(high - low + 1 for low, high, _ in self.domains)
        names = (INDEX, *self.observation)
        lows = (0, *(low for low, _, _ in self.domains))
        booleans = (False, *(boolean for _, _, boolean in self.domains))
        lines = []
        for constant, columns, fill in zip(self.constants, self.positions, self.fills):
            index = np.asarray(columns, dtype=np.int64)
            table = policies[:, np.maximum(index, 0)].reshape((len(policies), *shape))
            known = np.broadcast_to((index >= 0).reshape(shape), table.shape)  # False: no decision here
            lines.append(f"formula {constant} = {tree(table, names, lows, booleans, str(fill), known)};")
        if self.has_kept:
            kept = (np.asarray(self.positions[0]) >= 0).reshape(shape).astype(np.int64)
            lines.append(f"formula {KEPT} = {tree(kept, names[1:], lows[1:], booleans[1:], 'false')};")
        text = self.text.replace(_FORMULAS, "\n".join(lines), 1)
        # One policy starts at parley_policy = 0 (the dispatch value 1 is never reached: the
        # index ranges over two values, because Storm 2.0 (stormpy 2.0.0) sets a wrong
        # initial value for a boolean declared after a global variable of range [0..0],
        # tests/test_batch.py, test_storm_misreads_a_single_valued_global). Several start in
        # the dispatch state parley_policy = K, whose one command moves to each policy's
        # initial state, policy i's with probability (K + i) / total (dispatch_policy): the weights
        # differ, so they tell the starts apart without Storm's state valuations (which cost
        # about a fifth of a robot_grid batch's build).
        count = len(policies)
        top = max(1, count)
        total = _weight_total(count)
        split = (
            " + ".join(f"{count + i}/{total} : ({INDEX}'={i})" for i in range(count)) if count > 1 else f"({INDEX}'=0)"
        )
        text = text.replace(_TOP, str(top)).replace(_SPLIT, split)
        return text.replace(_START, str(top if count > 1 else 0))


def _weight_total(count: int) -> int:
    return count * count + count * (count - 1) // 2


def dispatch_policy(probability: float, count: int) -> int:
    """The policy whose start the dispatch state of a batch of ``count`` reaches with
    ``probability`` (policy ``i``'s is ``(count + i) / total``, ``total`` the sum over the
    batch: distinct weights, the largest at most twice the smallest)."""
    total = _weight_total(count)
    scaled = probability * total
    index = round(scaled) - count
    if not 0 <= index < count or abs(scaled - round(scaled)) > 1e-6:
        raise RuntimeError(f"the dispatch state of {count} policies moves with probability {probability}, no policy's")
    return index


def policy_template(family: Family) -> PolicyTemplate:
    """The policy program of a family augmented from a system model (:func:`Family.origin`)."""
    system = family.origin()
    origin = f"the {system.name} model"
    program = prism.parse_program(system.prism, origin=origin)
    service_vars = rewrite.service_variables(program, system.services, origin)
    manager = program.expression_manager
    if manager.has_variable(INDEX) or manager.has_variable(KEPT) or any(m.name == DISPATCH for m in program.modules):
        raise ModelError(f"{origin} uses the name {INDEX}, {KEPT} or {DISPATCH}; policy programs need them")
    has_kept = bool(family.left_out)
    condition = manager.declare_boolean_variable(KEPT).get_expression() if has_kept else None

    def one_copy(_command, _used: list[str]) -> list[rewrite.Copy]:
        return [rewrite.Copy(mapping={}, condition=condition)]

    rewritten = rewrite.copy_service_commands(program, system, service_vars, one_copy, origin)
    # Storm parses the program with stand-in formulas (so that the rewritten modules are
    # checked), prints it, and the stand-ins' lines become the place of the real ones.
    stand_ins = [f"formula {name} = {service.low};" for name, service in zip(service_vars, system.services)]
    stand_ins += [f"formula {KEPT} = true;"] if has_kept else []
    first = next(iter(service_vars))
    declarations = {name: "" for name in service_vars}
    declarations[first] = "\n".join(stand_ins)
    spliced = prism.splice(program, modules=rewritten.modules, constants=declarations)
    lines = _with_dispatch(prism.parse_program(spliced, origin=f"the policy program of {origin}")).split("\n")
    names = [*service_vars, *([KEPT] if has_kept else [])]
    places = {name: [i for i, line in enumerate(lines) if line.startswith(f"formula {name} = ")] for name in names}
    for name, found in places.items():
        if len(found) != 1:
            raise RuntimeError(f"formula {name} is not printed exactly once in the policy program")
    lines[places[first][0]] = _FORMULAS
    dropped = {found[0] for name, found in places.items() if name != first}
    text = "\n".join(line for i, line in enumerate(lines) if i not in dropped)
    domains = tuple(
        (domain.start, domain.stop - 1, prism.is_boolean(program, name))
        for name, domain in zip(system.observation, rewrite.observation_domains(program, system))
    )
    column = {(d.service.constant, d.valuation): i for i, d in enumerate(family.decisions)}
    every = rewrite.observation_valuations(program, system)
    positions = tuple(tuple(column.get((s.constant, v), -1) for v in every) for s in system.services)
    for service, columns in zip(system.services, positions):
        if sum(c >= 0 for c in columns) != len(family.valuations):
            raise ModelError(f"the {family.name} family's decisions for {service.constant} do not match its valuations")
    return PolicyTemplate(
        text=text,
        constants=tuple(service_vars),
        observation=tuple(system.observation),
        domains=domains,
        positions=positions,
        fills=tuple(s.low for s in system.services),
        has_kept=has_kept,
    )


def _with_dispatch(program) -> str:
    """Storm's printing of ``program`` with :data:`INDEX` declared, every command's guard
    conjoined with ``INDEX < _TOP``, and a module whose one command leaves the dispatch
    state ``INDEX = _TOP`` for each policy's own initial state."""
    modules = {}
    for module in program.modules:
        replacements = {
            command.global_index: [
                command_line(
                    command.action_name,
                    f"({INDEX} < {_TOP}) & ({command.guard_expression})",
                    [str(update) for update in command.updates],
                )
            ]
            for command in module.commands
        }
        modules[module.name] = prism.module_with_commands(module, replacements)
    lines = prism.splice(program, modules=modules).split("\n")
    lines.insert(1, f"global {INDEX} : [0..{_TOP}] init {_START};")
    dispatch = f"module {DISPATCH}\n\t[] ({INDEX} = {_TOP}) -> {_SPLIT};\nendmodule\n"
    return "\n".join(lines) + "\n" + dispatch


_MIXED = object()
"""A subtree whose values differ."""


def tree(
    table: np.ndarray,
    names: Sequence[str],
    lows: Sequence[int],
    booleans: Sequence[bool],
    fill: str,
    known: np.ndarray | None = None,
) -> str:
    """A balanced if-then-else tree over the variables ``names`` (one per dimension of
    ``table``, whose index 0 is the value ``lows[i]``) with ``table``'s values at its leaves.
    Where ``known`` (same shape) is False there is no value, which matches any value (``fill``
    where nothing is known); a subtree
    whose known values agree is that value, with no test."""
    boolean_leaves = fill in ("true", "false")

    def leaf(value: int) -> str:
        if boolean_leaves:
            return "true" if value else "false"
        return str(value)

    def node(values, depth: int) -> tuple[str, object]:
        """The text of a subtree and its value: an int when every known value is that
        int, None when nothing is known, _MIXED otherwise."""
        if depth == len(names):
            return (fill, None) if values is None else (leaf(values), values)
        name, low, boolean = names[depth], lows[depth], booleans[depth]

        def span(first: int, last: int) -> tuple[str, object]:
            if first == last:
                return node(values[first], depth + 1)
            if boolean:
                middle = first
            else:
                middle = (first + last) // 2
            below, above = span(first, middle), span(middle + 1, last)
            if below[1] is None:
                return above
            if above[1] is None or (below[1] is not _MIXED and below[1] == above[1]) or below[0] == above[0]:
                return below
            if boolean:
                return f"({name} ? {above[0]} : {below[0]})", _MIXED
            return f"({name} <= {low + middle} ? {below[0]} : {above[0]})", _MIXED

        return span(0, len(values) - 1)

    table = np.asarray(table, dtype=np.int64)
    mask = np.ones(table.shape, dtype=bool) if known is None else np.asarray(known, dtype=bool)
    values = table.astype(object)
    values[~mask] = None
    values = values.tolist()
    return node(values, 0)[0]
