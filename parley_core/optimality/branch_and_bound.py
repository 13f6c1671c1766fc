"""Exact Pareto fronts by branch and bound over the decisions' ranges.

A node is a sub-family (per decision an interval of its domain). Its bound, on the
quotient's relaxation (:mod:`parley_core.quotient.bounds`), is the ideal point of its
schedulers and a few weighted sums (half-spaces): every policy of the node lies in that
region. The archive of evaluated values (:mod:`parley_core.optimality.archive`) is kept with its
*local upper bounds*: the corners u whose open orthants ``{v > u}`` make up exactly the
points no archived value weakly dominates. A node none of whose region reaches beyond a
corner holds no policy with a new value, and is pruned. Where the bounds know their
schedulers (expected rewards to a target), each is tried as a policy (per decision the value
it takes in most states) and the node is split in the decision they disagree on most, as
PAYNT's abstraction refinement does; otherwise in its widest decision. A node whose
decisions leave at most ``leaf`` policies (decisions no reached state consults collapse to
one value) is evaluated policy by policy; with ``adaptive``, ``leaf`` grows to what costs as
much to evaluate as a few bounds (both times measured as the search goes), because where
fronts are dense (web_ids, tas) splitting rarely prunes. Evaluated nodes go to the evaluator
as whole boxes where it can take them
(:meth:`~parley_core.evaluate.quotient.QuotientEvaluator.box_fronts`: each box enumerated
where it is solved and cut to its own front, so only a few rows a box travel between
processes), and are solved there while the next nodes are bounded here: a node is pruned
against the values found so far, which is sound whatever is still pending. Until the first
leaf is evaluated the nodes are taken depth first, so that the adaptive leaf size is known
before the family is cut finer than it needs. When no node is left, the archive's
non-dominated values are the whole Pareto front (as a set of values); with a time limit, or
on Ctrl-C, the open nodes' regions (for two objectives a staircase over each one's box and
half-spaces) join the front in the bound. A batch that Ctrl-C cut short (the workers take it
too) puts the nodes its boxes came from back among the open ones, with their parents' bounds.
"""

from __future__ import annotations

import heapq
import itertools
import math
import time
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np
from attrs import field, frozen

from parley_core.boxes import FLOOR, Box, BoxValues, Pending, Ready, box_rows, local_front
from parley_core.model import Family
from parley_core.optimality.archive import Archive, depth, region_points, robust_front
from parley_core.optimality.records import SearchCounts, Stopped
from parley_core.quotient.bounds import RelaxedObjectives
from parley_core.quotient.coloring import Quotient

LEAF = 48
"""Nodes with at most this many policies are evaluated rather than split."""
LARGEST_LEAF = 65536
"""With ``adaptive``, a node with up to this many policies is evaluated when that costs no
more than :data:`LEAF_COST` bounds of a node (the mean measured so far): on web_ids a
node's bound costs as much as solving about 150 policies, and splitting rarely prunes."""
LEAF_COST = 16.0
"""Splitting costs at least two bounds (the children's), so a node that costs less than that
to evaluate is evaluated."""
CUTS = 3
"""Weighted sums tried per node before it is split."""
BATCH = 4096
"""Policies handed to the evaluator at a time."""
BOX_BATCH = 65536
"""Policies of whole boxes handed to a box evaluator at a time."""
BATCH_SECONDS = 5.0
"""Once the evaluator's speed is measured, a batch holds at most what it solves in this long
(at least :data:`SMALLEST_BATCH` policies): with slow policies (PAYNT's dpm, then about 7 ms
each on two workers, now 1 ms) batches of 65,536 kept the search waiting 20 minutes past its
time limit for the batches in flight."""
SMALLEST_BATCH = 64
IN_FLIGHT = 2
"""Batches an evaluator may be solving while nodes are bounded: the workers always have the
next batch when they finish one."""


class Tried:
    """The policies (rows of domain indices) already tried as a bound's scheduler."""

    def __init__(self) -> None:
        self.seen: set[bytes] = set()

    def add(self, choice: np.ndarray) -> bool:
        key = np.asarray(choice, dtype=np.int64).tobytes()
        if key in self.seen:
            return False
        self.seen.add(key)
        return True


@frozen
class Node:
    lo: np.ndarray = field(eq=False)
    hi: np.ndarray = field(eq=False)
    ideal: np.ndarray | None = field(default=None, eq=False)
    cuts: tuple[tuple[np.ndarray, float], ...] = ()

    def size(self) -> int:
        return math.prod(int(high - low + 1) for low, high in zip(self.lo, self.hi))


@frozen(kw_only=True)
class ExactResult:
    """The non-dominated evaluated policies (rows of decision values) and values (the
    objectives' units), the bound's points, and how the search went."""

    policies: np.ndarray = field(eq=False)
    values: np.ndarray = field(eq=False)
    bound: np.ndarray = field(eq=False)
    exact: bool
    nodes: int
    pruned: int
    evaluated: int
    unknown: int
    open: int
    seconds: float
    stopped_by: Stopped

    def counts(self) -> SearchCounts:
        """What the search did, as the run directory records it."""
        return SearchCounts(
            nodes=self.nodes,
            pruned=self.pruned,
            evaluated=self.evaluated,
            open=self.open,
            unknown=self.unknown,
            stopped_by=self.stopped_by,
        )


def branch_and_bound(
    family: Family,
    quotient: Quotient,
    evaluate: Callable[[np.ndarray], np.ndarray],
    seeds: tuple[np.ndarray, np.ndarray] | None = None,
    **options: Any,
) -> ExactResult:
    """The family's Pareto front (see the module docstring): a :class:`BranchAndBound` with
    ``options`` (its keyword arguments), run from ``seeds``. ``evaluate`` maps rows of decision
    values to objective values; ``seeds`` (rows, values) start the archive; ``progress``
    receives the fraction of the family resolved so far (pruned or evaluated), or of the time
    limit used if that is more; ``root_cuts`` are half-spaces (weights, level; sign space) every
    policy is known to satisfy; ``bounds`` the family's relaxed objectives, if already built;
    ``adaptive`` raises ``leaf`` to what costs :data:`LEAF_COST` bounds to evaluate (measured
    as the search goes: which nodes are split then depends on timing, the front's values do
    not); ``fronts`` starts evaluating whole boxes given the sign space and returns a pending
    :class:`~parley_core.boxes.BoxValues` with only each box's own non-dominated rows
    (:meth:`~parley_core.evaluate.quotient.QuotientEvaluator.submit_box_fronts`), else
    ``evaluate`` gets every row. Up to :data:`IN_FLIGHT` batches are evaluated while nodes
    are bounded; a node is pruned against the values found so far, which is sound whatever
    is still pending (an archive with fewer values dominates less). With ``whole``, a node
    keeps its widest decision whole while another can be split, so that leaves hold one
    decision's whole range: what an evaluator that walks a box's policies in blocks over its
    widest decision needs to be fast (:class:`~parley_core.quotient.forward.BoxWalker`; on tas
    about 1.6 times faster a policy than the balanced leaves bisection leaves otherwise)."""
    return BranchAndBound(family, quotient, evaluate, **options).run(seeds)


class _Costs:
    """What bounding and evaluating cost so far, which sets the adaptive leaf size and the
    batch size."""

    def __init__(self) -> None:
        self.bound_seconds = 0.0
        self.bounds = 0
        self.policy_seconds = 0.0
        self.policies = 0

    def leaf_size(self, leaf: int, adaptive: bool) -> int:
        if not adaptive or not self.policies or not self.bounds:
            return leaf
        per_bound = self.bound_seconds / self.bounds
        per_policy = max(self.policy_seconds / self.policies, 1e-9)
        return max(leaf, min(LARGEST_LEAF, int(LEAF_COST * per_bound / per_policy)))

    def batch_limit(self, boxes: bool) -> int:
        most = BOX_BATCH if boxes else BATCH
        if not self.policies:
            return most
        per_policy = max(self.policy_seconds / self.policies, 1e-12)
        return int(min(most, max(SMALLEST_BATCH, BATCH_SECONDS / per_policy)))


class _Kept:
    """The archive of values found, with the policy of each value it holds."""

    def __init__(self, signs: np.ndarray) -> None:
        self.signs = signs
        self.archive = Archive(len(signs))
        self.rows: list[np.ndarray] = []
        self.values: list[np.ndarray] = []

    def admit(self, rows: np.ndarray, values: np.ndarray) -> None:
        # what the archive would reject anyway is dropped in bulk: what the batch itself or
        # the archive weakly dominates (the archive keeps the first of equal values)
        signs, archive = self.signs, self.archive
        keep = local_front(values, signs)
        rows, values = rows[keep], values[keep]
        if len(archive.points) and len(values):
            points = np.maximum(values * signs, FLOOR)
            covered = np.zeros(len(points), dtype=bool)
            for lo in range(0, len(points), 256):
                part = points[lo : lo + 256]
                covered[lo : lo + 256] = (archive.points[None, :, :] >= part[:, None, :]).all(axis=2).any(axis=1)
            rows, values = rows[~covered], values[~covered]
        for row, value in zip(rows, values):
            # kept before the archive takes it: a Ctrl-C in between leaves no archived value
            # without its policy (the archive's values decide what was pruned)
            self.rows.append(row)
            self.values.append(value)
            if not archive.add(value * signs):
                self.rows.pop()
                self.values.pop()

    def front(self, n_decisions: int) -> tuple[np.ndarray, np.ndarray]:
        """The policies whose values the archive still holds (it drops what a later value
        dominates), cut to their robust front."""
        signs = self.signs
        rows = np.array(self.rows, dtype=np.int64).reshape(-1, n_decisions)
        values = np.array(self.values, dtype=float).reshape(-1, len(signs))
        points = self.archive.points
        alive = np.array([(points == np.maximum(v * signs, FLOOR)).all(axis=1).any() for v in values], dtype=bool)
        rows, values = rows[alive.reshape(-1)], values[alive.reshape(-1)]
        kept = robust_front(values * signs)
        return rows[kept], values[kept]


class _Batches:
    """Boxes waiting to be evaluated (``pending``, each with the node it covers, or None for
    a tried policy) and batches being evaluated (``inflight``, oldest first); their values go
    into ``kept`` in the order submitted, so that of equal values the archive keeps the same
    policy whatever the timing."""

    def __init__(self, search: BranchAndBound) -> None:
        self.search = search
        self.pending: list[Box] = []
        self.covering: list[Node | None] = []
        self.pending_size = 0
        self.inflight: deque[tuple[Pending, list[Node | None]]] = deque()

    def take(self, batch: BoxValues) -> None:
        search = self.search
        values = np.asarray(batch.values, dtype=float).reshape(len(batch.rows), len(search.signs))
        search.costs.policy_seconds += batch.seconds
        search.costs.policies += batch.evaluated
        search.evaluated += batch.evaluated
        search.unknown += int(np.isnan(values).any(axis=1).sum())
        search.kept.admit(batch.rows, values)

    def settle(self) -> None:
        # the oldest batch leaves the queue once its values are in: one that Ctrl-C cut short
        # is still there for the interrupted search to open its nodes again
        self.take(self.inflight[0][0].result())
        self.inflight.popleft()

    def harvest(self, wait: bool) -> None:
        while self.inflight and (wait or self.inflight[0][0].done()):
            self.settle()

    def flush(self) -> None:
        if not self.pending:
            return
        search = self.search
        if search.fronts is not None:
            self.inflight.append((search.fronts(list(self.pending), search.signs), list(self.covering)))
        else:
            began = time.perf_counter()
            rows = np.vstack([box_rows(box, search.domains) for box in self.pending])
            values = np.asarray(search.evaluate(rows), dtype=float).reshape(len(rows), len(search.signs))
            batch = BoxValues(rows=rows, values=values, evaluated=len(rows), seconds=time.perf_counter() - began)
            self.inflight.append((Ready(batch), []))
        self.pending.clear()
        self.covering.clear()
        self.pending_size = 0
        # the first batch is waited for: its time is what the adaptive leaf size is measured by
        if not search.costs.policies:
            self.harvest(wait=True)
        while len(self.inflight) > IN_FLIGHT:
            self.settle()

    def queue(self, lo: np.ndarray, hi: np.ndarray, node: Node | None) -> None:
        box = Box(lo, hi)
        self.pending.append(box)
        self.covering.append(node)
        self.pending_size += box.size
        # the first box goes at once: its time is what the adaptive leaf size is measured by
        costs = self.search.costs
        if not costs.policies or self.pending_size >= costs.batch_limit(self.search.fronts is not None):
            self.flush()

    def reopen(self) -> list[Node]:
        """After Ctrl-C: the nodes whose boxes were pending or in a batch the workers did not
        finish (the others' values are taken), and the nodes any of them stood for."""
        lost = [n for n in self.covering if n is not None]
        queued: list[Node | None] = list(lost)
        for batch, nodes_of in self.inflight:
            queued.extend(nodes_of)
            try:
                self.take(batch.result())
            except BaseException:  # the workers took the Ctrl-C too: their boxes are open again
                lost.extend(n for n in nodes_of if n is not None)
        working = self.search.working
        if working is not None and all(n is not working for n in queued):
            lost.append(working)
        self.inflight.clear()
        self.pending.clear()
        self.covering.clear()
        return lost


class BranchAndBound:
    """One branch and bound over a family (see the module docstring and :func:`branch_and_bound`,
    which makes one and runs it): nodes are taken best first from ``stack`` and each is
    pruned, evaluated as a leaf, or bounded, its bounds' schedulers tried, and split."""

    def __init__(
        self,
        family: Family,
        quotient: Quotient,
        evaluate: Callable[[np.ndarray], np.ndarray],
        *,
        time_limit: float | None = None,
        progress: Callable[[float], None] | None = None,
        leaf: int = LEAF,
        adaptive: bool = True,
        root_cuts: tuple[tuple[np.ndarray, float], ...] = (),
        bounds: RelaxedObjectives | None = None,
        fronts: Callable[[list[Box], np.ndarray], Pending] | None = None,
        whole: bool = False,
        sums_vote: bool = True,
    ) -> None:
        self.start = time.perf_counter()
        self.bounds = bounds = bounds or RelaxedObjectives(family, quotient)
        self.evaluate, self.fronts = evaluate, fronts
        self.time_limit, self.progress = time_limit, progress
        self.leaf, self.adaptive, self.whole, self.sums_vote = leaf, adaptive, whole, sums_vote
        self.signs = bounds.signs
        self.domains = [np.array(d.service.values, dtype=np.int64) for d in family.decisions]
        self.kept = _Kept(self.signs)
        self.costs = _Costs()
        self.batches = _Batches(self)
        self.tried = Tried()
        self.total = math.prod(int(s) for s in bounds.sizes)
        self.resolved = 0.0
        root = Node(np.zeros(len(self.domains), dtype=np.int64), bounds.sizes - 1, cuts=tuple(root_cuts))
        self.stack: list[tuple[float, int, Node]] = [(0.0, 0, root)]
        self.scale = np.ones(len(self.signs))
        self.counter = itertools.count(1)
        self.nodes = self.pruned = self.evaluated = self.unknown = 0
        self.stopped_by = Stopped.COMPLETE
        self.working: Node | None = None
        """The node popped and not yet pruned, queued or split (reopened on Ctrl-C)."""

    def run(self, seeds: tuple[np.ndarray, np.ndarray] | None = None) -> ExactResult:
        if seeds is not None and len(seeds[0]):
            self.kept.admit(*seeds)
        batches = self.batches
        try:
            while self.stack:
                self.working = None
                if self.time_limit is not None and time.perf_counter() - self.start > self.time_limit:
                    self.stopped_by = Stopped.TIME
                    break
                batches.harvest(wait=False)
                if self._finished():
                    self.stopped_by = Stopped.FOUND
                    break
                if self.fronts is not None and not batches.inflight:  # the evaluator is idle: give it what is pending
                    batches.flush()
                _, _, node = heapq.heappop(self.stack)
                self.working = node
                self.nodes += 1
                self._visit(node)
            self.working = None
            batches.flush()
            batches.harvest(wait=True)
            if self.stopped_by is Stopped.COMPLETE and self._finished():
                self.stopped_by = Stopped.FOUND
        except KeyboardInterrupt:  # Ctrl-C: the front and the bound so far, as with a time limit
            self.stopped_by = Stopped.INTERRUPTED
            self.stack.extend((0.0, -next(self.counter), n) for n in batches.reopen())
        return self._result()

    def _visit(self, node: Node) -> None:
        share = node.size()
        if node.ideal is not None and not len(self._open(node.ideal, node.cuts)):
            self._closed(node, node.ideal, node.cuts)
            self._resolve(share, pruned=True)
            return
        bounds = self.bounds
        view = bounds.restrict(node.lo, node.hi)
        consulted = bounds.consulted(view)
        lo, hi = node.lo.copy(), node.hi.copy()
        hi[~consulted] = lo[~consulted]  # decisions no reached state consults collapse to one value
        width = hi - lo + 1
        if math.prod(int(w) for w in width) <= self.costs.leaf_size(self.leaf, self.adaptive):
            self.batches.queue(lo, hi, node)
            self._closed(node, None, (), evaluated=hi)
            self._resolve(share)
            return
        ideal, cuts, corners = self._bound(node, view)
        if not len(corners):
            self._closed(node, ideal, cuts)
            self._resolve(share, pruned=True)
            return
        votes = self._try_schedulers(view, lo, cuts[len(node.cuts) :])
        d, middle = self._split_point(votes, np.where(consulted, width, 0), lo, hi)
        lo, hi = self._spans(node, lo, hi)
        upper_lo, lower_hi = lo.copy(), hi.copy()
        upper_lo[d], lower_hi[d] = middle + 1, middle
        self._resolve(share - math.prod(int(b - a + 1) for a, b in zip(lo, hi)))  # what collapsed decisions repeat
        # until a first leaf is evaluated, depth first: its time sets the adaptive leaf size
        # (nodes bounded best first before that would be split far finer than they need,
        # while the workers wait); of equal priorities the latest first
        priority = -depth(ideal, corners, self.scale) if self.costs.policies else -math.inf
        heapq.heappush(self.stack, (priority, -next(self.counter), Node(upper_lo, hi, ideal, cuts)))
        heapq.heappush(self.stack, (priority, -next(self.counter), Node(lo, lower_hi, ideal, cuts)))

    def _bound(self, node: Node, view) -> tuple[np.ndarray, tuple[tuple[np.ndarray, float], ...], np.ndarray]:
        """The node's ideal point, its half-spaces (its parent's and up to :data:`CUTS` new
        weighted sums, each aimed at the open corner farthest inside the ideal box) and the
        archive's corners still open within them."""
        began = time.perf_counter()
        bounds, archive = self.bounds, self.kept.archive
        ideal = np.maximum(bounds.ideal(view), FLOOR)
        if node.ideal is not None:
            ideal = np.minimum(ideal, node.ideal)
        else:  # the root: scale distances by the family's extent
            spread = ideal - archive.points.min(axis=0) if len(archive.points) else np.ones(len(self.signs))
            self.scale = np.where(np.isfinite(spread) & (spread > 0), spread, 1.0)
        cuts = list(node.cuts)
        corners = self._open(ideal, cuts)
        for attempt in range(CUTS if bounds.combines else 0):
            weights = self._aim(ideal, corners, attempt) if len(corners) else None
            if weights is None:
                break
            cuts.append((weights, float(bounds.weighted(view, weights)[0])))
            corners = self._open(ideal, cuts)
        self.costs.bound_seconds += time.perf_counter() - began
        self.costs.bounds += 1
        return ideal, tuple(cuts), corners

    def _open(self, ideal: np.ndarray, cuts) -> np.ndarray:
        """The points a region (ideal box and half-spaces) must still be searched for: the
        archive's corners it reaches beyond (none: the node is pruned)."""
        return self.kept.archive.open_corners(ideal, list(cuts))

    def _aim(self, ideal: np.ndarray, corners: np.ndarray, attempt: int) -> np.ndarray | None:
        """The weights of the next weighted sum to bound a node by: aimed at the open corner
        farthest inside the ideal box (None: no corner has a finite distance)."""
        gaps = ideal[None, :] - corners
        if not np.isfinite(gaps).all(axis=1).any():
            return None
        corner = corners[np.argmax(np.where(np.isfinite(gaps), gaps, -np.inf).min(axis=1))]
        weights = 1.0 / np.maximum(ideal - corner, 1e-12)
        return weights / weights.max()

    def _spans(self, node: Node, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What a split node's children share between them: its decisions with those no state
        consults collapsed to one value (``lo..hi``), which the search need not repeat."""
        return lo, hi

    def _finished(self) -> bool:
        """Whether the search may stop before every node is closed (never, for a front)."""
        return False

    def _closed(self, node: Node, ideal, cuts, evaluated: np.ndarray | None = None) -> None:
        """A node is closed: pruned by its bound (``ideal`` and ``cuts``), or queued to be
        evaluated with its decisions up to ``evaluated`` (those no state consults collapsed);
        what a search that proves something of each node records."""

    def _try_schedulers(self, view, lo: np.ndarray, fresh) -> list[np.ndarray]:
        """Where the bounds know their schedulers, each is tried as a policy (by the value each
        decision takes in most states: where they agree, it is the policy that attains the
        bound); their votes per decision and value. Where they do not (step-bounded weighted
        sums) and ``sums_vote``, the best scheduler of the node's first new weighted sum
        (``fresh``) votes by its expected steps in each value's states."""
        votes = [self.bounds.votes(view, actions) for actions in view.schedulers]
        if self.sums_vote and not votes and fresh:
            began = time.perf_counter()
            found = self.bounds.horizon_votes(view, fresh[0][0])
            self.costs.bound_seconds += time.perf_counter() - began
            if found is not None:
                votes.append(found)
        for vote in votes:
            choice = np.where(vote.sum(axis=1) > 0, vote.argmax(axis=1), lo)
            if self.tried.add(choice):
                self.batches.queue(choice, choice.copy(), None)
        return votes

    def _split_point(self, votes: list[np.ndarray], spans: np.ndarray, lo: np.ndarray, hi: np.ndarray):
        """The decision to split and the last value of its lower half: where the schedulers
        disagree most, between the two values taken most (PAYNT's abstraction refinement); else
        the widest consulted decision (with ``whole``, the widest but one), halved."""
        if votes:
            tally = np.sum(votes, axis=0)
            disagreement = np.where(spans > 1, tally.sum(axis=1) - tally.max(axis=1), 0)
            if disagreement.max() > 0:
                d = int(np.argmax(disagreement))
                first, second = np.argsort(-tally[d], kind="stable")[:2]
                return d, int(min(max(min(first, second), lo[d]), hi[d] - 1))
        d = int(np.argmax(spans))
        if self.whole:
            spans = spans.copy()
            spans[d] = 0
            if spans.max() > 1:
                d = int(np.argmax(spans))
        return d, (lo[d] + hi[d]) // 2

    def _resolve(self, share: float, pruned: bool = False) -> None:
        self.pruned += int(pruned)
        self.resolved += share
        if self.progress is not None:
            elapsed = (time.perf_counter() - self.start) / self.time_limit if self.time_limit else 0.0
            self.progress(max(self.resolved / self.total, min(1.0, elapsed)))

    def _result(self) -> ExactResult:
        rows, values = self.kept.front(len(self.domains))
        signs, stack = self.signs, self.stack
        open_points = [region_points(n.ideal, n.cuts) * signs for _, _, n in stack if n.ideal is not None]
        if any(n.ideal is None for _, _, n in stack):
            everything = self.bounds.restrict(np.zeros(len(self.domains), dtype=np.int64), self.bounds.sizes - 1)
            open_points.append(self.bounds.ideal(everything) * signs)
        return ExactResult(
            policies=rows,
            values=values,
            bound=np.vstack([values, *open_points]) if open_points else values,
            exact=not stack and self.unknown == 0,
            nodes=self.nodes,
            pruned=self.pruned,
            evaluated=self.evaluated,
            unknown=self.unknown,
            open=len(stack),
            seconds=time.perf_counter() - self.start,
            stopped_by=self.stopped_by,
        )
