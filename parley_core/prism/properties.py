"""What a property asks, classified once: the shapes the quotient solves and the simulator estimates.

:func:`shape` reads a parsed property through stormpy's formula classes and predicates
(``is_eventually_formula``, ``is_until_formula``, ``is_bounded_until_formula``). stormpy
does not bind the step bound of a cumulative reward formula nor a class for the total
reward formula, so those two are read from Storm's own printing of the path formula
(``C<=100``, ``C``), here and nowhere else.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable

import attrs
import stormpy.logic as logic
from attrs import field, frozen

from parley_core.errors import ModelError
from parley_core.model import SystemModel
from parley_core.prism import program as prism
from parley_core.prism.program import PrismProgram


class Shape(enum.Enum):
    """The kinds of ``=?`` queries parley's own solvers know."""

    UNTIL = "until"
    """``P=? [F psi]`` or ``P=? [phi U psi]``"""
    BOUNDED_UNTIL = "bounded until"
    """``P=? [F<=k psi]`` or ``P=? [phi U<=k psi]``"""
    REACH_REWARD = "reachability reward"
    """``R=? [F psi]``"""
    CUMULATIVE = "cumulative reward"
    """``R=? [C<=k]``"""
    TOTAL = "total reward"
    """``R=? [C]``"""
    OTHER = "other"


@frozen(kw_only=True)
class PropertyShape:
    """A property's shape and its parts. ``left`` and ``right`` are stormpy state formulas
    (``left`` None: ``true``, as in ``F psi``); ``steps`` the step bound; ``reward`` the
    reward structure's name (resolved when the program has exactly one and the property
    names none); ``reason`` says why a property is ``OTHER``."""

    kind: Shape
    left: object | None = field(default=None, eq=False)
    right: object | None = field(default=None, eq=False)
    steps: int | None = None
    reward: str | None = None
    reason: str = ""

    @property
    def is_probability(self) -> bool:
        return self.kind in (Shape.UNTIL, Shape.BOUNDED_UNTIL)


def _other(reason: str) -> PropertyShape:
    return PropertyShape(kind=Shape.OTHER, reason=reason)


def _is_true(formula) -> bool:
    return isinstance(formula, logic.BooleanLiteralFormula) and str(formula) == "true"


def reward_name(formula, program, ignore: Iterable[str] = ()) -> str | None:
    """The reward structure a reward operator formula refers to: its own name, else the
    program's only one (None if it has several or none); structures in ``ignore`` (parley's
    own) do not count."""
    if formula.has_reward_model_name():
        return formula.reward_name
    structures = prism.reward_structures(program, ignore)
    return structures[0] if len(structures) == 1 else None


def check_objectives(system: SystemModel, program: PrismProgram) -> None:
    """Each objective parses on the system's model (``program``, parsed) and names only
    labels and reward structures it has; a :class:`ModelError` names the objective and what
    the model has (Storm itself would only stop when building, or say nothing of a missing
    label)."""
    labels = [label.name for label in program.labels]
    for objective in system.objectives:
        origin = f"objective {objective.name!r}"
        (prop,) = prism.parse_properties([objective.formula], program, origin=origin)
        prism.check_property_references(prop, program, origin=origin)
        printed = str(prop.get_raw_formula().subformula).split('"')[1::2]  # Storm prints labels quoted
        missing = sorted({name for name in printed if name not in {"init", "deadlock"} and name not in labels})
        if missing:
            quoted = ", ".join(f'"{name}"' for name in missing)
            have = ", ".join(f'"{name}"' for name in labels) or "none"
            raise ModelError(
                f"{origin} ({objective.formula}) uses label {quoted}, which the {system.name} model lacks; "
                f"its labels: {have}"
            )


def name_unnamed_rewards(system: SystemModel, program: PrismProgram) -> SystemModel:
    """The system with every objective ``R=? [...]`` that names no reward structure, in a
    model (``program``, parsed) with several, naming the first one, as PRISM does (Storm
    refuses such a property as ambiguous); ``system.notes`` says so. Both evaluators then
    read the same structure."""
    structures = prism.reward_structures(program)
    if len(structures) < 2:
        return system
    objectives, notes = [], list(system.notes)
    for objective in system.objectives:
        (prop,) = prism.parse_properties([objective.formula], program, origin=f"objective {objective.name!r}")
        formula = prop.get_raw_formula()
        if formula.is_reward_operator_formula and not formula.has_reward_model_name():
            first = structures[0]
            if not first:
                raise ModelError(
                    f"objective {objective.name!r} names no reward structure and the first of the model's "
                    f'{len(structures)} has no name; name them and write R{{"name"}}=? [...]'
                )
            named = f'R{{"{first}"}}' + str(formula)[1:]
            prism.parse_properties([named], program, origin=f"objective {objective.name!r}")
            notes.append(
                f"objective {objective.name} names no reward structure and the model has {len(structures)}; "
                f'parley uses the first, "{first}", as PRISM does: {named}'
            )
            objective = attrs.evolve(objective, formula=named)
        objectives.append(objective)
    return attrs.evolve(system, objectives=objectives, notes=tuple(notes))


def shape(prop, program, ignore: Iterable[str] = ()) -> PropertyShape:
    """The shape of a parsed property (``stormpy.Property``) of ``program``; reward
    structures in ``ignore`` (parley's own) do not count when a property names none."""
    formula = prop.get_raw_formula()
    if not (formula.is_probability_operator_formula or formula.is_reward_operator_formula):
        return _other("it is neither a P nor an R operator")
    if formula.has_bound or formula.has_optimality_type:
        return _other("it is not a query of the form P=? or R=?")
    sub = formula.subformula
    if formula.is_probability_operator_formula:
        if sub.is_eventually_formula:
            return PropertyShape(kind=Shape.UNTIL, right=sub.subformula)
        if sub.is_until_formula:
            return PropertyShape(kind=Shape.UNTIL, left=sub.left_subformula, right=sub.right_subformula)
        if sub.is_bounded_until_formula:
            if sub.has_lower_bound or sub.is_multi_dimensional:
                return _other("its step bound has a lower bound or several dimensions")
            steps = prism.fixed_int(sub.upper_bound_expression)
            if steps is None:
                return _other("its step bound is not a fixed integer")
            left = None if _is_true(sub.left_subformula) else sub.left_subformula
            return PropertyShape(kind=Shape.BOUNDED_UNTIL, left=left, right=sub.right_subformula, steps=steps)
        return _other("its path formula is not F, U, F<=k or U<=k")
    reward = reward_name(formula, program, ignore)
    if sub.is_eventually_formula:
        return PropertyShape(kind=Shape.REACH_REWARD, right=sub.subformula, reward=reward)
    text = str(sub)  # stormpy binds neither the bound of C<=k nor a class for C
    if isinstance(sub, logic.CumulativeRewardFormula) and text.startswith("C<=") and text[3:].isdigit():
        return PropertyShape(kind=Shape.CUMULATIVE, steps=int(text[3:]), reward=reward)
    if text == "C":
        return PropertyShape(kind=Shape.TOTAL, reward=reward)
    return _other("its reward path formula is not F, C<=k or C")
