"""Objectives in the kernels' form: state masks, step bounds and reward rows of the quotient.

A property's shape comes from :func:`parley_core.prism.properties.shape`; its state
formulas (``phi``, ``psi``) are decided by Storm on the quotient MDP, so labels and
expressions mean exactly what they mean to Storm. A property of another shape, or whose
state formulas Storm cannot decide state by state, compiles to None: the evaluator has
Storm check it instead.
"""

from __future__ import annotations

import enum

import numpy as np
import stormpy
from attrs import field, frozen

from parley_core.prism.properties import Shape, reward_name, shape
from parley_core.prism.rewrite import OBSERVATION_REWARD
from parley_core.quotient.mdp import QuotientMDP


class KernelKind(enum.Enum):
    UNTIL = "until"
    """P, unbounded (F or U)"""
    BOUNDED = "bounded"
    """P, step-bounded (F<=k or U<=k)"""
    REACH_REWARD = "reach_reward"
    """R, F"""
    CUMULATIVE = "cumulative"
    """R, C<=k"""
    TOTAL = "total"
    """R, C"""


@frozen(kw_only=True)
class KernelObjective:
    """One objective in a form the kernels solve. ``left``/``right`` are state masks of the
    quotient (phi, psi); ``reward`` is a row of :func:`reward_arrays`."""

    kind: KernelKind
    left: np.ndarray | None = field(default=None, eq=False)
    right: np.ndarray | None = field(default=None, eq=False)
    steps: int = 0
    reward: int = -1
    right_deadlock: bool = False
    """``right`` is the label "deadlock": the quotient's own deadlocks (``right``) and the
    states of a policy's DTMC without a consistent choice, which depend on the policy (the
    solver adds them from its exploration)."""


def reward_names(mdp: QuotientMDP) -> list[str]:
    """The reward structures the objectives use, sorted: the rows of :func:`reward_arrays`."""
    names = set()
    for prop in mdp.properties:
        formula = prop.get_raw_formula()
        if formula.is_reward_operator_formula:
            name = reward_name(formula, mdp.program, (OBSERVATION_REWARD,))
            if name is not None:
                names.add(name)
    return sorted(names)


def reward_arrays(mdp: QuotientMDP, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """State rewards [r, states] and choice rewards [r, choices] (transition rewards folded
    into their choice's expected reward) of the named reward structures (at least one row)."""
    arrays = mdp.arrays
    n = mdp.states
    state_rewards = np.zeros((max(1, len(names)), n))
    choice_rewards = np.zeros((max(1, len(names)), len(mdp.state_of_choice)))
    for r, name in enumerate(names):
        if name not in mdp.reward_names:  # a defect: an objective's structure would read as zero
            raise RuntimeError(f"the quotient has no reward structure {name!r}; it has {sorted(mdp.reward_names)}")
        base = f"annotations/rewards/{name}"
        if f"{base}/states/values.bin" in arrays:
            state_rewards[r] = arrays[f"{base}/states/values.bin"]
        if f"{base}/choices/values.bin" in arrays:
            choice_rewards[r] = arrays[f"{base}/choices/values.bin"]
        if f"{base}/branches/values.bin" in arrays:
            branch_rewards = arrays[f"{base}/branches/values.bin"]
            weighted = branch_rewards * arrays["branch-to-probability.bin"]
            choice_branches = arrays["choice-to-branches.bin"].astype(np.int64)
            choice_rewards[r] += np.add.reduceat(weighted, choice_branches[:-1]) if len(weighted) else 0.0
    return state_rewards, choice_rewards


def states(model, formula) -> np.ndarray | None:
    """The states satisfying a propositional state formula (by Storm), or None if Storm cannot say."""
    try:
        result = stormpy.model_checking(model, formula)
        indices = np.asarray(result.get_truth_values_vector(), dtype=np.int64)
    except (RuntimeError, AttributeError):
        return None
    mask = np.zeros(model.nr_states, dtype=bool)
    mask[indices] = True
    return mask


DEADLOCK = "deadlock"
"""Storm's built-in label of the states without an enabled command."""


def uses_deadlock(formula) -> bool:
    """Whether a state formula mentions the label "deadlock" (found by renaming it)."""
    return str(formula.substitute_labels_by_labels({DEADLOCK: "__parley_probe"})) != str(formula)


def is_deadlock(formula) -> bool:
    """Whether a state formula is the label "deadlock" itself."""
    return isinstance(formula, stormpy.logic.AtomicLabelFormula) and str(formula) == f'"{DEADLOCK}"'


def compile_objective(mdp: QuotientMDP, prop, names: list[str]) -> KernelObjective | None:
    """The kernel form of a property, or None if the quotient evaluator does not support it.

    Storm's "deadlock" label depends on the policy (a decision value may leave a state with
    no enabled command), so the quotient cannot decide it once for all: a target that is
    exactly "deadlock" is taken from each policy's exploration, and any other use of the
    label leaves the objective to Storm."""
    found = shape(prop, mdp.program, (OBSERVATION_REWARD,))
    model = mdp.model
    for part in (found.left, found.right):
        if part is not None and uses_deadlock(part) and not (part is found.right and is_deadlock(part)):
            return None
    dynamic = found.right is not None and is_deadlock(found.right)
    if found.kind in (Shape.UNTIL, Shape.BOUNDED_UNTIL):
        left = np.ones(model.nr_states, bool) if found.left is None else states(model, found.left)
        right = states(model, found.right)
        if left is None or right is None:
            return None
        if found.kind is Shape.UNTIL:
            return KernelObjective(kind=KernelKind.UNTIL, left=left, right=right, right_deadlock=dynamic)
        return KernelObjective(
            kind=KernelKind.BOUNDED, left=left, right=right, steps=found.steps or 0, right_deadlock=dynamic
        )
    if found.kind is Shape.OTHER or found.reward is None:
        return None
    reward = names.index(found.reward)
    if found.kind is Shape.REACH_REWARD:
        right = states(model, found.right)
        if right is None:
            return None
        return KernelObjective(kind=KernelKind.REACH_REWARD, right=right, reward=reward, right_deadlock=dynamic)
    if found.kind is Shape.CUMULATIVE:
        return KernelObjective(kind=KernelKind.CUMULATIVE, steps=found.steps or 0, reward=reward)
    return KernelObjective(kind=KernelKind.TOTAL, reward=reward)
