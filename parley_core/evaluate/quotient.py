"""The fast evaluator: one quotient MDP per family, every policy solved on it.

The quotient (:mod:`parley_core.quotient`) holds every policy of the family; a policy keeps
the consistent choices, a state mixes them uniformly and a state left without one loops on
itself and earns no reward, exactly as Storm builds the policy's DTMC. Objectives:
``P=? [F phi]``, ``P=? [phi U psi]``, ``P=? [phi U<=k psi]`` (and ``F<=k``), ``R=? [F phi]``,
``R=? [C<=k]`` and ``R=? [C]``, with propositional ``phi`` and ``psi`` (their states are found
by Storm on the quotient). Any other objective is evaluated by the Storm evaluator, and
:attr:`QuotientEvaluator.fallback` names it.
"""

from __future__ import annotations

import time

import numpy as np

from parley_core.boxes import Box, BoxValues, Ready, box_rows, local_front
from parley_core.evaluate.pool import ProcessPool, default_workers, spawn_pool, stop_pool
from parley_core.evaluate.storm import StormEvaluator
from parley_core.model import Family
from parley_core.progress import Progress
from parley_core.quotient.coloring import Quotient, build_quotient
from parley_core.quotient.forward import BoxWalker
from parley_core.quotient.mdp import QuotientMDP
from parley_core.quotient.solver import QuotientSolver

_SOLVER: list[QuotientSolver] = []
"""Per worker process: its solver, set once by the pool's initializer."""
_WALKER: list[BoxWalker] = []
"""Per worker process: its box walker, made when first needed."""
PROBE = 512
"""Policies of the first box that both box solvers are timed on (:meth:`QuotientEvaluator.box_fronts`)."""

START_WORKERS = 64
"""The smallest batch that starts the worker processes (about 2 s on this machine)."""
CHUNKS = (4, 16)
"""The fewest and most chunks a large batch is split into per worker. A generation ends
when its last chunk does: on a 50x50 map, whose policies take 5 to 100 ms, 16 chunks a
worker instead of 4 took its search from 69 to 65 s; on map_10 (1.5 ms a policy) a chunk
must hold a dozen policies to keep the round trip to a worker small (:data:`CHUNK_SECONDS`)."""
CHUNK_SECONDS = 0.02
"""The least time a chunk should take, as the last large batch's time a policy predicts."""
SHARE_SMALL = 16
"""The smallest batch split over workers already running: 16 policies of map_10 take about
25 ms here, a round trip to a worker well under 1 ms."""


def _worker_start(quotient: Quotient) -> None:
    _SOLVER[:] = [QuotientSolver(quotient)]
    _WALKER.clear()


def _domain_table(domains: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The decisions' domains as one flat array and its pointers (for :class:`BoxWalker`)."""
    pointers = np.zeros(len(domains) + 1, dtype=np.int64)
    pointers[1:] = np.cumsum([len(d) for d in domains])
    flat = np.concatenate(domains) if domains else np.zeros(0, dtype=np.int64)
    return pointers, flat.astype(np.int64)


def _solve_rows(solver: QuotientSolver, rows: np.ndarray, n_objectives: int, progress=None):
    """Values and consulted decisions of ``rows`` on one solver (None: a value it leaves to Storm)."""
    values = np.empty((len(rows), n_objectives))
    consulted = np.zeros(rows.shape, dtype=bool)
    for i, row in enumerate(rows):
        values[i] = [np.nan if v is None else v for v in solver.solve(row)]
        consulted[i] = solver.consulted
        if progress:
            progress(1)
    return values, consulted


def _worker_solve(rows: np.ndarray, n_objectives: int) -> tuple[np.ndarray, np.ndarray, int]:
    solver = _SOLVER[0]
    before = solver.direct_solves
    values, consulted = _solve_rows(solver, rows, n_objectives)
    return values, consulted, solver.direct_solves - before


def _box_fronts(solver: QuotientSolver, boxes: list[Box], domains, signs, n_objectives: int, walker=None):
    """Each box's policies solved and cut to the box's own front (:func:`.local_front`):
    (rows, values) of the fronts, in box order, and the rows whose values the quotient could
    not certify (for Storm), the policies solved and the direct solves. With a ``walker``
    (:class:`BoxWalker`), each box is walked as a whole instead of solved policy by policy;
    last, the seconds it took."""
    began = time.perf_counter()
    before = solver.direct_solves
    rows_out, values_out, unsure, solved = [], [], [], 0
    table = _domain_table(domains) if walker is not None else None
    for box in boxes:
        if walker is not None and table is not None:
            rows, values = walker.solve(box, *table)
        else:
            rows = box_rows(box, domains)
            values, _ = _solve_rows(solver, rows, n_objectives)
        solved += len(rows)
        keep = local_front(values, signs)
        rows_out.append(rows[keep])
        values_out.append(values[keep])
        unsure.append(rows[np.isnan(values).any(axis=1)])
    width = len(domains)
    return (
        np.vstack([np.zeros((0, width), dtype=np.int64), *rows_out]),
        np.vstack([np.zeros((0, n_objectives)), *values_out]),
        np.vstack([np.zeros((0, width), dtype=np.int64), *unsure]),
        solved,
        solver.direct_solves - before,
        time.perf_counter() - began,
    )


def _worker_box_fronts(boxes: list[Box], domains, signs, n_objectives: int, walk: bool):
    if walk and not _WALKER:
        walker = BoxWalker.of(_SOLVER[0].q, max((len(d) for d in domains), default=1))
        assert walker is not None  # the parent walks the same quotient
        _WALKER.append(walker)
    return _box_fronts(_SOLVER[0], boxes, domains, signs, n_objectives, _WALKER[0] if walk else None)


def _probe_box(box: Box, limit: int) -> Box:
    """A part of ``box`` with at most ``limit`` policies: its leading decisions fixed at their
    lowest values until the rest fit."""
    lo, hi = box.lo.copy(), box.hi.copy()
    for d in range(len(lo)):
        if Box(lo, hi).size <= limit:
            break
        hi[d] = lo[d]
    return Box(lo, hi)


def _offsets(boxes: list[Box]):
    """(first row, box) of each box in the rows of all of them."""
    start = 0
    for box in boxes:
        yield start, box
        start += box.size


class PendingFronts:
    """Box fronts the workers are solving (:meth:`QuotientEvaluator.submit_box_fronts`)."""

    def __init__(self, evaluator: QuotientEvaluator, futures: list) -> None:
        self._evaluator = evaluator
        self._futures = futures
        self._value: BoxValues | None = None

    def done(self) -> bool:
        return self._value is not None or all(f.done() for f in self._futures)

    def result(self) -> BoxValues:
        if self._value is None:
            parts = [f.result() for f in self._futures]
            self._value = self._evaluator._merge(parts, self._evaluator.workers)
        return self._value


class QuotientEvaluator:
    """Evaluate policies on the family's quotient MDP; unsupported objectives go to Storm.

    With ``workers`` > 1, batches of :data:`START_WORKERS` policies or more are split over
    worker processes that receive the quotient once, when the pool starts; once it runs,
    batches from :data:`SHARE_SMALL` policies up too (a polishing round's 20), one chunk a
    worker. ``quotient`` reuses one built before; ``mdp``, a quotient MDP built with the
    family's objectives.
    """

    name = "quotient"

    def __init__(
        self,
        family: Family,
        workers: int | None = None,
        quotient: Quotient | None = None,
        mdp: QuotientMDP | None = None,
    ) -> None:
        self.family = family
        self.quotient = quotient if quotient is not None else build_quotient(family, mdp)
        self.solver = QuotientSolver(self.quotient)
        self.workers = default_workers(workers)
        self.fallback = tuple(o.name for o, q in zip(family.objectives, self.quotient.objectives) if q is None)
        self._storm: StormEvaluator | None = None
        self._pool: ProcessPool | None = None
        self.direct_solves = 0
        """Policies whose sweeps could not be certified and were solved directly."""
        self.uncertified = 0
        """Policies no solve of the quotient could certify, checked by Storm instead."""
        widest = max((len(d.service.values) for d in family.decisions), default=1)
        self._walker = BoxWalker.of(self.quotient, widest) if not self.fallback else None
        self._walk: bool | None = None
        """Whether :meth:`box_fronts` walks boxes (None: not decided yet)."""
        self._per_policy: float | None = None
        """Seconds a policy took a worker in the last large batch (for :meth:`_chunks`)."""

    def evaluate(self, policies: np.ndarray, progress: Progress | None = None) -> np.ndarray:
        return self.evaluate_consulted(policies, progress)[0]

    def _chunks(self, policies: int) -> int:
        """How many chunks a large batch of ``policies`` is split into (:data:`CHUNKS`): as many
        as keep each at least :data:`CHUNK_SECONDS` long by the last large batch's time a
        policy (the fewest before one was timed). Values do not depend on it."""
        fewest, most = (self.workers * c for c in CHUNKS)
        if self._per_policy is None:
            return fewest
        size = max(1, int(np.ceil(CHUNK_SECONDS / max(self._per_policy, 1e-9))))
        return int(np.clip(-(-policies // size), fewest, most))

    def evaluate_consulted(
        self, policies: np.ndarray, progress: Progress | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Values [n, objectives] and, per policy, the decisions its reachable states consult
        [n, decisions] bool: a policy that agrees with it there has the same DTMC (the search
        mutates what a policy consults, and knows a child equal there is no new policy)."""
        policies = np.asarray(policies, dtype=np.int64).reshape(-1, len(self.family.decisions))
        n_objectives = len(self.family.objectives)
        large = len(policies) >= START_WORKERS
        if self.workers > 1 and (large or (len(policies) >= SHARE_SMALL and self._pool is not None)):
            pool = self._executor()
            started = time.perf_counter()
            chunks = [
                c for c in np.array_split(policies, self._chunks(len(policies)) if large else self.workers) if len(c)
            ]
            futures = [pool.submit(_worker_solve, chunk, n_objectives) for chunk in chunks]
            parts, masks = [], []
            for future, chunk in zip(futures, chunks):
                part, mask, direct = future.result()
                parts.append(part)
                masks.append(mask)
                self.direct_solves += direct
                if progress:
                    progress(len(chunk))
            values, consulted = np.vstack(parts), np.vstack(masks)
            if large:
                self._per_policy = (time.perf_counter() - started) * self.workers / len(policies)
        else:
            before = self.solver.direct_solves
            values, consulted = _solve_rows(self.solver, policies, n_objectives, progress)
            self.direct_solves += self.solver.direct_solves - before
        missing = [i for i, q in enumerate(self.quotient.objectives) if q is None]
        if missing:
            values[:, missing] = self._storm_values(policies)[:, missing]
        # a value no solve could certify is NaN: Storm checks those policies instead
        supported = [i for i, q in enumerate(self.quotient.objectives) if q is not None]
        uncertain = (
            np.flatnonzero(np.isnan(values[:, supported]).any(axis=1)) if supported else np.zeros(0, dtype=np.int64)
        )
        if len(uncertain):
            self.uncertified += len(uncertain)
            values[uncertain] = self._storm_values(policies[uncertain])
        return values, consulted

    def box_fronts(self, boxes: list[Box], signs: np.ndarray) -> BoxValues:
        """The policies of ``boxes`` evaluated where they are solved, each box cut to its own
        non-dominated values in sign space ``signs`` (1 maximised, -1 minimised): what branch
        and bound needs of a box, without carrying every value of it between processes.
        Values the quotient cannot give (an objective it leaves to Storm, an uncertified
        solve) are Storm's, as in :meth:`evaluate`."""
        return self.submit_box_fronts(boxes, signs).result()

    def submit_box_fronts(self, boxes: list[Box], signs: np.ndarray) -> Ready | PendingFronts:
        """:meth:`box_fronts` without waiting: over workers, the boxes are solved while the
        caller goes on (branch and bound bounds its next nodes meanwhile); ``result()``
        waits for them."""
        began = time.perf_counter()
        domains = [np.array(d.service.values, dtype=np.int64) for d in self.family.decisions]
        n_objectives = len(self.family.objectives)
        if self.fallback:  # Storm's objectives: every policy's values are needed here
            rows = np.vstack([box_rows(b, domains) for b in boxes])
            values = self.evaluate(rows)
            keep = np.concatenate([o + local_front(values[o : o + b.size], signs) for o, b in _offsets(boxes)])
            return Ready(
                BoxValues(
                    rows=rows[keep], values=values[keep], evaluated=len(rows), seconds=time.perf_counter() - began
                )
            )
        walk = self._walks(boxes[0], domains) if boxes else False
        if self.workers > 1 and sum(b.size for b in boxes) >= 64:
            pool = self._executor()
            shares: list[list[Box]] = [[] for _ in range(self.workers * 2)]
            for i, box in enumerate(boxes):  # contiguous shares keep the boxes in order
                shares[i * len(shares) // len(boxes)].append(box)
            futures = [
                pool.submit(_worker_box_fronts, share, domains, signs, n_objectives, walk) for share in shares if share
            ]
            return PendingFronts(self, futures)
        part = _box_fronts(self.solver, boxes, domains, signs, n_objectives, self._walker if walk else None)
        return Ready(self._merge([part], 1))

    def _merge(self, parts: list[tuple], processes: int) -> BoxValues:
        """The workers' parts as one :class:`BoxValues`, with Storm's values for the rows the
        quotient could not certify."""
        self.direct_solves += sum(p[4] for p in parts)
        rows = np.vstack([p[0] for p in parts])
        values = np.vstack([p[1] for p in parts])
        unsure = np.vstack([p[2] for p in parts])
        if len(unsure):  # Storm values the policies the quotient could not certify
            self.uncertified += len(unsure)
            rows, values = np.vstack([rows, unsure]), np.vstack([values, self._storm_values(unsure)])
        seconds = sum(p[5] for p in parts) / max(1, min(processes, len(parts)))
        return BoxValues(rows=rows, values=values, evaluated=sum(p[3] for p in parts), seconds=seconds)

    def box_seeds(self, rows: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Seeds for branch and bound over :meth:`box_fronts` (policies and their values from
        :meth:`evaluate`), with their values as :meth:`box_fronts` gives them. The walk and
        the solve agree to rounding, but a front that mixed them could keep a policy that wins
        a tie by rounding alone (a last-bit better value beside a much worse one)."""
        domains = [np.array(d.service.values, dtype=np.int64) for d in self.family.decisions]
        rows = np.asarray(rows, dtype=np.int64).reshape(-1, len(domains))
        if not len(rows) or not self.walks_boxes():
            return rows, values
        assert self._walker is not None  # walks_boxes says so
        table = _domain_table(domains)
        index = np.column_stack([np.searchsorted(domain, rows[:, d]) for d, domain in enumerate(domains)])
        walked = np.vstack([self._walker.solve(Box(i, i), *table)[1] for i in index])
        return rows, walked

    def walks_boxes(self) -> bool:
        """Whether this evaluator walks boxes in blocks over their widest decision
        (:meth:`_walks`, decided on the whole family if no box was given before)."""
        domains = [np.array(d.service.values, dtype=np.int64) for d in self.family.decisions]
        whole = Box(np.zeros(len(domains), dtype=np.int64), np.array([len(d) - 1 for d in domains], dtype=np.int64))
        return self._walker is not None and self._walks(whole, domains)

    def _walks(self, box: Box, domains: list[np.ndarray]) -> bool:
        """Whether boxes are walked (:class:`BoxWalker`) rather than solved policy by policy:
        decided once, on the first box, by timing both on :data:`PROBE` of its policies.
        Both give every value to within rounding (1e-14 of its size), and the choice holds
        for the whole evaluator, so every box of a run is solved the same way."""
        if self._walk is None:
            self._walk = False
            if self._walker is not None:
                probe = _probe_box(box, PROBE)
                table = _domain_table(domains)
                self._walker.solve(Box(probe.lo, probe.lo), *table)  # compiled before it is timed
                began = time.perf_counter()
                rows, _ = self._walker.solve(probe, *table)
                walked = time.perf_counter() - began
                began = time.perf_counter()
                _solve_rows(self.solver, rows, len(self.family.objectives))
                self._walk = walked < time.perf_counter() - began
        return self._walk

    def _storm_values(self, policies: np.ndarray) -> np.ndarray:
        if self._storm is None:
            self._storm = StormEvaluator(self.family, workers=self.workers)
        return self._storm.evaluate(policies)

    def describe(self) -> dict[str, object]:
        """The quotient's size and the objectives Storm checks instead, for the run's summary."""
        return {
            "quotient_states": self.quotient.states,
            "quotient_choices": self.quotient.choices,
            "quotient_transitions": self.quotient.branches,
            "objectives_checked_by_storm": list(self.fallback),
            "direct_solves": self.direct_solves,
            "policies_checked_by_storm_uncertified": self.uncertified,
            "boxes_walked": bool(self._walk),
        }

    def _executor(self) -> ProcessPool:
        if self._pool is None:
            self._pool = spawn_pool(self.workers, initializer=_worker_start, initargs=(self.quotient,))
        return self._pool

    def close(self, abort: bool = False) -> None:
        """Release the workers (``abort``: end them at once, on an error or Ctrl-C)."""
        if self._pool is not None:
            stop_pool(self._pool, abort)
            self._pool = None
        if self._storm is not None:
            self._storm.close(abort)
            self._storm = None

    def __enter__(self) -> QuotientEvaluator:
        return self

    def __exit__(self, kind, *exc) -> None:
        self.close(abort=kind is not None)
