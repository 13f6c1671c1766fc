"""Agreement of the quotient evaluator with Storm on robot_grid maps.

For each map (generated 10x10 maps with seeds 0-2, a generated 20x20 map, and the published
map_10, map_42 and map_99 when ../shared/reference is present) it evaluates the ten baselines
and random policies with both evaluators and prints the largest absolute difference; 200
random policies in all by default.

Usage: python benchmarks/agreement.py [--policies 200]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from parley_core.evaluate.quotient import QuotientEvaluator
from parley_core.evaluate.storm import StormEvaluator
from parley_core.family.augment import augment
from parley_core.plugin.manager import load_registry

MAPS = Path(__file__).resolve().parents[2] / "shared" / "reference" / "parley2024" / "maps"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policies", type=int, default=200)
    args = parser.parse_args()
    case = load_registry().get("robot_grid")
    instances = [["size=10", f"seed={s}"] for s in range(3)] + [["size=20", "seed=0"]]
    instances += [[f"map={MAPS / f'map_{n}.csv'}"] for n in (10, 42, 99) if (MAPS / f"map_{n}.csv").is_file()]
    per_map = -(-args.policies // len(instances))  # at least --policies in all
    worst = 0.0
    total = 0
    start = time.time()
    for index, options in enumerate(instances):
        family = augment(case.build(case.options(options)))
        rng = np.random.default_rng(index)
        random = rng.integers(1, 11, size=(per_map, len(family.decisions)))
        baselines = np.array([p.values for p in family.baseline_policies()])
        policies = np.vstack([baselines, random])
        with QuotientEvaluator(family, workers=1) as quotient, StormEvaluator(family) as storm:
            difference = float(np.abs(quotient.evaluate(policies) - storm.evaluate(policies)).max())
        worst = max(worst, difference)
        total += len(random)
        print(
            f"{' '.join(options)}: {len(baselines)} baselines + {len(random)} random policies, max difference {difference:.1e}",
            flush=True,
        )
    print(
        f"all: {total} random policies and the baselines of {len(instances)} maps, max difference {worst:.1e} ({time.time() - start:.0f} s)"
    )
    return 0 if worst <= 1e-6 else 1


if __name__ == "__main__":
    sys.exit(main())
