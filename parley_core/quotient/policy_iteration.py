"""Policy iteration on a sub-family's relaxation: the best scheduler it finds for an expected
reward until a target, its values and its expected steps.

Only a guess: :meth:`~parley_core.quotient.bounds.RelaxedObjectives._least_rewards` lowers
it to a post-fixpoint before it bounds anything. Each round solves the chosen actions'
equations with the states that only pass on (one transition, probability 1: dpm's tick1,
half its states) substituted away (:func:`~parley_core.quotient.kernels.lump`), in the
model's elimination order (:mod:`~parley_core.quotient.ordering`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from parley_core.quotient import kernels as kq
from parley_core.quotient import ordering
from parley_core.quotient import subfamily as k
from parley_core.quotient.relaxation import Relaxation

ITERATIONS = 20
"""Rounds at most (each a sparse solve)."""


class _Chosen:
    """One scheduler's equations over the local states: its transitions, which states pass
    on, and the factors of the rest in elimination order."""

    def __init__(self, r: Relaxation, rank: np.ndarray, states: np.ndarray, index: np.ndarray, actions) -> None:
        self.size = len(states)
        self.matrix = kq.chosen_rows(actions, r.action_entries, r.targets, r.probabilities, index)
        pointers, columns, weights = self.matrix
        self.through = kq.pass_through(
            self.size, pointers, columns, weights, np.zeros(self.size, dtype=bool), self.size
        )
        passed = self.through >= 0
        self.unknown = ordering.in_order(np.flatnonzero(~passed), rank[states[~passed]])
        self.factors: Any = None

    def solve(self, constant: np.ndarray) -> np.ndarray:
        """x = constant + P x over the local states (RuntimeError where it is singular)."""
        pointers, columns, weights = self.matrix
        ptr, columns, weights, lumped = kq.lump(self.size, pointers, columns, weights, self.through, constant)
        data, indices, pointers, rhs = kq.equations(ptr, columns, weights, self.unknown, np.zeros(self.size), lumped)
        if self.factors is None:
            self.factors = ordering.factor(data, indices, pointers)[1]
        x = np.zeros(self.size)
        with np.errstate(all="ignore"):
            x[self.unknown] = self.factors.solve(rhs)
        kq.unlump(self.through, constant, x)
        return x


def best_scheduler(r: Relaxation, rank: np.ndarray, allowed: np.ndarray, reward: np.ndarray, free: np.ndarray,
                   x: np.ndarray, start: np.ndarray):  # fmt: skip
    """The values, expected steps and actions of the best scheduler policy iteration finds on
    ``free`` (the ``allowed`` actions; ``rank``: the relaxation's elimination order) from
    ``start`` (an action per state, -1 where it takes the greedy one of ``x``); None if a
    solve fails (a scheduler that does not reach the target)."""
    index = np.full(r.states, -1, dtype=np.int64)
    states = np.flatnonzero(free)
    index[states] = np.arange(len(states))
    guess = chosen = equations = None
    current = start
    values = x
    for _ in range(ITERATIONS):
        actions = k.greedy(r.state_actions, r.action_entries, r.targets, r.probabilities, allowed, free, reward,
                           values, current, guess is None)[states]  # fmt: skip
        if (actions < 0).any() or (chosen is not None and (actions == chosen).all()):
            break
        trying = _Chosen(r, rank, states, index, actions)
        try:
            solved = trying.solve(reward[actions])
        except RuntimeError:  # singular: the scheduler does not reach the target
            break
        if not np.isfinite(solved).all() or (solved < -1e-9).any():
            break
        chosen, guess, equations = actions, np.maximum(solved, 0.0), trying
        values = np.where(free, 0.0, x)
        values[states] = guess
        current = np.full(r.states, -1, dtype=np.int64)
        current[states] = chosen
    if guess is None or equations is None or chosen is None:
        return None
    steps = equations.solve(np.ones(len(states)))
    if not np.isfinite(steps).all():
        return None
    out, length, policy = np.zeros(r.states), np.zeros(r.states), np.full(r.states, -1, dtype=np.int64)
    out[states], length[states], policy[states] = guess, steps, chosen
    return out, length, policy
