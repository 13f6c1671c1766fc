"""What a policy's improvement scores cost (parley_core.quotient.improve), against what an
evaluation costs: the walks of ``guided`` and the polishing of ``polished`` spend their time
on scores.

Per instance, on policies a search would score (random ones and the policies three steps of
policy improvement lead to from them, in three weightings):

- the quotient's evaluation of a policy (ms, one core): the reference of the same run;
- one policy's scores (ms, one core) and how many evaluations they cost;
- four policies' scores at once on one and on two threads (ms), as a polishing round asks
  for them (``PolicyImprover.gradients_of``; ``parley run`` gives the improver as many
  threads as the evaluator has workers).

Then the search of ``parley run robot_grid`` (map_10, seed 1, an evaluator with two workers
as ``parley run`` has on this machine) by ``paper`` with 4,000 evaluations, the reference,
and by ``polished`` with 1,000, 2,000 and 4,000: seconds and the ratio to the reference;
and a polishing round's 20 evaluations (random policies of map_10) in the main process
against split over the running workers (``quotient.SHARE_SMALL``).

Usage: python benchmarks/improve.py [--seconds 2] [--skip-20] [--skip-searches | --only-searches]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from parley_core.evaluate import quotient
from parley_core.evaluate.quotient import QuotientEvaluator
from parley_core.quotient.improve import PolicyImprover
from parley_core.search import SearchSettings, search
from parley_core.testing import family as make_family

INSTANCES = [
    ("robot_grid map_10 (default)", "robot_grid", []),
    ("robot_grid 20x20", "robot_grid", ["size=20", "seed=0"]),
    ("turtlebot", "turtlebot", []),
    ("web_ids", "web_ids", []),
    ("tas", "tas", []),
]


def timed(call, seconds: float) -> float:
    """Mean seconds of ``call()`` over at least ``seconds`` (and at least three calls)."""
    call()
    start, count = time.perf_counter(), 0
    while count < 3 or time.perf_counter() - start < seconds:
        call()
        count += 1
    return (time.perf_counter() - start) / count


def scored_policies(improver: PolicyImprover, rng: np.random.Generator) -> list[np.ndarray]:
    """Four random policies and the policies three improvement steps lead to from the first."""
    policies = [rng.integers(0, improver.sizes) for _ in range(4)]
    for weights in ([1.0, 0.0], [0.5, 0.5], [0.2, 0.8]):
        current = policies[0]
        for _ in range(3):
            scores, _ = improver.gradients(current)
            current = improver.improve(current, scores, np.resize(np.array(weights), len(improver.signs)))
        policies.append(current)
    return policies


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="time each measurement for at least this long")
    parser.add_argument("--skip-20", action="store_true")
    parser.add_argument("--skip-searches", action="store_true")
    parser.add_argument(
        "--only-searches", action="store_true", help="only the second table (it runs on earlier versions too)"
    )
    args = parser.parse_args()
    if not args.only_searches:
        print(
            "| instance | relaxation states | horizon | evaluation (ms) | scores (ms) | scores / evaluation "
            "| 4 policies' scores, 1 thread (ms) | 2 threads (ms) | speed-up |"
        )
        print("|---|---|---|---|---|---|---|---|---|")
        for label, case, assignments in INSTANCES:
            if args.skip_20 and "20x20" in label:
                continue
            print(measure(label, case, assignments, args.seconds), flush=True)
    if not args.skip_searches:
        searches()


def searches() -> None:
    """The second table: whole searches of map_10 against ``paper``'s."""
    family = make_family("robot_grid", [])
    print("\n| map_10, evaluator with 2 workers | evaluations | search (s) | against paper |")
    print("|---|---|---|---|")
    with QuotientEvaluator(family, workers=2) as evaluator:
        baselines = np.array([p.values for p in family.baseline_policies()], dtype=np.int64)
        evaluator.evaluate(np.repeat(baselines, 8, axis=0))  # the workers start here, not in the first search
        reference = None
        for name, budget in (("paper", 4000), ("polished", 1000), ("polished", 2000), ("polished", 4000)):
            settings = SearchSettings(algorithm=name, generations=None, max_evaluations=budget, seed=1)
            result = search(family, evaluator, settings)
            reference = reference or result.seconds
            print(
                f"| {name} | {result.evaluations} | {result.seconds:.1f} | {result.seconds / reference:.2f}x |",
                flush=True,
            )
        if not hasattr(quotient, "SHARE_SMALL"):
            return  # a version before small batches went to the workers
        rng = np.random.default_rng(1)
        rounds = [family.random(rng, 20) for _ in range(40)]
        print("\n| a round's 20 evaluations, map_10 | main process (ms) | over 2 workers (ms) |")
        print("|---|---|---|")
        shared = quotient.SHARE_SMALL
        try:
            quotient.SHARE_SMALL = 10**9  # never split
            alone = timed(lambda: [evaluator.evaluate(r) for r in rounds], 2.0) / len(rounds)
        finally:
            quotient.SHARE_SMALL = shared
        split = timed(lambda: [evaluator.evaluate(r) for r in rounds], 2.0) / len(rounds)
        print(f"| random policies | {1000 * alone:.1f} | {1000 * split:.1f} |", flush=True)


def measure(label: str, case: str, assignments: list[str], seconds: float) -> str:
    """One instance's row of the table."""
    family = make_family(case, assignments)
    with QuotientEvaluator(family, workers=1) as evaluator:
        alone = PolicyImprover(family, evaluator.quotient)
        threaded = PolicyImprover(family, evaluator.quotient, threads=2)
        policies = scored_policies(alone, np.random.default_rng(0))
        values = [[d.service.values[i] for d, i in zip(family.decisions, p)] for p in policies]
        rows = np.array(values, dtype=np.int64)
        evaluation = timed(lambda: evaluator.evaluate(rows), seconds) / len(rows)
    one = timed(lambda: [alone.gradients(p) for p in policies], seconds) / len(policies)
    four = policies[-4:]
    serial = timed(lambda: alone.gradients_of(four), seconds)
    parallel = timed(lambda: threaded.gradients_of(four), seconds)
    for (a, b), (c, d) in zip(alone.gradients_of(four), threaded.gradients_of(four)):
        if not (np.array_equal(a, c) and np.array_equal(b, d)):
            raise SystemExit(f"{label}: scores on two threads differ from one thread's")
    threaded.close()
    return (
        f"| {label} | {alone.relaxation.states:,} | {alone.horizon} | {1000 * evaluation:.2f} | {1000 * one:.2f} "
        f"| {one / evaluation:.1f} | {1000 * serial:.1f} | {1000 * parallel:.1f} | {serial / parallel:.2f}x |"
    )


if __name__ == "__main__":
    main()
