"""Which value each decision of a policy should move to: policy improvement on the relaxation.

The search's evaluator says how good a policy is; this module says in which direction to
change it. For a policy and a weighting ``w >= 0`` of the objectives (in sign space, every
objective maximised, as in :mod:`parley_core.quotient.bounds`), it computes on the quotient's
relaxation (:mod:`parley_core.quotient.relaxation`), restricted to the policy's own actions
(one per state: the uniform mix of its consistent choices, or the deadlock):

- the policy's time-dependent weighted value ``V_t(s)`` of every state, by backward induction
  over the objectives' horizon (the weighted sum of step-bounded rewards and at most one
  reachability objective, as :func:`~parley_core.quotient.subfamily.weighted_horizon` solves it
  over all schedulers; past the horizon an unbounded reachability objective is worth the
  policy's own probability to reach);
- the policy's occupancy ``mu_t(s)``, forward from the initial state;
- per decision ``d`` and value ``k`` the score ``sum_t sum_s mu_t(s) Q_t(s, k)``, over the
  states that consult ``d``, where ``Q_t(s, k)`` is the value of taking at ``s`` an action
  that assigns ``k`` to ``d`` (the best such, if ``s`` consults other decisions too) and
  following the policy afterwards.

By the performance-difference lemma, ``score[d, k] - score[d, current]`` is the first-order
change of the policy's weighted value if it chose ``k`` for ``d``: exact where one state
consults ``d`` once, an estimate where many states share it (they all change together). So
moving every decision to its best-scored value is a step of policy iteration restricted to
policies that decide by what the controller observes; unlike policy iteration on an MDP it
need not improve, which is why the search evaluates every step
(:mod:`parley_core.search.guide`). Nothing here is a value the run reports: scores only
choose which policies get evaluated.

Memory: a step's values are kept at the states listed for that step only (on map_10, 168,000
entries instead of 101 x 21,073), each two floats per objective.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from parley_core.model import Family
from parley_core.quotient import subfamily as k
from parley_core.quotient.bounds import RelaxedObjectives
from parley_core.quotient.coloring import Quotient
from parley_core.quotient.gradient import (
    Dense,
    Listing,
    Reach,
    Relaxed,
    StepRewards,
    backward,
    chosen_rewards,
    deviations,
    forward,
    representatives,
)

REACH_TOLERANCE = 1e-6
REACH_SWEEPS = 200
"""The policy's probability to reach past the horizon is a guide, not a bound: iterated to
this tolerance (at most this many sweeps)."""


class PolicyImprover:
    """Scores of every decision's values for policies of one family (see the module).

    ``available`` is False, with the reason in ``unavailable``, where the objectives do not
    combine into a weighted sum on the relaxation (the same condition as the Pareto outer
    bound's: step-bounded rewards and at most one reachability objective)."""

    def __init__(
        self, family: Family, quotient: Quotient, relaxed: RelaxedObjectives | None = None, threads: int = 1
    ) -> None:
        self.family = family
        self.threads = max(1, int(threads))
        self._pool: ThreadPoolExecutor | None = None
        self.bounds = b = relaxed if relaxed is not None else RelaxedObjectives(family, quotient)
        self.relaxation = r = b.relaxation
        self.signs = b.signs
        self.unavailable = "" if b.weighted_ok else "the objectives do not combine into a weighted sum"
        self.cumulative, self.rows, self.steps = b.cumulative, b.cumulative_rows, b.cumulative_steps
        self.until, self.until_steps, self.horizon = b.until, b.until_steps, b.weighted_horizon
        n = r.states
        self.left, self.right = np.ones(n, dtype=bool), np.zeros(n, dtype=bool)
        if self.until >= 0:
            self.left, self.right = b.left[self.until], b.right[self.until]
        self.live = np.ones(n, dtype=bool)
        self.sizes = np.asarray(r.domain_sizes, dtype=np.int64)
        domains = [np.asarray(d.service.values, dtype=np.int64) for d in family.decisions]
        self.table = np.full((len(domains), max((len(v) for v in domains), default=0)), -1, dtype=np.int64)
        """Per decision and position in its domain, the value (-1 past the domain)."""
        for d, domain in enumerate(domains):
            self.table[d, : len(domain)] = domain
        self._where = [{int(v): i for i, v in enumerate(domain)} for domain in domains]
        self.same = representatives(r.state_actions, r.action_entries, r.targets, r.probabilities, r.rewards)
        self.arrays = Relaxed(
            r.state_actions, r.action_entries, r.targets, r.probabilities, r.state_decisions, r.decisions
        )
        """The relaxation's arrays as the compiled loops of the scores read them."""

    @property
    def available(self) -> bool:
        return not self.unavailable

    def positions(self, policy: np.ndarray) -> np.ndarray:
        """Per decision the position of the policy's value in the decision's domain (the
        ``indices`` the other methods take)."""
        return np.array([where[int(v)] for where, v in zip(self._where, policy)], dtype=np.int64)

    def values(self, positions: np.ndarray) -> np.ndarray:
        """The policy (its values) at these positions: the inverse of :meth:`positions`."""
        return self.table[np.arange(len(positions)), np.asarray(positions, dtype=np.int64)]

    def chosen(self, indices: np.ndarray) -> np.ndarray:
        """The policy's action in every state of the relaxation (``indices``: per decision
        the position of its value in the decision's domain)."""
        r = self.relaxation
        indices = np.asarray(indices, dtype=np.int64)
        allowed = k.allowed_actions(r.state_actions, r.state_decisions, r.decisions, r.domain_sizes, indices, indices)
        actions = np.flatnonzero(allowed)
        if len(actions) != r.states:
            raise RuntimeError(f"a policy keeps {len(actions)} actions of the relaxation's {r.states} states")
        return actions

    def gradients(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per objective ``i`` (sign space) ``score[i, d, k]`` for every decision and value
        (-inf past a decision's domain), and the policy's values (sign space) at the initial
        state. Values and scores are linear in the objectives' weights, so the scores of a
        weighting ``w`` are ``w @ score`` over the first axis (:meth:`improve`)."""
        if not self.available:
            raise RuntimeError(f"no policy improvement here: {self.unavailable}")
        r, b = self.relaxation, self.bounds
        channels = len(self.signs)
        chosen = self.chosen(indices)
        unit = np.eye(channels) * self.signs
        coefficients = np.ascontiguousarray(unit[:, self.cumulative])
        has_until = self.until >= 0
        gain = np.ascontiguousarray(unit[:, self.until]) if has_until else np.zeros(channels)
        terminal = np.zeros((r.states, channels))
        if has_until and self.until_steps < 0:
            allowed = np.zeros(r.actions, dtype=bool)
            allowed[chosen] = True
            reach = k.reach_probability(
                r.state_actions, r.action_entries, r.targets, r.probabilities, allowed, self.live,
                self.left, self.right, True, *b.pred, REACH_TOLERANCE, REACH_SWEEPS,
            )  # fmt: skip
            terminal = np.ascontiguousarray(reach[:, None] * gain[None, :])
        horizon, n = self.horizon, r.states
        rewards = (r.rewards, self.rows, self.steps, coefficients)
        ends = sorted({0, *[int(x) for x in self.steps if x <= horizon], horizon + 1})
        window = np.array([max(i for i, e in enumerate(ends) if e <= t) for t in range(horizon + 1)], dtype=np.int64)
        rewards_by_window = np.empty((len(ends), n, channels))  # the chosen actions' rewards, where they stay
        for i, e in enumerate(ends):
            if e <= horizon:
                chosen_rewards(*rewards, e, chosen, rewards_by_window[i])
        pointers, listed, on_policy = deviations(
            r.initial, horizon, chosen, r.state_actions, r.action_entries, r.targets, r.state_decisions, self.same
        )
        # each step's values at its listed states only; dense arrays carry a step to the next
        values_at = np.empty((len(listed), 2, channels))
        dense = [np.empty((n, channels)) for _ in range(4)]
        listing = Listing(pointers, listed, on_policy)
        reach = Reach(has_until, self.left, self.right, self.until_steps)
        backward(
            listing,
            horizon,
            chosen,
            self.arrays,
            rewards_by_window,
            window,
            reach,
            gain,
            terminal,
            values_at,
            Dense(*dense),
        )
        values = np.array(values_at[0, 0 if has_until else 1])  # the initial state, listed first at step 0

        score = np.zeros((channels, len(self.sizes), int(self.sizes.max()) if len(self.sizes) else 0))
        masses = np.zeros((2, 2, n))  # [step parity, pending or not, state]
        masses[0, 0 if has_until else 1, r.initial] = 1.0
        stamp, known = np.zeros(r.actions + 1, dtype=np.int64), np.empty((r.actions, channels))
        work = (masses, score, stamp, known)
        forward(
            listing,
            horizon,
            chosen,
            self.arrays,
            StepRewards(*rewards),
            reach,
            self.sizes,
            self.same,
            work,
            values_at,
            (dense[0], dense[1]),
        )
        for d, size in enumerate(self.sizes):
            score[:, d, size:] = -np.inf
        return score, values

    def gradients_of(self, policies: Sequence[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:
        """:meth:`gradients` of several policies (position indices, as there), in order; on
        ``threads`` threads where there are several (the compiled loops release the GIL, and
        a policy's scores do not depend on the others', so the results are the same as one
        at a time). The threads stay for the next call until :meth:`close`."""
        if self.threads == 1 or len(policies) < 2:
            return [self.gradients(p) for p in policies]
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix="parley-scores")
        return list(self._pool.map(self.gradients, policies))

    def close(self) -> None:
        """End the threads of :meth:`gradients_of` (a later call starts them again)."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    @staticmethod
    def improve(indices: np.ndarray, gradients: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """The policy with every decision at its best value under ``weights`` by the scores of
        :meth:`gradients` (a decision keeps its value unless another scores better by more
        than rounding)."""
        indices = np.asarray(indices, dtype=np.int64)
        with np.errstate(invalid="ignore"):
            score = np.tensordot(np.asarray(weights, dtype=float), gradients, axes=1)
        score = np.where(np.isnan(score), -np.inf, score)
        rows = np.arange(len(indices))
        current = score[rows, indices]
        best = score.argmax(axis=1)
        better = score[rows, best] > current + 1e-12 * np.maximum(1.0, np.abs(current))
        return np.where(better, best, indices)


def improver_for(family: Family, quotient: Quotient | None, threads: int = 1) -> PolicyImprover | str:
    """The family's :class:`PolicyImprover`, or why there is none (no quotient, objectives that
    do not combine): a search builds it once for its walks and its polishing. ``threads``:
    how many policies' scores it computes at once (:meth:`PolicyImprover.gradients_of`)."""
    if quotient is None:
        return "the evaluator has no quotient"
    improver = PolicyImprover(family, quotient, threads=threads)
    return improver if improver.available else improver.unavailable
