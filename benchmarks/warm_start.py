"""Re-synthesis after the model changed: a warm start from the old front against a cold search.

The robot's slip probability moves from 0.01 to 0.03 on the paper's map_10. A cold search
for p=0.03 starts from the baselines and random policies; a warm one also from the p=0.01
front (``parley run ... --warm-start RUN_DIR``). Both have the paper's budget (population
100, 40 generations, 4,000 evaluations); the script prints, per seed, the hypervolume of
everything evaluated so far (the quotient's values, one reference point for both: the cold
run's) after 250, 500, 1000, 2000 and 4000 evaluations, as a share of the cold search's
final one, and the evaluations each needs to reach 99 % and 100 % of it.

    .venv/bin/python benchmarks/warm_start.py [--seeds 3] [--map PATH]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from parley_core import metrics
from parley_core.family.prepare import prepare
from parley_core.model import Policy
from parley_core.pipeline import run
from parley_core.plugin.manager import load_registry
from parley_core.search import SearchSettings

MAP = Path(__file__).resolve().parents[2] / "shared" / "reference" / "parley2024" / "maps" / "map_10.csv"
CHECKPOINTS = (250, 500, 1000, 2000, 4000)


def curve(values: np.ndarray, directions, reference, points) -> list[float]:
    return [metrics.hypervolume(values[:n], directions, reference) for n in points]


def first_reaching(values: np.ndarray, directions, reference, target: float) -> int | None:
    """The fewest evaluations whose archive reaches ``target`` hypervolume (steps of 50)."""
    for n in range(50, len(values) + 50, 50):
        if metrics.hypervolume(values[:n], directions, reference) >= target * (1 - 1e-12):
            return min(n, len(values))
    return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--map", type=Path, default=MAP)
    args = parser.parse_args()
    case = load_registry().get("robot_grid")
    old = prepare(case, case.options_from({"map": str(args.map), "p": "0.01"}))
    new = prepare(case, case.options_from({"map": str(args.map), "p": "0.03"}))
    print("| seed | start | " + " | ".join(f"HV@{n}" for n in CHECKPOINTS) + " | evals to 99 % | evals to 100 % |")
    print("|---|---|" + "---|" * len(CHECKPOINTS) + "---|---|")
    gains = []
    for seed in range(1, args.seeds + 1):
        settings = SearchSettings(population=100, generations=40, seed=seed)
        before = run(old, settings, workers=2, verify=False, bound="none")
        warm = [Policy(name=p.name, values=p.values) for p in before.front.policies]
        cold = run(new, settings, workers=2, verify=False, bound="none")
        hot = run(new, settings, workers=2, verify=False, bound="none", warm=warm)
        directions = [o.direction for o in new.family.objectives]
        reference = cold.reference
        target = metrics.hypervolume(cold.search.values, directions, reference)
        for name, result in (("cold", cold), ("warm", hot)):
            values = result.search.values
            shares = [v / target for v in curve(values, directions, reference, CHECKPOINTS)]
            at99 = first_reaching(values, directions, reference, 0.99 * target)
            at100 = first_reaching(values, directions, reference, target)
            print(
                f"| {seed} | {name} | "
                + " | ".join(f"{100 * s:.2f} %" for s in shares)
                + f" | {at99 if at99 is not None else '> 4000'} | {at100 if at100 is not None else '> 4000'} |",
                flush=True,
            )
            if name == "warm":
                gains.append((at99, first_reaching(cold.search.values, directions, reference, 0.99 * target)))
    ratios = [c / w for w, c in gains if w and c]
    if ratios:
        print(
            f"\ncold / warm evaluations to 99 % of the cold search's final hypervolume: median {np.median(ratios):.1f}x"
        )


if __name__ == "__main__":
    main()
