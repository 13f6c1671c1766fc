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

import numpy as np
from attrs import field, frozen

from parley_core.boxes import FLOOR, Box, BoxValues, Pending, Ready, box_rows, local_front
from parley_core.model import Family
from parley_core.optimality.archive import Archive, depth, region_points, robust_front
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
    stopped_by: str


def branch_and_bound(
    family: Family,
    quotient: Quotient,
    evaluate: Callable[[np.ndarray], np.ndarray],
    seeds: tuple[np.ndarray, np.ndarray] | None = None,
    time_limit: float | None = None,
    progress: Callable[[float], None] | None = None,
    leaf: int = LEAF,
    adaptive: bool = True,
    root_cuts: tuple[tuple[np.ndarray, float], ...] = (),
    bounds: RelaxedObjectives | None = None,
    fronts: Callable[[list[Box], np.ndarray], Pending] | None = None,
    whole: bool = False,
) -> ExactResult:
    """The family's Pareto front (see the module docstring). ``evaluate`` maps rows of decision
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
    start = time.perf_counter()
    bounds = bounds or RelaxedObjectives(family, quotient)
    signs = bounds.signs
    domains = [np.array(d.service.values, dtype=np.int64) for d in family.decisions]
    archive = Archive(len(signs))
    kept_rows: list[np.ndarray] = []
    kept_values: list[np.ndarray] = []

    def admit(rows: np.ndarray, values: np.ndarray) -> None:
        # what the archive would reject anyway is dropped in bulk: what the batch itself or
        # the archive weakly dominates (the archive keeps the first of equal values)
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
            kept_rows.append(row)
            kept_values.append(value)
            if not archive.add(value * signs):
                kept_rows.pop()
                kept_values.pop()

    if seeds is not None and len(seeds[0]):
        admit(*seeds)
    total = math.prod(int(s) for s in bounds.sizes)
    resolved = 0.0
    root = Node(np.zeros(len(domains), dtype=np.int64), bounds.sizes - 1, cuts=tuple(root_cuts))
    stack: list[tuple[float, int, Node]] = [(0.0, 0, root)]
    scale = np.ones(len(signs))
    counter = itertools.count(1)
    pending: list[Box] = []
    # per pending box the node it covers (None: a tried policy, also inside a node of its own),
    # so that a batch lost to Ctrl-C goes back on the stack with that node's bound
    covering: list[Node | None] = []
    nodes = pruned = evaluated = unknown = 0
    stopped_by = "complete"

    spent = {"bound": 0.0, "bounds": 0, "policy": 0.0, "policies": 0, "pending": 0}

    def leaf_size() -> int:
        if not adaptive or not spent["policies"] or not spent["bounds"]:
            return leaf
        per_bound = spent["bound"] / spent["bounds"]
        per_policy = max(spent["policy"] / spent["policies"], 1e-9)
        return max(leaf, min(LARGEST_LEAF, int(LEAF_COST * per_bound / per_policy)))

    inflight: deque[tuple[Pending, list[Node | None]]] = deque()

    def batch_limit() -> int:
        most = BATCH if fronts is None else BOX_BATCH
        if not spent["policies"]:
            return most
        per_policy = max(spent["policy"] / spent["policies"], 1e-12)
        return int(min(most, max(SMALLEST_BATCH, BATCH_SECONDS / per_policy)))

    tried = Tried()

    def take(batch: BoxValues) -> None:
        nonlocal evaluated, unknown
        values = np.asarray(batch.values, dtype=float).reshape(len(batch.rows), len(signs))
        spent["policy"] += batch.seconds
        spent["policies"] += batch.evaluated
        evaluated += batch.evaluated
        unknown += int(np.isnan(values).any(axis=1).sum())
        admit(batch.rows, values)

    def settle() -> None:
        # the oldest batch leaves the queue once its values are in: one that Ctrl-C cut short
        # is still there for the interrupted search to open its nodes again
        take(inflight[0][0].result())
        inflight.popleft()

    def harvest(wait: bool) -> None:
        # in the order submitted, so that of equal values the archive keeps the same policy
        while inflight and (wait or inflight[0][0].done()):
            settle()

    def flush() -> None:
        if not pending:
            return
        if fronts is not None:
            inflight.append((fronts(list(pending), signs), list(covering)))
        else:
            began = time.perf_counter()
            rows = np.vstack([box_rows(box, domains) for box in pending])
            values = np.asarray(evaluate(rows), dtype=float).reshape(len(rows), len(signs))
            seconds = time.perf_counter() - began
            inflight.append((Ready(BoxValues(rows=rows, values=values, evaluated=len(rows), seconds=seconds)), []))
        pending.clear()
        covering.clear()
        spent["pending"] = 0
        # the first batch is waited for: its time is what the adaptive leaf size is measured by
        if not spent["policies"]:
            harvest(wait=True)
        while len(inflight) > IN_FLIGHT:
            settle()

    def queue(lo: np.ndarray, hi: np.ndarray, node: Node | None) -> None:
        box = Box(lo, hi)
        pending.append(box)
        covering.append(node)
        spent["pending"] += box.size
        # the first box goes at once: its time is what the adaptive leaf size is measured by
        if not spent["policies"] or spent["pending"] >= batch_limit():
            flush()

    def resolve(share: int) -> None:
        nonlocal resolved
        resolved += share
        if progress is not None:
            elapsed = (time.perf_counter() - start) / time_limit if time_limit else 0.0
            progress(max(resolved / total, min(1.0, elapsed)))

    working: Node | None = None  # popped, and not yet pruned, queued or split
    try:
        while stack:
            working = None
            if time_limit is not None and time.perf_counter() - start > time_limit:
                stopped_by = "time"
                break
            harvest(wait=False)
            if fronts is not None and not inflight:  # the evaluator is idle: it gets what is pending
                flush()
            _, _, node = heapq.heappop(stack)
            working = node
            nodes += 1
            share = node.size()
            if node.ideal is not None and not len(archive.open_corners(node.ideal, list(node.cuts))):
                pruned += 1
                resolve(share)
                continue
            view = bounds.restrict(node.lo, node.hi)
            consulted = bounds.consulted(view)
            lo, hi = node.lo.copy(), node.hi.copy()
            hi[~consulted] = lo[~consulted]
            width = hi - lo + 1
            if math.prod(int(w) for w in width) <= leaf_size():
                queue(lo, hi, node)
                resolve(share)
                continue
            began = time.perf_counter()
            ideal = np.maximum(bounds.ideal(view), FLOOR)
            if node.ideal is not None:
                ideal = np.minimum(ideal, node.ideal)
            else:  # the root: scale distances by the family's extent
                spread = ideal - archive.points.min(axis=0) if len(archive.points) else np.ones(len(signs))
                scale = np.where(np.isfinite(spread) & (spread > 0), spread, 1.0)
            cuts = list(node.cuts)
            corners = archive.open_corners(ideal, cuts)
            for _ in range(CUTS if bounds.combines else 0):
                if not len(corners):
                    break
                gaps = ideal[None, :] - corners
                if not np.isfinite(gaps).all(axis=1).any():
                    break
                corner = corners[np.argmax(np.where(np.isfinite(gaps), gaps, -np.inf).min(axis=1))]
                weights = 1.0 / np.maximum(ideal - corner, 1e-12)
                weights /= weights.max()
                cuts.append((weights, float(bounds.weighted(view, weights)[0])))
                corners = archive.open_corners(ideal, cuts)
            spent["bound"] += time.perf_counter() - began
            spent["bounds"] += 1
            if not len(corners):
                pruned += 1
                resolve(share)
                continue
            # where the bounds' schedulers are known, each is tried as a policy (by the value each
            # decision takes in most states: where they agree, it is the policy that attains the
            # bound) and the node is split in the decision they disagree on most, between the two
            # values taken most, as PAYNT's abstraction refinement does; else in the widest
            # consulted decision (with ``whole``, the widest but one)
            votes = [bounds.votes(view, actions) for actions in view.schedulers]
            for vote in votes:
                choice = np.where(vote.sum(axis=1) > 0, vote.argmax(axis=1), lo)
                if tried.add(choice):
                    queue(choice, choice.copy(), None)
            spans = np.where(consulted, width, 0)
            split = None
            if votes:
                tally = np.sum(votes, axis=0)
                disagreement = np.where(spans > 1, tally.sum(axis=1) - tally.max(axis=1), 0)
                if disagreement.max() > 0:
                    split = d = int(np.argmax(disagreement))
                    first, second = np.argsort(-tally[d], kind="stable")[:2]
                    middle = int(min(max(min(first, second), lo[d]), hi[d] - 1))
            if split is None:
                d = int(np.argmax(spans))
                if whole:
                    spans[d] = 0
                    if spans.max() > 1:
                        d = int(np.argmax(spans))
                middle = (lo[d] + hi[d]) // 2
            upper_lo, lower_hi = lo.copy(), hi.copy()
            upper_lo[d], lower_hi[d] = middle + 1, middle
            resolve(share - math.prod(int(w) for w in width))  # what collapsed decisions repeat
            # until a first leaf is evaluated, depth first: its time sets the adaptive leaf size
            # (nodes bounded best first before that would be split far finer than they need,
            # while the workers wait); of equal priorities the latest first
            priority = -depth(ideal, corners, scale) if spent["policies"] else -math.inf
            heapq.heappush(stack, (priority, -next(counter), Node(upper_lo, hi, ideal, tuple(cuts))))
            heapq.heappush(stack, (priority, -next(counter), Node(lo, lower_hi, ideal, tuple(cuts))))
        working = None
        flush()
        harvest(wait=True)
    except KeyboardInterrupt:  # Ctrl-C: the front and the bound so far, as with a time limit
        stopped_by = "interrupted"
        lost = [n for n in covering if n is not None]
        queued: list[Node | None] = list(lost)  # the nodes a pending or submitted box stands for
        for batch, nodes_of in inflight:
            queued.extend(nodes_of)
            try:
                take(batch.result())
            except BaseException:  # the workers took the Ctrl-C too: their boxes are open again
                lost.extend(n for n in nodes_of if n is not None)
        if working is not None and all(n is not working for n in queued):
            lost.append(working)
        inflight.clear()
        pending.clear()
        covering.clear()
        stack.extend((0.0, -next(counter), n) for n in lost)
    rows = np.array(kept_rows, dtype=np.int64).reshape(-1, len(domains))
    values = np.array(kept_values, dtype=float).reshape(-1, len(signs))
    # the archive drops what a later value dominates: keep the policies whose value it still holds
    alive = np.array([(archive.points == np.maximum(v * signs, FLOOR)).all(axis=1).any() for v in values], dtype=bool)
    rows, values = rows[alive.reshape(-1)], values[alive.reshape(-1)]
    kept = robust_front(values * signs)
    rows, values = rows[kept], values[kept]
    open_points = [region_points(n.ideal, n.cuts) * signs for _, _, n in stack if n.ideal is not None]
    if any(n.ideal is None for _, _, n in stack):
        everything = bounds.restrict(np.zeros(len(domains), dtype=np.int64), bounds.sizes - 1)
        open_points.append(bounds.ideal(everything) * signs)
    bound = np.vstack([values, *open_points]) if open_points else values
    return ExactResult(
        policies=rows,
        values=values,
        bound=bound,
        exact=not stack and unknown == 0,
        nodes=nodes,
        pruned=pruned,
        evaluated=evaluated,
        unknown=unknown,
        open=len(stack),
        seconds=time.perf_counter() - start,
        stopped_by=stopped_by,
    )
