"""Storm's proof at the speed of the search: the two verification paths, measured in one run.

Four tables, printed as Markdown:

1. per-policy time of each path on one core: the reference (the augmented program with the
   decisions defined, one Storm build per policy) and policy programs (the original model
   with the decisions as a formula of the observation and the policy index, several
   policies per build, the default), on robot_grid maps of 10x10, 20x20 and 50x50 and the
   other case studies' defaults; the same random policies for both, and the largest
   difference between their values (relative to the value's size, at least 1);
2. a whole front: ``parley run robot_grid`` (the published map_10 when ../shared is there,
   else a generated 10x10 map) verified by each path on two workers, front and baselines;
3. Storm's floor for that front: the states Storm built for it (policy programs), and how
   long Storm's explicit builder takes for as many states of the simplest program there is
   (one counter variable, two successors a state, built in batches of the same size): about
   the least time in which any program Storm builds state by state verifies the front on
   two workers;
4. campaign runs as ``parley experiment run`` makes them (one worker, the paper's budget,
   verification on): search time against verification time per run, over ``--campaign``
   published maps (generated ones when ../shared is absent).

Usage: python benchmarks/verify.py [--policies 24] [--big 2] [--campaign 4] [--skip-50]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from parley_core.evaluate.batch import BATCH_STATES, BatchStormEvaluator
from parley_core.evaluate.storm import StormEvaluator
from parley_core.family.prepare import prepare
from parley_core.pipeline import run
from parley_core.plugin.manager import load_registry
from parley_core.prism import program as prism
from parley_core.search import SearchSettings
from parley_core.testing import family as make_family
from parley_core.verify import VerifyPath, check_with_storm, differences

MAPS = Path(__file__).resolve().parents[2] / "shared" / "reference" / "parley2024" / "maps"


def per_policy(label: str, case: str, assignments: list[str], count: int, reference_count: int) -> dict:
    family = make_family(case, assignments)
    policies = family.random(np.random.default_rng(11), count)
    with StormEvaluator(family, workers=1) as reference:
        reference.evaluate(policies[:1])  # parse and warm up
        start = time.perf_counter()
        single = reference.evaluate(policies[:reference_count])
        reference_ms = 1000 * (time.perf_counter() - start) / reference_count
    with BatchStormEvaluator(family, workers=1) as fast:
        fast.evaluate(policies[:1])
        start = time.perf_counter()
        batch = fast.evaluate(policies)
        fast_ms = 1000 * (time.perf_counter() - start) / count
        states = (fast.states - fast.states_per_policy) / count  # the timed batches only
    _, relative = differences(batch[:reference_count], single)
    return {
        "instance": label,
        "decisions": len(family.decisions),
        "states": states,
        "reference_ms": reference_ms,
        "batch_ms": fast_ms,
        "ratio": reference_ms / fast_ms,
        "difference": float(relative.max()),
        "policies": f"{reference_count} / {count}",
    }


def whole_front(options: list[str]) -> dict:
    case = load_registry().get("robot_grid")
    prepared = prepare(case, case.options(options))
    result = run(prepared, SearchSettings(seed=1), workers=2, verify=False, bound="none")
    family = prepared.family
    rows = np.vstack(
        [
            np.array([p.values for p in result.baseline.policies], dtype=np.int64),
            np.array([p.values for p in result.front.policies], dtype=np.int64),
        ]
    )
    values = np.vstack([result.baseline.values, result.front.values])
    timings = {}
    for path in (VerifyPath.REFERENCE, VerifyPath.BATCH):
        start = time.perf_counter()
        verification, _ = check_with_storm(family, rows, values, workers=2, path=path)
        timings[path] = (time.perf_counter() - start, verification.max_relative_difference)
    states, one_core = front_states(family, rows)
    return {
        "instance": " ".join(options) or "defaults",
        "policies": len(rows),
        "states": states,
        "one_core_s": one_core,
        "floor_us": storm_floor(states),
        "search_s": result.timings["search"],
        "reference_s": timings[VerifyPath.REFERENCE][0],
        "batch_s": timings[VerifyPath.BATCH][0],
        "difference": max(timings[VerifyPath.REFERENCE][1], timings[VerifyPath.BATCH][1]),
    }


def front_states(family, rows: np.ndarray) -> tuple[int, float]:
    """The DTMC states Storm builds for ``rows`` by policy programs, and the seconds the
    whole path (writing, parsing, building and checking each batch) takes on one core."""
    with BatchStormEvaluator(family, workers=1) as fast:
        start = time.perf_counter()
        fast.evaluate(rows)
        return fast.states, time.perf_counter() - start


def counter_program(states: int) -> str:
    """The simplest DTMC of ``states`` states Storm's builder can be given: one counter, two
    successors a state, one command enabled in each."""
    last = states - 1
    return (
        "dtmc\nmodule counter\n"
        f"  i : [0..{last}] init 0;\n"
        f"  [] i < {last - 1} -> 0.3 : (i'=i+1) + 0.7 : (i'=i+2);\n"
        f"  [] i = {last - 1} -> (i'=i+1);\n"
        f"  [] i = {last} -> true;\n"
        "endmodule\n"
    )


def storm_floor(states: int, repeats: int = 3) -> float:
    """Microseconds a state that Storm's explicit builder needs for :func:`counter_program`
    in batches of :data:`BATCH_STATES` states (the best of ``repeats`` builds)."""
    import stormpy

    size = min(states, BATCH_STATES)
    program = prism.parse_program(counter_program(size), origin="the counter program")
    options = stormpy.BuilderOptions([])
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        model = stormpy.build_model[float](program, options=options)
        best = min(best, time.perf_counter() - start)
    return 1e6 * best / model.nr_states


def campaign_runs(count: int) -> list[dict]:
    case = load_registry().get("robot_grid")
    if (MAPS / "map_10.csv").is_file():
        instances = [[f"map={MAPS / f'map_{n}.csv'}"] for n in range(10, 10 + count)]
    else:
        instances = [["size=10", f"seed={n}"] for n in range(count)]
    rows = []
    for options in instances:
        start = time.perf_counter()
        prepared = prepare(case, case.options(options))
        result = run(prepared, SearchSettings(seed=1), workers=1, verify=True, bound="none")
        rows.append(
            {
                "instance": Path(options[0].split("=", 1)[1]).stem if options[0].startswith("map=") else options[1],
                "policies": result.verification.policies + result.verification.baselines,
                "run_s": time.perf_counter() - start,
                "verify_s": result.timings["verify"],
                "difference": result.verification.max_relative_difference,
            }
        )
        print(f"  {rows[-1]}", flush=True)
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policies", type=int, default=24, help="policies per instance (batch path)")
    parser.add_argument("--big", type=int, default=2, help="reference policies on the 50x50 map")
    parser.add_argument("--campaign", type=int, default=4, help="campaign runs to time")
    parser.add_argument("--skip-50", action="store_true", help="leave out the 50x50 map")
    args = parser.parse_args()

    map10 = [f"map={MAPS / 'map_10.csv'}"] if (MAPS / "map_10.csv").is_file() else ["size=10", "seed=0"]
    instances = [
        ("robot_grid map_10" if map10[0].startswith("map=") else "robot_grid 10x10", "robot_grid", map10, 12),
        ("robot_grid 20x20", "robot_grid", ["size=20", "seed=0"], 6),
        ("turtlebot (paper's world)", "turtlebot", [], 12),
        ("web_ids", "web_ids", [], 12),
        ("tas", "tas", [], 12),
    ]
    if not args.skip_50:
        instances.insert(2, ("robot_grid 50x50", "robot_grid", ["size=50", "seed=0"], args.big))
    print("## Per policy, one core\n", flush=True)
    rows = []
    for label, case, options, reference_count in instances:
        count = args.policies if "50x50" not in label else max(args.big, 8)
        rows.append(per_policy(label, case, options, count, min(reference_count, count)))
        print(f"  {rows[-1]}", flush=True)
    print()
    print(
        "| instance | decisions | DTMC states a policy | reference (ms/policy) | policy programs (ms/policy) | ratio | max difference | policies (reference / batch) |"
    )  # noqa: E501
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['instance']} | {r['decisions']} | {r['states']:.0f} | {r['reference_ms']:.1f} | {r['batch_ms']:.1f} "
            f"| {r['ratio']:.1f}x | {r['difference']:.1e} | {r['policies']} |"
        )

    print("\n## A whole front (parley run robot_grid, two workers)\n", flush=True)
    front = whole_front(map10)
    print(
        "| instance | front + baselines | search (s) | reference path (s) | policy programs (s) | ratio | max difference |"
    )  # noqa: E501
    print("|---|---|---|---|---|---|---|")
    print(
        f"| {front['instance'].split('/')[-1]} | {front['policies']} | {front['search_s']:.1f} | {front['reference_s']:.1f} "
        f"| {front['batch_s']:.1f} | {front['reference_s'] / front['batch_s']:.1f}x | {front['difference']:.1e} |"
    )

    print("\n## Storm's floor for that front\n", flush=True)
    states, floor_us = front["states"], front["floor_us"]
    actual_us = 1e6 * front["one_core_s"] / states
    print(
        "| DTMC states Storm builds | policy programs, one core (µs a state: write, parse, build, check) "
        "| the simplest program (µs a state, build only) | floor on two workers (s) | policy programs on two workers (s) |"
    )  # noqa: E501
    print("|---|---|---|---|---|")
    print(f"| {states:,} | {actual_us:.2f} | {floor_us:.2f} | {states * floor_us / 2e6:.1f} | {front['batch_s']:.1f} |")

    if args.campaign:
        print(f"\n## Campaign runs (one worker, paper's budget, verified), {args.campaign} maps\n", flush=True)
        runs = campaign_runs(args.campaign)
        print(
            "| map | front + baselines | run without verification (s) | verification (s) | verified / unverified time |"
        )
        print("|---|---|---|---|---|")
        for r in [*runs, None]:
            if r is None:
                r = {
                    "instance": "all",
                    **{k: sum(x[k] for x in runs) for k in ("policies", "run_s", "verify_s")},
                }
            rest = r["run_s"] - r["verify_s"]
            print(f"| {r['instance']} | {r['policies']} | {rest:.1f} | {r['verify_s']:.1f} | {r['run_s'] / rest:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
