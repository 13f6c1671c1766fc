"""A family's view of the quotient: which decision each choice needs (PAYNT's coloring),
packed with the transition, reward and objective arrays into a picklable :class:`Quotient`.

A choice carries the (service, value) pairs of the commands it came from; its decision is
the family's decision for that service at the choice's state's observation valuation. A
policy keeps the choices whose every pair agrees with it.
"""

from __future__ import annotations

import numpy as np
from attrs import field, frozen

from parley_core.model import Family
from parley_core.quotient.compile import KernelObjective, compile_objective, reward_arrays, reward_names
from parley_core.quotient.mdp import QuotientMDP, build_mdp


@frozen(kw_only=True)
class Quotient:
    """The quotient MDP as arrays (picklable): CSR over choices and branches, each choice's
    (decision index, value) pairs (-1: none), rewards, and the objectives' kernel forms."""

    states: int
    initial: int
    state_choices: np.ndarray = field(eq=False)
    choice_branches: np.ndarray = field(eq=False)
    targets: np.ndarray = field(eq=False)
    probabilities: np.ndarray = field(eq=False)
    choice_dec: np.ndarray = field(eq=False)
    choice_val: np.ndarray = field(eq=False)
    state_rewards: np.ndarray = field(eq=False)
    choice_rewards: np.ndarray = field(eq=False)
    objectives: tuple[KernelObjective | None, ...]
    """One per family objective; None where Storm must evaluate it."""

    @property
    def choices(self) -> int:
        return int(self.state_choices[-1])

    @property
    def branches(self) -> int:
        return len(self.targets)


def choice_decisions(mdp: QuotientMDP, family: Family) -> np.ndarray:
    """Per choice and service column, the index of the family decision it needs (-1: none)."""
    width = len(family.services)
    full_index = {v: i for i, v in enumerate(mdp.valuations)}
    decision_of = np.full((len(mdp.valuations), width), -1, dtype=np.int64)
    services = {s.constant: i for i, s in enumerate(family.services)}
    for index, decision in enumerate(family.decisions):
        decision_of[full_index[decision.valuation], services[decision.service.constant]] = index
    service = mdp.service_of_choice
    return np.where(service >= 0, decision_of[mdp.obs_of_choice[:, None], np.maximum(service, 0)], -1)


def build_quotient(family: Family, mdp: QuotientMDP | None = None) -> Quotient:
    """The family's quotient; ``mdp`` must have been built with the family's objectives
    (by default it is built here)."""
    if mdp is None:
        mdp = build_mdp(family.origin(), [o.formula for o in family.objectives], [o.name for o in family.objectives])
    choice_dec = choice_decisions(mdp, family)
    if ((mdp.service_of_choice >= 0) & (choice_dec < 0)).any():
        raise RuntimeError("a reachable observation valuation has no decision")
    names = reward_names(mdp)
    state_rewards, choice_rewards = reward_arrays(mdp, names)
    arrays = mdp.arrays
    return Quotient(
        states=mdp.states,
        initial=mdp.initial,
        state_choices=mdp.state_choices,
        choice_branches=arrays["choice-to-branches.bin"].astype(np.int64),
        targets=arrays["branch-to-target.bin"].astype(np.int64),
        probabilities=arrays["branch-to-probability.bin"].astype(np.float64),
        choice_dec=choice_dec.astype(np.int64),
        choice_val=mdp.value_of_choice.astype(np.int64),
        state_rewards=state_rewards,
        choice_rewards=choice_rewards,
        objectives=tuple(compile_objective(mdp, prop, names) for prop in mdp.properties),
    )
