"""Requirement answers for a campaign's cells: ``parley experiment check`` says, for every
instance and requirement setting (the box of a Table 2 cell), whether a policy of the
instance's family meets it, and stores the answer.

Per cell, cheapest first:

1. a policy of a stored front (any repetition) meets the box by its stored values: Storm
   checks that policy, and its values decide (*feasible*, by "front");
2. the instance's stored certified bound (``parley experiment bound``) misses the box: no
   policy of the family can meet it (*infeasible*, by "bound");
3. otherwise branch and bound driven by the box (:mod:`parley_core.optimality.requirement`),
   started from the stored fronts, for at most the cell's time limit: *feasible* (its policy
   checked by Storm), *infeasible* (every sub-family closed; ``parley check`` on the instance
   writes the certificate) or *unknown*.

An answer is a property of the instance's family, not of a repetition; it is computed once
per cell (rerunning skips the cells that have one, unless asked again).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import attrs
import numpy as np
from attrs import frozen

from parley_core.constraints import Constraint, Operator
from parley_core.errors import OptionError
from parley_core.evaluate.pool import each_result
from parley_core.experiment.store import Store
from parley_core.model import Direction, Family
from parley_core.progress import Progress

Setting = tuple[float, ...]


@frozen(kw_only=True)
class CellAnswer:
    """One cell's answer, how it was reached ("front", "bound", "branch and bound"), the
    values of the policy that meets it (Storm's; empty otherwise), the share of the family
    left open (unknown) and the seconds it took."""

    setting: Setting
    answer: str
    by: str
    values: tuple[float, ...] = ()
    open_share: float = 0.0
    seconds: float = 0.0


@frozen(kw_only=True)
class AnswerTask:
    campaign: str
    case: str
    instance: str
    options: dict[str, Any]
    settings: tuple[Setting, ...]
    policies: np.ndarray
    """The stored fronts' policies (every repetition), rows of decision values."""
    values: np.ndarray
    """Their stored values."""
    bound: np.ndarray | None
    """The instance's stored certified bound (points), if any."""
    seconds: float
    """Branch and bound's time limit per cell."""


def constraints(family: Family, setting: Setting) -> list[Constraint]:
    """A setting (the worst acceptable value per objective) as requirements."""
    if len(setting) != len(family.objectives):
        raise OptionError(f"setting {setting} has {len(setting)} bounds; give one per objective")
    return [
        Constraint(
            objective=o.name,
            operator=Operator.AT_LEAST if o.direction is Direction.MAX else Operator.AT_MOST,
            bound=float(b),
        )
        for o, b in zip(family.objectives, setting)
    ]


def _bound_misses(points: np.ndarray | None, corner: np.ndarray, signs: np.ndarray) -> bool:
    """Whether no point of a certified bound weakly dominates the box's corner (sign space):
    every policy is weakly dominated by a bound point, so none is in the box."""
    if points is None or not len(points):
        return False
    rows = np.asarray(points, dtype=float).reshape(-1, len(signs)) * signs
    return not bool((rows >= corner).all(axis=1).any())


def compute(task: AnswerTask) -> tuple[AnswerTask, list[CellAnswer]]:
    """One instance's cells (in this process: a campaign's cells go over instances)."""
    import time

    from parley_core.evaluate.storm import StormChecker, StormTask
    from parley_core.family.prepare import prepare
    from parley_core.optimality.requirement import Requirement, Verdict, answer
    from parley_core.plugin.manager import load_registry
    from parley_core.prism.program import quiet_storm
    from parley_core.quotient.bounds import RelaxedObjectives
    from parley_core.quotient.coloring import build_quotient
    from parley_core.quotient.solver import QuotientSolver

    quiet_storm()  # in a worker process this is the entry point
    case = load_registry().get(task.case)
    family = prepare(case, case.options_from_json(task.options)).family
    signs = np.array([1.0 if o.direction is Direction.MAX else -1.0 for o in family.objectives])
    quotient = build_quotient(family)
    solver = QuotientSolver(quotient)
    bounds = RelaxedObjectives(family, quotient)
    storm = StormChecker(StormTask.of(family))
    rows = np.asarray(task.policies, dtype=np.int64).reshape(-1, len(family.decisions))
    values = np.asarray(task.values, dtype=float).reshape(-1, len(family.objectives))

    def evaluate(policies: np.ndarray) -> np.ndarray:
        return np.array([solver.solve(p) for p in policies], dtype=float).reshape(-1, len(signs))

    def verified(requirement: Requirement, candidates: np.ndarray) -> tuple[float, ...] | None:
        for row in candidates[:3]:  # Storm's values decide; the first that meets them is the answer
            checked = np.array(storm.check(row), dtype=float)
            if requirement.met(checked, signs).all():
                return tuple(float(v) for v in checked)
        return None

    out = []
    for setting in task.settings:
        began = time.perf_counter()
        requirement = Requirement.of(family, constraints(family, setting))
        found = verified(requirement, rows[requirement.met(values, signs)])
        if found is not None:
            out.append(CellAnswer(setting=setting, answer="feasible", by="front", values=found))
        elif _bound_misses(task.bound, requirement.corner, signs):
            out.append(CellAnswer(setting=setting, answer="infeasible", by="bound"))
        else:
            result = answer(
                family, quotient, evaluate, requirement, seeds=(rows, values), time_limit=task.seconds, bounds=bounds
            )
            checked = verified(requirement, result.policies) if result.verdict is Verdict.FEASIBLE else None
            verdict = "feasible" if checked is not None else result.verdict.value
            if result.verdict is Verdict.FEASIBLE and checked is None:
                verdict = "unknown"  # Storm's values of the policies found miss the box: not an answer
            out.append(
                CellAnswer(
                    setting=setting,
                    answer=verdict,
                    by="branch and bound",
                    values=checked or (),
                    open_share=result.open_share if verdict == "unknown" else 0.0,
                )
            )
        out[-1] = attrs.evolve(out[-1], seconds=time.perf_counter() - began)
    return task, out


def plan(
    store: Store, campaign: str, case: str, settings: Sequence[Setting], seconds: float, again: bool = False
) -> list[AnswerTask]:
    """One task per instance with a cell not answered yet (every cell with ``again``)."""
    have = {} if again else store.answers(campaign)
    bounds = store.bounds(campaign)
    by_instance: dict[str, list] = {}
    for record in store.runs(campaign):
        by_instance.setdefault(record.instance, []).append(record)
    if not by_instance:
        raise OptionError(f"campaign {campaign} has no finished run yet; its instances come from its runs")
    tasks = []
    for instance, records in by_instance.items():
        wanted = tuple(s for s in settings if (instance, tuple(s)) not in have)
        if not wanted:
            continue
        n = len(records[0].objectives)
        policies = [np.array([p.values for p in r.front.policies], dtype=np.int64) for r in records]
        tasks.append(
            AnswerTask(
                campaign=campaign,
                case=case,
                instance=instance,
                options=records[0].options,
                settings=wanted,
                policies=np.vstack([p.reshape(len(p), -1) for p in policies]),
                values=np.vstack([r.values()[0].reshape(-1, n) for r in records]),
                bound=bounds.get(instance),
                seconds=seconds,
            )
        )
    return tasks


def run(tasks: Sequence[AnswerTask], store: Store, workers: int | None = None, progress: Progress | None = None) -> int:
    """Answer and store each task's cells as it finishes; the number of cells stored."""
    stored = 0

    def finish(task: AnswerTask, cells: list[CellAnswer]) -> None:
        nonlocal stored
        for cell in cells:
            store.add_answer(task.campaign, task.instance, cell.setting, attrs.asdict(cell))
            stored += 1
        if progress:
            progress(1)

    for found in each_result(compute, tasks, workers):
        finish(*found)
    return stored
