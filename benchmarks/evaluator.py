"""Evaluator benchmark: the quotient evaluator against the Storm evaluator, measured in one run.

For each robot_grid map size (10x10 is the paper's map_10 when the reference data is present,
otherwise a generated map; larger sizes are generated with seed 0) it prints, from
:func:`parley_core.experiment.scalability.measure` run in a fresh process per size:

- the quotient MDP's size and build time;
- the median time per policy of both evaluators, in one process each, on the same random
  policies, their ratio, and their largest difference;
- the time of a 4000-evaluation NSGA-II search (population 100, 40 generations) with the
  quotient evaluator and two worker processes, as ``parley run`` does it;
- peak memory (resident set) of the measuring process and of its largest worker.

Usage: python benchmarks/evaluator.py [--sizes 10,20,50] [--storm-policies 20] [--quotient-policies 200]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from parley_core.experiment.scalability import measure_isolated, table3_markdown

PUBLISHED_MAP = Path(__file__).resolve().parents[2] / "shared" / "reference" / "parley2024" / "maps" / "map_10.csv"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", default="10,20,50")
    parser.add_argument("--storm-policies", type=int, default=20)
    parser.add_argument("--quotient-policies", type=int, default=200)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    rows = []
    for size in [int(s) for s in args.sizes.split(",")]:
        assignments = [f"map={PUBLISHED_MAP}"] if size == 10 and PUBLISHED_MAP.is_file() else [f"size={size}", "seed=0"]
        start = time.perf_counter()
        row = measure_isolated(
            "robot_grid",
            assignments,
            storm_policies=args.storm_policies if size <= 20 else max(3, args.storm_policies // 4),
            quotient_policies=args.quotient_policies if size <= 20 else args.quotient_policies // 4,
            workers=args.workers,
        )
        row["instance"] = f"{size}x{size}" + (" (map_10)" if "map=" in assignments[0] else "")
        rows.append(row)
        print(
            f"{row['instance']}: quotient {row['quotient_states']} states, built in {row['quotient_build_s']:.1f} s; "
            f"per policy: Storm {row['storm_ms']:.1f} ms, quotient {row['quotient_ms']:.2f} ms, ratio {row['ratio']:.0f}x, "
            f"max difference {row['max_difference']:.1e}; 4000-evaluation search {row['search_s']:.1f} s "
            f"with {row['workers']} workers; peak memory {row['peak_mb']:.0f} MB (+ {row['peak_worker_mb']:.0f} MB per worker); "
            f"{time.perf_counter() - start:.0f} s in all",
            flush=True,
        )
    print()
    print(table3_markdown(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
