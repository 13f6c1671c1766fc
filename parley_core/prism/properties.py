"""What a property asks, classified once: the shapes the quotient solves and the simulator estimates.

:func:`shape` reads a parsed property through stormpy's formula classes and predicates
(``is_eventually_formula``, ``is_until_formula``, ``is_bounded_until_formula``). stormpy
does not bind the step bound of a cumulative reward formula nor a class for the total
reward formula, so those two are read from Storm's own printing of the path formula
(``C<=100``, ``C``), here and nowhere else.
"""

from __future__ import annotations

import enum

import stormpy.logic as logic
from attrs import field, frozen

from parley_core.prism import program as prism


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


def reward_name(formula, program) -> str | None:
    """The reward structure a reward operator formula refers to: its own name, else the
    program's only one (None if it has several or none)."""
    if formula.has_reward_model_name():
        return formula.reward_name
    models = list(program.reward_models)
    return models[0].name if len(models) == 1 else None


def shape(prop, program) -> PropertyShape:
    """The shape of a parsed property (``stormpy.Property``) of ``program``."""
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
    reward = reward_name(formula, program)
    if sub.is_eventually_formula:
        return PropertyShape(kind=Shape.REACH_REWARD, right=sub.subformula, reward=reward)
    text = str(sub)  # stormpy binds neither the bound of C<=k nor a class for C
    if isinstance(sub, logic.CumulativeRewardFormula) and text.startswith("C<=") and text[3:].isdigit():
        return PropertyShape(kind=Shape.CUMULATIVE, steps=int(text[3:]), reward=reward)
    if text == "C":
        return PropertyShape(kind=Shape.TOTAL, reward=reward)
    return _other("its reward path formula is not F, C<=k or C")
