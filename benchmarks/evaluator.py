"""Evaluator benchmark: the quotient evaluator against the Storm evaluator, measured in one run.

For each map size (10x10 is the paper's map_10 when the reference data is present,
otherwise a generated map; larger sizes are generated with seed 0) it prints:

- the quotient MDP's size and build time;
- the median time per policy of both evaluators, in one process each, on the same random
  policies, their ratio, and their largest difference;
- the time of a 4000-evaluation NSGA-II search (population 100, 40 generations) with the
  quotient evaluator and its worker processes, as ``parley run`` does it;
- peak memory (resident set) of the process and of its workers.

Each size runs in a fresh subprocess so that memory figures do not mix.

Usage: python benchmarks/evaluator.py [--sizes 10,20,50] [--storm-policies 20] [--quotient-policies 200]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PUBLISHED_MAP = ROOT.parent / "shared" / "reference" / "parley2024" / "maps" / "map_10.csv"


def measure(size: int, storm_policies: int, quotient_policies: int, workers: int) -> dict:
    from parley_core.augment import augment
    from parley_core.evaluate.quotient import QuotientEvaluator
    from parley_core.evaluate.storm import StormEvaluator
    from parley_core.plugins import load_registry
    from parley_core.search import SearchSettings, search

    case = load_registry().get("robot_grid")
    options = [f"map={PUBLISHED_MAP}"] if size == 10 and PUBLISHED_MAP.is_file() else [f"size={size}", "seed=0"]
    family = augment(case.build(case.options(options)))
    rng = np.random.default_rng(0)
    policies = rng.integers(1, 11, size=(max(storm_policies, quotient_policies), len(family.decisions)))

    start = time.perf_counter()
    quotient = QuotientEvaluator(family, workers=1)
    build = time.perf_counter() - start
    quotient.evaluate(policies[:2])  # compile / warm up
    fast_times, fast_values = [], []
    for row in policies[:quotient_policies]:
        t = time.perf_counter()
        fast_values.append(quotient.evaluate(row[None])[0])
        fast_times.append(time.perf_counter() - t)
    storm = StormEvaluator(family, workers=1)
    storm.evaluate(policies[:1])
    storm_times, storm_values = [], []
    for row in policies[:storm_policies]:
        t = time.perf_counter()
        storm_values.append(storm.evaluate(row[None])[0])
        storm_times.append(time.perf_counter() - t)
    storm.close()
    difference = float(np.abs(np.array(fast_values[:storm_policies]) - np.array(storm_values)).max())
    memory_before_search = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    searcher = QuotientEvaluator(family, workers=workers, quotient=quotient.quotient)
    start = time.perf_counter()
    result = search(family, searcher, SearchSettings(population=100, generations=40, seed=1))
    search_seconds = time.perf_counter() - start
    searcher.close()
    return {
        "size": size,
        "map": options[0],
        "decisions": len(family.decisions),
        "quotient_states": quotient.quotient.states,
        "quotient_choices": quotient.quotient.choices,
        "quotient_transitions": quotient.quotient.branches,
        "quotient_build_s": build,
        "storm_ms": 1000 * float(np.median(storm_times)),
        "quotient_ms": 1000 * float(np.median(fast_times)),
        "ratio": float(np.median(storm_times) / np.median(fast_times)),
        "max_difference": difference,
        "search_evaluations": result.evaluations,
        "search_s": search_seconds,
        "workers": workers,
        "peak_mb": max(memory_before_search, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024),
        "peak_worker_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", default="10,20,50")
    parser.add_argument("--storm-policies", type=int, default=20)
    parser.add_argument("--quotient-policies", type=int, default=200)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        print(json.dumps(measure(args.child, args.storm_policies, args.quotient_policies, args.workers)))
        return 0
    rows = []
    for size in [int(s) for s in args.sizes.split(",")]:
        storm_policies = args.storm_policies if size <= 20 else max(3, args.storm_policies // 4)
        command = [
            sys.executable, __file__, "--child", str(size), "--storm-policies", str(storm_policies),
            "--quotient-policies", str(args.quotient_policies if size <= 20 else args.quotient_policies // 4),
            "--workers", str(args.workers),
        ]
        start = time.perf_counter()
        output = subprocess.run(command, capture_output=True, text=True, check=True).stdout
        row = json.loads(output.strip().splitlines()[-1])
        row["total_s"] = time.perf_counter() - start
        rows.append(row)
        print(
            f"{size}x{size}: quotient {row['quotient_states']} states, {row['quotient_transitions']} transitions, "
            f"built in {row['quotient_build_s']:.1f} s; per policy: Storm {row['storm_ms']:.1f} ms, "
            f"quotient {row['quotient_ms']:.2f} ms, ratio {row['ratio']:.0f}x, max difference {row['max_difference']:.1e}; "
            f"4000-evaluation search {row['search_s']:.1f} s with {row['workers']} workers; "
            f"peak memory {row['peak_mb']:.0f} MB (+ {row['peak_worker_mb']:.0f} MB per worker)",
            flush=True,
        )
    print()
    print("| map | quotient states | build (s) | Storm (ms/policy) | quotient (ms/policy) | ratio | max diff | 4000-eval search (s) | peak MB (main + per worker) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['size']}x{r['size']} | {r['quotient_states']:,} | {r['quotient_build_s']:.1f} | {r['storm_ms']:.1f} | "
            f"{r['quotient_ms']:.2f} | {r['ratio']:.0f}x | {r['max_difference']:.0e} | {r['search_s']:.1f} | "
            f"{r['peak_mb']:.0f} + {r['peak_worker_mb']:.0f} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
