"""The kernels' Pareto outer bound against Storm's own multi-objective engine, on the relaxation.

For each family: parley's outer bound of the quotient's relaxation (``pareto_outer``: the
ideal box cut by weighted sums solved by backward induction, covered by a staircase) and
Storm's multi-objective query on the same relaxation (``storm_pareto``: PCAA, step-bounded
rewards included, at ``--precision``). Printed: both times, the vertices of Storm's
under-approximation (values relaxed schedulers reach), whether the bound weakly dominates
every one of them (it must: it is sound for the relaxation), and the bound's hypervolume
over those vertices' (how much room the staircase leaves beyond points known to be reached;
the vertices' staircase, not their convex hull, so an upper limit), reference point 10 % of
the span beyond the worst value of either.

Usage: python benchmarks/storm_pareto.py [--precision 1e-4]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from parley_core import metrics
from parley_core.optimality.bound import pareto_outer
from parley_core.optimality.storm_pareto import storm_pareto
from parley_core.quotient.coloring import build_quotient
from parley_core.testing import family as make_family

CASES = [
    ("robot_grid 5x5", "robot_grid", ["size=5", "seed=1", "max_interval=4", "horizon=45"]),
    ("robot_grid 10x10 (defaults)", "robot_grid", []),
    ("web_ids", "web_ids", []),
    ("tas", "tas", []),
    ("turtlebot", "turtlebot", []),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--precision", type=float, default=1e-4)
    args = parser.parse_args()
    print(
        "| family | parley's bound (s) | Storm multi-objective (s) | Storm's vertices | all dominated | bound HV / vertices' HV |"
    )
    print("|---|---|---|---|---|---|")
    for label, case, options in CASES:
        family = make_family(case, options)
        quotient = build_quotient(family)
        start = time.perf_counter()
        outer = pareto_outer(family, quotient)
        ours = time.perf_counter() - start
        storm = storm_pareto(family, quotient, precision=args.precision)
        directions = [o.direction for o in family.objectives]
        signs = np.array([o.direction.sign for o in family.objectives])  # minimised in sign space
        both = np.vstack([outer.points, storm.achieved]) * signs
        low, high = both.min(axis=0), both.max(axis=0)
        reference = (high + 0.1 * (high - low)) * signs
        ratio = metrics.hypervolume(outer.points, directions, reference) / metrics.hypervolume(
            storm.achieved, directions, reference
        )
        dominated = bool(outer.dominates(storm.achieved, tolerance=1e-6).all())
        print(
            f"| {label} | {ours:.2f} | {storm.seconds:.2f} | {len(storm.achieved)} | "
            f"{'yes' if dominated else 'NO'} | {ratio:.4f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
