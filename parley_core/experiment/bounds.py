"""Certified bounds for a campaign's instances: ``parley experiment bound`` computes each
instance's outer bound once (it depends on the instance alone, not on a repetition) and
stores it; the campaign report then says, per requirement setting, how far the fronts are
from it (the median gap of the hypervolume to the bound's, within the setting's box)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from attrs import frozen

from parley_core.errors import OptionError
from parley_core.evaluate.pool import each_result
from parley_core.experiment.store import Store
from parley_core.optimality.after_search import family_bound
from parley_core.optimality.records import BoundMethod
from parley_core.progress import Progress


@frozen(kw_only=True)
class BoundTask:
    campaign: str
    case: str
    instance: str
    options: dict[str, Any]
    method: str


def compute(task: BoundTask) -> tuple[BoundTask, np.ndarray, str, float]:
    """One instance's bound (in this process: campaigns parallelize over instances)."""
    from parley_core.family.prepare import prepare
    from parley_core.plugin.manager import load_registry
    from parley_core.prism.program import quiet_storm

    quiet_storm()  # in a worker process this is the entry point
    case = load_registry().get(task.case)
    prepared = prepare(case, case.options_from_json(task.options))
    bound = family_bound(prepared.family, task.method)
    return task, np.asarray(bound.points, dtype=float), bound.method, bound.seconds


def plan(store: Store, campaign: str, case: str, method: str, again: bool = False) -> list[BoundTask]:
    """One task per instance of the campaign without a stored bound (every one with ``again``)."""
    method = BoundMethod.of(method, cheap=True).value
    have = set() if again else set(store.bounds(campaign))
    first: dict[str, dict[str, Any]] = {}
    for record in store.runs(campaign):
        first.setdefault(record.instance, record.options)
    if not first:
        raise OptionError(f"campaign {campaign} has no finished run yet; its instances come from its runs")
    return [
        BoundTask(campaign=campaign, case=case, instance=i, options=o, method=method)
        for i, o in first.items()
        if i not in have
    ]


def run(tasks: Sequence[BoundTask], store: Store, workers: int | None = None, progress: Progress | None = None) -> int:
    """Compute and store each task's bound as it finishes; the number stored."""
    stored = 0

    def finish(task: BoundTask, points: np.ndarray, method: str, seconds: float) -> None:
        nonlocal stored
        store.add_bound(task.campaign, task.instance, method, points, seconds)
        stored += 1
        if progress:
            progress(1)

    for found in each_result(compute, tasks, workers):
        finish(*found)
    return stored


def hypervolume(points: np.ndarray | None, directions, setting) -> float:
    """The bound's hypervolume with the setting as reference point (nan: no bound, or an
    unbounded one); no front of the instance can exceed it."""
    from parley_core import metrics

    if points is None or not len(points) or not np.isfinite(points).all():
        return float("nan")
    return float(metrics.hypervolume(points, directions, setting))


def gaps(bound_hv: float, hvs: Sequence[float]) -> list[float]:
    """(bound - front) / bound of each repetition's hypervolume (empty: no usable bound)."""
    if not (np.isfinite(bound_hv) and bound_hv > 0):
        return []
    return [(bound_hv - h) / bound_hv for h in hvs]
