"""Storm's values of many policies at once: the default verification path.

Each batch of policies is written as one *policy program* (:mod:`parley_core.prism.policy`):
the original model with each service constant a formula of the observation variables and
the policy index, and a dispatch state that starts each policy. Storm parses, builds and
checks it like any program, with the reference evaluator's solver settings
(:func:`storm.check_instance`); the value at the state where ``parley_policy = i`` starts
is policy ``i``'s.

It shares nothing with the quotient evaluator (no quotient, no choice consistency, no UMB
export), and nothing with the reference evaluator but the solver settings: the augmented
program is not read at all, so a defect in augmentation would show up as a disagreement.
It is 2 to 25 times faster than the reference (``benchmarks/verify.py``), because Storm's
builder evaluates one command instead of one copy per observation valuation, and because one
build serves many policies.

Families whose objectives include an unbounded reward (``R=? [F ...]``, ``R=? [C]``) are
checked one policy per program: the reference solves those to a precision relative to the
largest value of the model, which a batch would share between its policies, or exactly
when the model is small. So are objectives that mention the ``"init"`` label, which the
dispatch state of a batch would carry instead of the policies' starts.
"""

from __future__ import annotations

import math

import numpy as np
from attrs import frozen

from parley_core.errors import ModelError
from parley_core.evaluate.pool import PoolOwner, ProcessPool, default_workers, worker_state
from parley_core.evaluate.storm import check_instance, reference_environment, unbounded_reward
from parley_core.model import Family
from parley_core.prism import program as prism
from parley_core.prism.policy import PolicyTemplate, dispatch_policy, policy_template
from parley_core.progress import Progress

BATCH_STATES = 400_000
"""The states a batch aims at: the batch size is this over the states of a policy's DTMC
(measured on the first batch), between 1 and :data:`MAX_BATCH`."""

FIRST_BATCH = 4
MAX_BATCH = 64
SHARES = 4
MIN_SHARE = 16
"""At least this many policies in a batch when splitting for :data:`SHARES` (a batch costs
about 20 ms of parsing and set-up whatever its size: a small model's 48 policies take 45 ms
each one by one, 23 in batches of 6, 15 in one batch; web_ids and tas)."""


@frozen(kw_only=True)
class BatchTask:
    """What a process needs to check batches of one family (picklable)."""

    template: PolicyTemplate
    formulas: tuple[str, ...]
    objective_names: tuple[str, ...]
    lows: tuple[int, ...]
    """A policy to try the program on (every decision at its lowest value)."""

    @classmethod
    def of(cls, family: Family) -> BatchTask:
        return cls(
            template=policy_template(family),
            lows=family.lows,
            formulas=tuple(o.formula for o in family.objectives),
            objective_names=tuple(o.name for o in family.objectives),
        )


class BatchChecker:
    """Checks batches of policies of one family in this process."""

    def __init__(self, task: BatchTask) -> None:
        self.task = task
        self.environment = reference_environment()
        probe = self._program(np.array([task.lows], dtype=np.int64).reshape(1, -1))
        properties = prism.parse_properties(task.formulas, probe, origin="objective")
        self.unbounded = [unbounded_reward(p) for p in properties]
        self.single = any(self.unbounded) or any('"init"' in f for f in task.formulas)
        """Whether every policy needs a program of its own (module docstring)."""

    def _program(self, policies: np.ndarray):
        return prism.parse_program(self.task.template.render(policies), origin="the policy program")

    def check(self, policies: np.ndarray) -> tuple[np.ndarray, int]:
        """Values [len(policies), objectives] and the batch model's number of states."""
        program = self._program(policies)
        properties = prism.parse_properties(self.task.formulas, program, origin="objective")
        model, at, rows = check_instance(
            program,
            properties,
            self.task.objective_names,
            self.unbounded,
            self.environment,
            at=lambda model: starts(model, len(policies)),
        )
        out = np.asarray(rows, dtype=float).reshape(len(policies), len(self.task.formulas))
        # the dispatch state is not a policy's: without it, the batch's states are the policies'
        return out, int(model.nr_states) - (len(policies) > 1)


def starts(model, count: int) -> list[int]:
    """The states where the policies of a batch of ``count`` start, in the policies' order:
    the initial state of a single policy, else the successors of the dispatch state (the
    only initial state), told apart by the probability of moving there
    (:func:`~parley_core.prism.policy.dispatch_policy`)."""
    if len(model.initial_states) != 1:
        raise ModelError(
            f"the policy program has {len(model.initial_states)} initial states; parley needs exactly one "
            "(every variable needs one initial value)"
        )
    initial = model.initial_states[0]
    if count == 1:
        return [initial]
    found: dict[int, int] = {}
    for entry in model.transition_matrix.get_row(initial):
        found[dispatch_policy(float(entry.value), count)] = entry.column
    if sorted(found) != list(range(count)):
        raise RuntimeError(f"the dispatch state of {count} policies reaches the starts of {sorted(found)}")
    return [found[i] for i in range(count)]


def _worker_check(task: BatchTask, policies: np.ndarray) -> tuple[np.ndarray, int]:
    return worker_state(BatchChecker, task).check(policies)


def _worker_ready(task: BatchTask) -> None:
    worker_state(BatchChecker, task)


class BatchStormEvaluator(PoolOwner):
    """Evaluate policies with Storm in batches, in this process or in ``workers`` processes."""

    name = "storm"

    def __init__(self, family: Family, workers: int | None = None) -> None:
        self.family = family
        self.task = BatchTask.of(family)
        self.local = BatchChecker(self.task)
        self.workers = default_workers(workers)
        self._pool: ProcessPool | None = None
        self.states_per_policy: float | None = None
        """Measured on the first batch; sets the batch size."""
        self.states = 0
        """States built so far (without the dispatch states)."""

    def batch_size(self, remaining: int) -> int:
        if self.local.single:
            return 1
        if self.states_per_policy is None:
            return min(FIRST_BATCH, remaining)
        size = int(BATCH_STATES / max(1.0, self.states_per_policy))
        # At least SHARES batches, so that two workers finish together. Not a function of the
        # worker count: a policy's value depends on its batch in the last bits (the solver
        # stops when the whole batch has converged), and a run's values should not depend
        # on --workers.
        share = max(MIN_SHARE, math.ceil(remaining / SHARES))
        return max(1, min(size, MAX_BATCH, share, remaining))

    def describe(self) -> dict[str, object]:
        return {}

    def evaluate(self, policies: np.ndarray, progress: Progress | None = None) -> np.ndarray:
        policies = np.asarray(policies, dtype=np.int64).reshape(-1, len(self.family.decisions))
        out = np.empty((len(policies), len(self.family.objectives)))
        parallel = self.workers > 1 and len(policies) > FIRST_BATCH + 1
        warm: list = []
        if parallel and self._pool is None:
            # the workers start (import Storm, parse the template) while the first batch runs here
            warm = [self._executor().submit(_worker_ready, self.task) for _ in range(self.workers)]
        start = 0
        if self.states_per_policy is None and len(policies):
            start = self.batch_size(len(policies))
            out[:start], states = self.local.check(policies[:start])
            self.states_per_policy = states / start
            self.states += states
            if progress:
                progress(start)
        batches = []
        while start < len(policies):
            size = self.batch_size(len(policies) - start)
            batches.append((start, start + size))
            start += size
        if parallel and len(batches) > 1:
            for ready in warm:
                ready.result()
            futures = [self._executor().submit(_worker_check, self.task, policies[a:b]) for a, b in batches]
            results = (future.result() for future in futures)
        else:
            results = (self.local.check(policies[a:b]) for a, b in batches)
        for (first, last), (values, states) in zip(batches, results):
            out[first:last] = values
            self.states += states
            if progress:
                progress(last - first)
        return out
