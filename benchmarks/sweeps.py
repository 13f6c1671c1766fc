"""What benchmarks/loc_error.py and benchmarks/imperfect_services.py share: one option of a
case study swept over rates, a default run (through ``parley_core.pipeline``) at each."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence

import numpy as np
from attrs import frozen

from parley_core import metrics
from parley_core.family.prepare import prepare
from parley_core.pipeline import RunResult, run
from parley_core.plugin.manager import load_registry
from parley_core.search import SearchSettings


@frozen(kw_only=True)
class Point:
    """One run of a sweep: its rate and what the run gave."""

    rate: float
    result: RunResult
    seconds: float

    @property
    def front(self) -> np.ndarray:
        return np.array(self.result.front.values)

    @property
    def baseline(self) -> np.ndarray:
        return np.array(self.result.baseline.values)

    @property
    def knee(self) -> np.ndarray:
        return self.front[self.result.selected]

    def hypervolume(self, reference) -> float:
        directions = [o.direction for o in self.result.family.objectives]
        return metrics.hypervolume(self.front, directions, reference)


def sweep(
    case_name: str, option: str, rates: Sequence[float], settings: SearchSettings, base: Mapping[str, str]
) -> list[Point]:
    """The default run of ``case_name`` (options ``base``) at each rate of ``option``."""
    case = load_registry().get(case_name)
    points = []
    for rate in rates:
        start = time.perf_counter()
        result = run(prepare(case, case.options_from({**base, option: repr(rate)})), settings, workers=2, bound="none")
        points.append(Point(rate=rate, result=result, seconds=time.perf_counter() - start))
    return points


def common_reference(points: Sequence[Point]) -> np.ndarray:
    """One reference point for all runs of a sweep, chosen as a run chooses its own."""
    objectives = points[0].result.family.objectives
    return metrics.reference_point(objectives, *(p.front for p in points), *(p.baseline for p in points))
