"""How much tighter is the bound when the relaxation is read as a POMDP?

Per case study, the ideal point of the quotient's relaxation as an MDP (its schedulers see
the true state) and as a POMDP whose observations are the decisions a state consults,
over-approximated by Storm's belief discretization (:mod:`parley_core.optimality.belief`), for each
objective Storm's belief exploration takes (unbounded reachability probabilities and
rewards); then the default run's gap to the Pareto outer approximation built on each ideal
point (same front, same reference point).

Usage: python benchmarks/belief.py [--resolution 2]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from parley_core import metrics
from parley_core.family.prepare import prepare
from parley_core.optimality.belief import belief_ideal
from parley_core.optimality.bound import ideal_point, pareto_outer
from parley_core.pipeline import run
from parley_core.plugin.manager import load_registry
from parley_core.quotient.bounds import RelaxedObjectives
from parley_core.quotient.coloring import build_quotient
from parley_core.search import SearchSettings

REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference" / "parley2024"
CASES = [
    ("robot_grid 5x5", "robot_grid", ["size=5", "seed=1"]),
    ("robot_grid (10x10)", "robot_grid", []),
    ("robot_grid, published map_10", "robot_grid", [f"map={REFERENCE / 'maps' / 'map_10.csv'}"]),
    ("turtlebot", "turtlebot", []),
    ("turtlebot, the paper's motions", "turtlebot", [f"model={REFERENCE / 'models' / 'turtlebot' / 'model.prism'}"]),
    ("web_ids", "web_ids", []),
    ("tas", "tas", []),
]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--resolution", type=int, default=2)
    args = parser.parse_args()
    print(
        "| case study | objective | MDP (all schedulers) | POMDP (belief, resolution "
        f"{args.resolution}) | belief (s) | Pareto outer gap, MDP | Pareto outer gap, POMDP |"
    )
    print("|---|---|---|---|---|---|---|")
    for label, name, options in CASES:
        case = load_registry().get(name)
        prep = prepare(case, case.options(options))
        fam = prep.family
        quotient = build_quotient(fam)
        bounds = RelaxedObjectives(fam, quotient)
        mdp = ideal_point(fam, quotient, bounds)
        start = time.perf_counter()
        pomdp = belief_ideal(fam, quotient, bounds, resolution=args.resolution, ideal=mdp)
        seconds = time.perf_counter() - start
        result = run(prep, SearchSettings(seed=1), bound="none", verify=False)
        directions = [o.direction for o in fam.objectives]
        front = metrics.hypervolume(np.array(result.front.values), directions, result.reference)
        gaps = []
        for ideal in (mdp, pomdp):
            outer = pareto_outer(fam, quotient, ideal, bounds)
            volume = outer.hypervolume(result.reference)
            gaps.append(f"{100 * (volume - front) / volume:.2f}%")
        answered = pomdp.belief or {}
        if not answered:
            print(
                f"| {label} | - (no objective Storm's belief exploration takes) | | | {seconds:.1f} | {gaps[0]} | {gaps[1]} |"
            )
        for objective, both in answered.items():
            pomdp_text = f"{both.pomdp:.6g}" if both.pomdp is not None else f"Storm refused: {both.error}"
            print(
                f"| {label} | {objective} | {both.mdp:.6g} | {pomdp_text} | {seconds:.1f} | {gaps[0]} | {gaps[1]} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
