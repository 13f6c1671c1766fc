"""Scalability (the paper's Table 3): model size, per-policy time of both evaluators, search time.

:func:`measure` builds one instance, times the quotient's construction, the median time per
policy of the Storm evaluator (the reference path, and policy programs in batches, the
verification path) and of the quotient evaluator (one process each, the same random policies),
their largest difference, and a search with the quotient evaluator; it also reports the
search space (values per decision to the power of the decisions) and peak memory.
"""

from __future__ import annotations

import json
import math
import resource
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from parley_core.evaluate.batch import BatchStormEvaluator
from parley_core.evaluate.quotient import QuotientEvaluator
from parley_core.evaluate.storm import StormEvaluator
from parley_core.family.prepare import make_family
from parley_core.plugin.casestudy import CaseStudy
from parley_core.progress import Progress
from parley_core.search import SearchSettings, search
from parley_core.search import default as search_default


def _peak_mb(who: int) -> float:
    return resource.getrusage(who).ru_maxrss / 1024


def measure(
    case: CaseStudy,
    assignments: Sequence[str],
    *,
    storm_policies: int = 20,
    quotient_policies: int = 200,
    population: int = search_default("population"),
    generations: int = search_default("generations"),
    workers: int = 2,
    seed: int = 0,
) -> dict[str, Any]:
    family = make_family(case.build(case.options(assignments)), prune=case.prune)
    rng = np.random.default_rng(seed)
    policies = family.random(rng, max(storm_policies, quotient_policies))

    start = time.perf_counter()
    quotient = QuotientEvaluator(family, workers=1)
    build = time.perf_counter() - start
    quotient.evaluate(policies[:2])  # compile and warm up
    fast_times, fast_values = [], []
    for row in policies[:quotient_policies]:
        t = time.perf_counter()
        fast_values.append(quotient.evaluate(row[None])[0])
        fast_times.append(time.perf_counter() - t)
    storm_times, storm_values = [], []
    with StormEvaluator(family, workers=1) as storm:
        storm.evaluate(policies[:1])
        for row in policies[:storm_policies]:
            t = time.perf_counter()
            storm_values.append(storm.evaluate(row[None])[0])
            storm_times.append(time.perf_counter() - t)
    # the verification path runs use: policy programs, several policies per Storm build
    with BatchStormEvaluator(family, workers=1) as batch:
        batch.evaluate(policies[:1])
        t = time.perf_counter()
        batch_values = batch.evaluate(policies[:storm_policies])
        batch_ms = 1000 * (time.perf_counter() - t) / max(1, storm_policies)
    difference = float(np.abs(np.array(fast_values[:storm_policies]) - np.array(storm_values)).max())
    difference = max(difference, float(np.abs(batch_values - np.array(storm_values)).max()))
    peak = _peak_mb(resource.RUSAGE_SELF)

    searcher = QuotientEvaluator(family, workers=workers, quotient=quotient.quotient)
    start = time.perf_counter()
    result = search(family, searcher, SearchSettings(population=population, generations=generations, seed=1))
    search_seconds = time.perf_counter() - start
    searcher.close()
    space = sum(math.log10(d.service.high - d.service.low + 1) for d in family.decisions)
    return {
        "instance": " ".join(assignments),
        "decisions": len(family.decisions),
        "search_space_log10": space,
        "quotient_states": quotient.quotient.states,
        "quotient_choices": quotient.quotient.choices,
        "quotient_transitions": quotient.quotient.branches,
        "quotient_build_s": build,
        "storm_ms": 1000 * float(np.median(storm_times)),
        "batch_ms": batch_ms,
        "quotient_ms": 1000 * float(np.median(fast_times)),
        "ratio": float(np.median(storm_times) / np.median(fast_times)),
        "max_difference": difference,
        "search_evaluations": result.evaluations,
        "search_s": search_seconds,
        "workers": workers,
        "peak_mb": max(peak, _peak_mb(resource.RUSAGE_SELF)),
        "peak_worker_mb": _peak_mb(resource.RUSAGE_CHILDREN),
    }


def table3_markdown(rows: Sequence[dict[str, Any]]) -> str:
    lines = [
        "| instance | decisions | search space | quotient states | transitions | build (s) | Storm, augmented (ms/policy) | Storm, policy programs (ms/policy) | quotient (ms/policy) | ratio | max diff | search (s, evaluations) | peak MB (main + per worker) |",  # noqa: E501
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['instance']} | {r['decisions']} | 10^{r['search_space_log10']:.0f} | {r['quotient_states']:,} | "
            f"{r['quotient_transitions']:,} | {r['quotient_build_s']:.1f} | {r['storm_ms']:.1f} | "
            f"{r.get('batch_ms', float('nan')):.1f} | "
            f"{r['quotient_ms']:.2f} | {r['ratio']:.0f}x | {r['max_difference']:.0e} | "
            f"{r['search_s']:.1f} ({r['search_evaluations']}) | {r['peak_mb']:.0f} + {r['peak_worker_mb']:.0f} |"
        )
    return "\n".join(lines) + "\n"


def _measure_by_name(case_name: str, assignments: Sequence[str], kwargs: dict[str, Any]) -> dict[str, Any]:
    from parley_core.plugin.manager import load_registry

    return measure(load_registry().get(case_name), assignments, **kwargs)


def measure_isolated(case_name: str, assignments: Sequence[str], **kwargs: Any) -> dict[str, Any]:
    """:func:`measure` in a fresh process, so that memory figures do not mix between instances."""
    from parley_core.evaluate.pool import spawn_pool

    with spawn_pool(1) as pool:
        return pool.submit(_measure_by_name, case_name, list(assignments), kwargs).result()


def write_table3(
    case: CaseStudy,
    sizes: Sequence[int],
    option: str,
    fixed: Sequence[str],
    *,
    storm_policies: int,
    out: Path | None = None,
    progress: Progress | None = None,
) -> str:
    """Measure every size in a fresh process; write table3.md and table3.json into ``out``
    (if given); returns the table."""
    for size in sizes:
        case.options([*fixed, f"{option}={size}"])  # every size's options are checked first
    rows = []
    for size in sizes:
        row = measure_isolated(case.name, [*fixed, f"{option}={size}"], storm_policies=storm_policies)
        row["instance"] = f"{option}={size}"
        rows.append(row)
        if progress:
            progress(1)
    table = table3_markdown(rows)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "table3.md").write_text(table)
        (out / "table3.json").write_text(json.dumps(rows, indent=2))
    return table
