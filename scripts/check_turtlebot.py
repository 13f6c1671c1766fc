"""Check the turtlebot plugin against the paper's published model and print the differences.

The paper's ``models/turtlebot/model.prism`` holds its Gazebo-sampled motions, its movement
controller and the URC as 196 ``evolve int decision_X_Y_H[1..5]`` parameters;
``umc_controller.txt`` is one synthesized policy (values in ``decisions.txt`` order). For
that policy, the five fixed periods and ``--random`` random policies, this script checks with
plain stormpy that

1. the published file (parameters defined as constants) and
2. the model parley generates from it (``model=FILE repair=false``, the published semantics)

give the same success probability and energy, and prints how much the repair of the
published ``[south]`` slip (``repair=true``, the default) changes them.

Usage:
    python scripts/check_turtlebot.py [--reference DIR] [--random 20] [--seed 0]

The reference data is not part of this repository (see ../shared/reference/parley2024).
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

import numpy as np

from parley_core.family.augment import augment
from parley_core.plugin.manager import load_registry
from parley_core.testing import storm_values

ROOT = Path(__file__).resolve().parents[1]
PUBLISHED_PROPERTIES = ["P=? [ F x=targetX & y=targetY ]", 'R{"energy"}=? [ C<=200 ]']
PARLEY_PROPERTIES = ['P=? [F "goal"]', 'R{"energy"}=? [C<=200]']


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference", type=Path, default=ROOT.parent / "shared/reference/parley2024")
    parser.add_argument(
        "--random", type=int, default=20, help="random policies besides the published one and the baselines"
    )
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    folder = args.reference / "models" / "turtlebot"
    model = folder / "model.prism"
    if not model.is_file():
        print(f"error: {model} not found; give --reference DIR (the paper's reference data)", file=sys.stderr)
        return 2
    text = model.read_text()
    names = (folder / "decisions.txt").read_text().split()
    published_policy = [int(v) for v in (folder / "umc_controller.txt").read_text().split()]

    case = load_registry().get("turtlebot")
    kept = augment(case.build(case.options([f"model={model}", "repair=false"])))
    repaired = augment(case.build(case.options([f"model={model}"])))

    rng = np.random.default_rng(args.seed)
    policies = [("umc_controller.txt", published_policy)]
    policies += [(f"period-{k}", [k] * len(names)) for k in range(1, 6)]
    policies += [(f"random-{i}", rng.integers(1, 6, len(names)).tolist()) for i in range(args.random)]

    print(
        f"{'policy':>20}  {'published P':>12} {'E':>10}  {'parley P':>12} {'E':>10}  {'diff':>8}  {'repaired P':>10} {'E':>10}"
    )
    worst = 0.0
    start = time.perf_counter()
    for label, values in policies:
        by_name = dict(zip(names, values))
        defined = re.sub(
            r"evolve int (decision_\w+)\[1\.\.5\];",
            lambda m, by_name=by_name: f"const int {m.group(1)} = {by_name[m.group(1)]};",
            text,
        )
        published = storm_values(defined, PUBLISHED_PROPERTIES)
        ours = storm_values(kept.prism, PARLEY_PROPERTIES, _constants(kept, by_name))
        fixed = storm_values(repaired.prism, PARLEY_PROPERTIES, _constants(repaired, by_name))
        diff = max(abs(a - b) for a, b in zip(published, ours))
        worst = max(worst, diff)
        print(
            f"{label:>20}  {published[0]:12.6f} {published[1]:10.4f}  {ours[0]:12.6f} {ours[1]:10.4f}  {diff:8.1e}  "
            f"{fixed[0]:10.6f} {fixed[1]:10.4f}"
        )
    print(
        f"{len(policies)} policies in {time.perf_counter() - start:.0f} s; largest difference published vs parley: {worst:.1e}"
    )
    return 0 if worst <= 1e-9 else 1


def _constants(family, by_name):
    return {d.name: by_name["decision_" + "_".join(map(str, d.valuation))] for d in family.decisions}


if __name__ == "__main__":
    sys.exit(main())
