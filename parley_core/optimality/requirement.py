"""Requirements answered: a policy of the family inside a box of objective values, or a
certificate that none is.

A requirement is a conjunction of constraints, at most one per objective, each asking for a
value at least as good as a level (``success>=0.8`` for a maximised objective, ``cost<=60``
for a minimised one). In sign space (every objective maximised) that is the box
``{v >= r}``: upward closed. A sub-family's region, its ideal box cut by half-spaces with
non-negative weights (:mod:`parley_core.optimality.branch_and_bound`), is downward closed, so
it meets the box exactly when it holds the corner ``r``. Branch and bound driven by the box
(:class:`RequirementSearch`) therefore prunes a node whose region misses ``r``, aims its
weighted sums at ``r``, and stops at the first policy whose value meets ``r``. The values
the search found cannot prune anything here: a value that weakly dominates a point of the
box is in it.

When no node is left open and no value met the box, the nodes it closed are the
certificate (:class:`Closed`): together they cover the family, and each was either bounded
away from ``r`` (its ideal point or one of its half-spaces misses it) or evaluated, its own
front below ``r``. :func:`recheck` checks a certificate again from the family alone.

Ties: a value within the verification tolerance (:data:`~parley_core.optimality.archive.TOLERANCE`
of its size, at least 1) of a level meets it. ``r`` is lowered by that much before anything
is compared, so *feasible* means a policy meets the requirement to the tolerance and
*infeasible* means no policy comes within it.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from attrs import field, frozen

from parley_core.boxes import FLOOR, Box, box_rows
from parley_core.constraints import Constraint, Operator
from parley_core.errors import OptionError, ParleyDefect
from parley_core.model import Direction, Family
from parley_core.optimality.archive import TOLERANCE
from parley_core.optimality.branch_and_bound import BranchAndBound, ExactResult, Node
from parley_core.optimality.records import SearchCounts, Stopped
from parley_core.quotient.bounds import RelaxedObjectives
from parley_core.quotient.coloring import Quotient

TILT = 3.0
"""After the weighted sum aimed straight at the box's corner, each further one weighs one
constrained objective this much more (the region's boundary near the corner may slope either
way)."""


class Verdict(enum.Enum):
    """What a check found."""

    FEASIBLE = "feasible"
    """A policy inside the box (its values Storm's, once the pipeline verified it)."""
    INFEASIBLE = "infeasible"
    """No policy of the family is inside the box: every sub-family was closed without one."""
    UNKNOWN = "unknown"
    """Neither, within the time limit: some sub-families are still open."""


@frozen(kw_only=True)
class Requirement:
    """Constraints on a family's objectives, as the box's corner in sign space (lowered by
    the tolerance; :data:`~parley_core.boxes.FLOOR` for an objective left free)."""

    constraints: tuple[Constraint, ...] = field(converter=tuple[Constraint, ...])
    corner: np.ndarray = field(eq=False, repr=False)

    @classmethod
    def of(cls, family: Family, constraints: Sequence[Constraint]) -> Requirement:
        """The requirement on ``family``; a constraint on an unknown objective, a second one on
        the same objective, or one that asks for a worse value than a level is an error."""
        names = [o.name for o in family.objectives]
        if not constraints:
            raise OptionError("give at least one requirement, e.g. --require success>=0.8")
        corner = np.full(len(names), FLOOR)
        for constraint in constraints:
            i = constraint.column(names)
            objective = family.objectives[i]
            wanted = Operator.AT_LEAST if objective.direction is Direction.MAX else Operator.AT_MOST
            if constraint.operator is not wanted:
                way = "maximised" if objective.direction is Direction.MAX else "minimised"
                raise OptionError(
                    f"requirement {constraint}: {objective.name} is {way}, so a "
                    f"requirement on it asks for {objective.name}{wanted.value}LEVEL; a bound the other way "
                    "cannot be proven unreachable by the family's bounds"
                )
            if corner[i] > FLOOR:
                raise OptionError(f"two requirements on {objective.name}; give one level per objective")
            if not math.isfinite(constraint.bound):
                raise OptionError(f"requirement {constraint}: give a finite level")
            level = float(constraint.bound) if objective.direction is Direction.MAX else -float(constraint.bound)
            corner[i] = level - TOLERANCE * max(1.0, abs(level))
        return cls(constraints=tuple(constraints), corner=corner)

    def relaxed(self) -> tuple[Constraint, ...]:
        """The constraints with their levels moved by the tolerance, as the corner is: what a
        value that meets the requirement to the tolerance meets exactly."""
        out = []
        for constraint in self.constraints:
            level = float(constraint.bound)
            slack = TOLERANCE * max(1.0, abs(level))
            moved = level - slack if constraint.operator is Operator.AT_LEAST else level + slack
            out.append(Constraint(objective=constraint.objective, operator=constraint.operator, bound=moved))
        return tuple(out)

    @property
    def constrained(self) -> np.ndarray:
        return self.corner > FLOOR

    def met(self, values: np.ndarray, signs: np.ndarray) -> np.ndarray:
        """Which rows of ``values`` (objectives' units) meet the requirement, to the tolerance."""
        rows = np.maximum(np.asarray(values, dtype=float).reshape(-1, len(signs)) * signs, FLOOR)
        with np.errstate(invalid="ignore"):
            return (rows >= self.corner).all(axis=1) & ~np.isnan(rows).any(axis=1)

    def reaches(self, ideal: np.ndarray, cuts) -> bool:
        """Whether a region (ideal point and half-spaces, sign space) holds the corner."""
        corner = self.corner
        if not (ideal >= corner).all():
            return False
        with np.errstate(over="ignore", invalid="ignore"):
            return not any(float(np.asarray(w) @ corner) > level for w, level in cuts)

    def __str__(self) -> str:
        return " and ".join(map(str, self.constraints))


@frozen(kw_only=True)
class Closed:
    """A sub-family (positions ``lo..hi`` in each decision's domain) that a check closed:
    bounded away from the box (``ideal`` and ``cuts`` in sign space, the bound it was pruned
    by) or ``evaluated`` (its policies with the decisions no state consults collapsed, up to
    those positions) and found outside it."""

    lo: np.ndarray = field(eq=False)
    hi: np.ndarray = field(eq=False)
    ideal: np.ndarray | None = field(default=None, eq=False)
    cuts: tuple[tuple[np.ndarray, float], ...] = field(default=(), eq=False)
    evaluated: np.ndarray | None = field(default=None, eq=False)

    @property
    def size(self) -> int:
        return math.prod(int(h - lo + 1) for lo, h in zip(self.lo, self.hi))


@frozen(kw_only=True)
class Answer:
    """What branch and bound driven by a requirement found: its verdict, the policies it
    evaluated that meet the box (rows of decision values, the evaluator's values), the
    certificate (every sub-family closed; a proof only with ``INFEASIBLE``), the share of the
    family left open, and per objective the best value an open sub-family's bound allows
    (objectives' units; NaN where none is open)."""

    verdict: Verdict
    requirement: Requirement
    policies: np.ndarray = field(eq=False)
    values: np.ndarray = field(eq=False)
    closed: tuple[Closed, ...] = field(eq=False, repr=False)
    open_share: float
    open_best: np.ndarray = field(eq=False)
    counts: SearchCounts
    seconds: float
    result: ExactResult = field(eq=False, repr=False)
    """Branch and bound's own result (its front of what it evaluated)."""


class RequirementSearch(BranchAndBound):
    """Branch and bound that answers a requirement (the module docstring): a node is open
    while its region holds the box's corner, weighted sums aim at the corner, and the search
    stops at the first value inside the box. Every closed node is recorded in ``closed``."""

    def __init__(
        self,
        family: Family,
        quotient: Quotient,
        evaluate: Callable[[np.ndarray], np.ndarray],
        requirement: Requirement,
        **options: Any,
    ) -> None:
        super().__init__(family, quotient, evaluate, **options)
        self.requirement = requirement
        self.closed: list[Closed] = []

    def _open(self, ideal: np.ndarray, cuts) -> np.ndarray:
        corner = self.requirement.corner
        return corner[None, :] if self.requirement.reaches(ideal, cuts) else np.zeros((0, len(corner)))

    def _aim(self, ideal: np.ndarray, corners: np.ndarray, attempt: int) -> np.ndarray | None:
        constrained = self.requirement.constrained
        if constrained.sum() < 2:  # the ideal point alone decides one level
            return None
        gap = np.maximum(ideal - self.requirement.corner, 1e-12)
        weights = np.where(constrained, 1.0 / np.where(constrained, gap, 1.0), 0.0)
        if attempt:
            tilted = np.flatnonzero(constrained)[(attempt - 1) % int(constrained.sum())]
            weights[tilted] *= TILT
        return weights / weights.max()

    def _spans(self, node: Node, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # the children keep every value of the decisions no state consults: the closed nodes
        # then cover the family exactly, as a certificate must (the bounds are the same)
        return node.lo.copy(), node.hi.copy()

    def _finished(self) -> bool:
        points = self.kept.archive.points
        return bool(len(points)) and bool((points >= self.requirement.corner).all(axis=1).any())

    def _closed(self, node: Node, ideal, cuts, evaluated: np.ndarray | None = None) -> None:
        self.closed.append(
            Closed(
                lo=node.lo,
                hi=node.hi,
                ideal=None if ideal is None else np.asarray(ideal, dtype=float),
                cuts=tuple(cuts),
                evaluated=evaluated,
            )
        )

    def answer(self, seeds: tuple[np.ndarray, np.ndarray] | None = None) -> Answer:
        result = self.run(seeds)
        signs, requirement = self.signs, self.requirement
        inside = requirement.met(result.values, signs)
        if result.stopped_by is Stopped.FOUND and inside.any():
            verdict = Verdict.FEASIBLE
        elif result.stopped_by is Stopped.COMPLETE and not self.stack and self.unknown == 0:
            verdict = Verdict.INFEASIBLE
        else:
            verdict = Verdict.UNKNOWN
        open_ideals = [n.ideal for _, _, n in self.stack if n.ideal is not None]
        best = np.full(len(signs), np.nan)
        if any(n.ideal is None for _, _, n in self.stack):
            everything = self.bounds.restrict(np.zeros(len(self.domains), dtype=np.int64), self.bounds.sizes - 1)
            open_ideals.append(self.bounds.ideal(everything))
        if open_ideals:
            best = np.max(np.vstack(open_ideals), axis=0) * signs
        return Answer(
            verdict=verdict,
            requirement=requirement,
            policies=result.policies[inside],
            values=result.values[inside],
            closed=tuple(self.closed),
            open_share=0.0 if verdict is Verdict.INFEASIBLE else max(0.0, 1.0 - self.resolved / self.total),
            open_best=best,
            counts=result.counts(),
            seconds=result.seconds,
            result=result,
        )


def answer(
    family: Family,
    quotient: Quotient,
    evaluate: Callable[[np.ndarray], np.ndarray],
    requirement: Requirement,
    seeds: tuple[np.ndarray, np.ndarray] | None = None,
    **options: Any,
) -> Answer:
    """The requirement's answer on the family: a :class:`RequirementSearch` with ``options``
    (:func:`~parley_core.optimality.branch_and_bound.branch_and_bound`'s), run from ``seeds``."""
    return RequirementSearch(family, quotient, evaluate, requirement, **options).answer(seeds)


class CertificateError(ParleyDefect):
    """A certificate that does not prove what it claims (raised by :func:`recheck`)."""


def _covers(family: Family, closed: Sequence[Closed]) -> None:
    total = math.prod(len(d.service.values) for d in family.decisions)
    if sum(c.size for c in closed) != total:
        raise CertificateError(f"the sub-families hold {sum(c.size for c in closed)} policies, the family {total}")
    lo = np.array([c.lo for c in closed], dtype=np.int64).reshape(len(closed), -1)
    hi = np.array([c.hi for c in closed], dtype=np.int64).reshape(len(closed), -1)
    for i in range(len(closed)):  # equal sizes and pairwise disjoint: an exact cover
        overlap = ((lo[i + 1 :] <= hi[i]) & (hi[i + 1 :] >= lo[i])).all(axis=1)
        if overlap.any():
            raise CertificateError(f"sub-families {i} and {i + 1 + int(np.argmax(overlap))} overlap")


def recheck(
    family: Family,
    quotient: Quotient,
    requirement: Requirement,
    closed: Sequence[Closed],
    evaluate: Callable[[np.ndarray], np.ndarray],
    bounds: RelaxedObjectives | None = None,
) -> None:
    """Check an infeasibility certificate again from the family alone: the sub-families cover
    it exactly, each bounded one's own bound (its ideal point and a weighted sum per recorded
    weights, computed again) misses the box's corner, and no policy of an evaluated one (the
    decisions its states do not consult collapsed, as found again) meets the requirement.
    Raises :class:`CertificateError` naming the first that fails."""
    bounds = bounds or RelaxedObjectives(family, quotient)
    domains = [np.array(d.service.values, dtype=np.int64) for d in family.decisions]
    _covers(family, closed)
    for i, part in enumerate(closed):
        view = bounds.restrict(np.asarray(part.lo, dtype=np.int64), np.asarray(part.hi, dtype=np.int64))
        if part.evaluated is None:
            ideal = np.maximum(bounds.ideal(view), FLOOR)
            cuts = [(np.asarray(w, dtype=float), float(bounds.weighted(view, np.asarray(w))[0])) for w, _ in part.cuts]
            if requirement.reaches(ideal, cuts):
                raise CertificateError(f"sub-family {i}: its bound reaches the box {requirement}")
            continue
        consulted = bounds.consulted(view)
        hi = np.where(consulted, part.hi, part.lo)
        rows = box_rows(Box(np.asarray(part.lo), hi), domains)
        values = np.asarray(evaluate(rows), dtype=float).reshape(len(rows), len(bounds.signs))
        if np.isnan(values).any():
            raise CertificateError(f"sub-family {i}: a policy has no value")
        if requirement.met(values, bounds.signs).any():
            raise CertificateError(f"sub-family {i}: a policy meets {requirement}")


def certificate_json(family: Family, answer: Answer) -> dict[str, Any]:
    """The certificate as a document: the box and every sub-family closed, with the decision
    values it spans and how it was closed (the bound in the objectives' units, each half-space
    as weights in sign space and its level)."""
    names = [d.name for d in family.decisions]
    domains = [d.service.values for d in family.decisions]
    signs = [1.0 if o.direction is Direction.MAX else -1.0 for o in family.objectives]

    def spans(lo, hi) -> dict[str, list[int]]:
        return {n: [int(dom[a]), int(dom[b])] for n, dom, a, b in zip(names, domains, lo, hi)}

    parts = []
    for part in answer.closed:
        entry: dict[str, Any] = {"decisions": spans(part.lo, part.hi)}
        if part.evaluated is None:
            assert part.ideal is not None
            entry["closed_by"] = "bound"
            entry["ideal"] = [_finite(v * s) for v, s in zip(part.ideal, signs)]
            entry["cuts"] = [{"weights": [float(x) for x in w], "level": _finite(level)} for w, level in part.cuts]
        else:
            entry["closed_by"] = "evaluated"
            entry["evaluated"] = spans(part.lo, part.evaluated)
        parts.append(entry)
    return {
        "format": "parley-certificate/1",
        "requirement": [str(c) for c in answer.requirement.constraints],
        "objectives": [o.name for o in family.objectives],
        "corner": [_finite(c) for c in answer.requirement.corner],
        "tolerance": TOLERANCE,
        "sub_families": parts,
    }


def _finite(value: float) -> float | str:
    value = float(value)
    return value if math.isfinite(value) and abs(value) < abs(FLOOR) else ("inf" if value > 0 else "-inf")


def read_certificate(family: Family, document: dict[str, Any]) -> tuple[Requirement, list[Closed]]:
    """A certificate document back as the requirement and its sub-families (positions in the
    family's domains), for :func:`recheck`."""
    requirement = Requirement.of(family, [Constraint.parse(t) for t in document["requirement"]])
    positions = [{int(v): i for i, v in enumerate(d.service.values)} for d in family.decisions]
    names = [d.name for d in family.decisions]
    signs = [1.0 if o.direction is Direction.MAX else -1.0 for o in family.objectives]

    def indices(spans: dict[str, list[int]]) -> tuple[np.ndarray, np.ndarray]:
        lo = np.array([positions[k][int(spans[n][0])] for k, n in enumerate(names)], dtype=np.int64)
        hi = np.array([positions[k][int(spans[n][1])] for k, n in enumerate(names)], dtype=np.int64)
        return lo, hi

    closed = []
    for entry in document["sub_families"]:
        lo, hi = indices(entry["decisions"])
        if entry["closed_by"] == "bound":
            ideal = np.array([float(v) * s for v, s in zip(entry["ideal"], signs)])
            cuts = tuple((np.array(c["weights"], dtype=float), float(c["level"])) for c in entry["cuts"])
            closed.append(Closed(lo=lo, hi=hi, ideal=ideal, cuts=cuts))
        else:
            closed.append(Closed(lo=lo, hi=hi, evaluated=indices(entry["evaluated"])[1]))
    return requirement, closed
