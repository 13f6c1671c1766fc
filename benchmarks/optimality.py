"""How good are Parley's fronts? Exact fronts by branch and bound, certified gaps, NSGA-II
against the exact front.

Three tables, printed as Markdown:

1. exact fronts: per family its size, branch and bound's wall time, front size, nodes
   explored and pruned, policies evaluated, and exhaustive enumeration's time and front for
   comparison (both on the quotient evaluator, one process);
2. certified gaps: per case study (its defaults) the gap of the default run's front to the
   ideal-point bound, to the Pareto outer approximation (the default) and to the bound
   branch and bound leaves after ``--bound-time`` seconds (``parley run CASE --bound
   refine``);
3. NSGA-II (the default search: population 100, 40 generations) against the exact fronts of
   table 1, over ``--seeds`` seeds: the fraction of the exact hypervolume reached (same
   reference point), min / median / max.

Between 1 and 2, ``parley exact`` on web_ids and tas with their defaults (2 workers, every
front value Storm's), against enumerating every policy on the quotient (``--no-enumeration``
leaves that out: about 20 s for web_ids and 80 s for tas), and NSGA-II (as in 3) against
those exact fronts.

After 2, robot_grid's full families (generated 5x5 and 6x6 maps, the published map_10; intervals
1..10): the gap branch and bound leaves after ``--robot-time`` seconds (10 minutes by default;
``--only-robot`` prints only this table).

Finally (``--only-methods SECONDS``, alone), the bound methods side by side on the same
fronts: ideal point, Pareto outer approximation, belief (POMDP) ideal point, and SECONDS of
branch and bound splitting in the widest decision or where the bound's best scheduler is
inconsistent (PAYNT's refinement), on robot_grid's full families and tas; and
(``--only-votes SECONDS``, alone) the time to web_ids' and tas' exact fronts split either
way, in alternating runs.

Usage: python benchmarks/optimality.py [--seeds 10] [--bound-time 60] [--skip-gaps | --only-gaps]
       [--skip-full | --only-full] [--no-enumeration] [--time-limit 600]
       [--robot-time 600 | --only-robot] [--only-methods SECONDS] [--only-votes SECONDS]
"""

from __future__ import annotations

import argparse
import itertools
import math
import time
from collections import deque
from pathlib import Path

import numpy as np

from parley_core import metrics
from parley_core.boxes import Box
from parley_core.evaluate.quotient import QuotientEvaluator
from parley_core.family.prepare import Prepared, prepare
from parley_core.optimality.branch_and_bound import branch_and_bound
from parley_core.pipeline import run
from parley_core.plugin.manager import load_registry
from parley_core.quotient.coloring import build_quotient
from parley_core.quotient.solver import QuotientSolver
from parley_core.search import SearchSettings
from parley_core.testing import family

EXACT = [
    ("tas, intervals 0..3", "tas", ["rounds=6", "max_interval=3"], None),
    ("web_ids, intervals cut to 4", "web_ids", ["rounds=6"], 4),
    ("robot_grid 3x3, intervals cut to 3", "robot_grid", ["size=3", "seed=2"], 3),
    ("robot_grid 4x4, intervals cut to 3", "robot_grid", ["size=4", "seed=1"], 3),
    ("robot_grid 4x4, intervals cut to 4", "robot_grid", ["size=4", "seed=1"], 4),
]
FULL = [
    ("web_ids (defaults)", "web_ids", []),
    ("tas (defaults)", "tas", []),
]
REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference" / "parley2024"
GAPS = [
    ("robot_grid (10x10)", "robot_grid", []),
    ("robot_grid 5x5", "robot_grid", ["size=5", "seed=1"]),
    ("web_ids", "web_ids", []),
    ("tas", "tas", []),
    ("turtlebot", "turtlebot", []),
    (
        "turtlebot, the paper's motions",
        "turtlebot",
        [f"model={REFERENCE / 'models' / 'turtlebot' / 'model.prism'}"],
    ),
]
ROBOT = [
    ("robot_grid 5x5 (intervals 1..10)", ["size=5", "seed=1"]),
    ("robot_grid 6x6 (intervals 1..10)", ["size=6", "seed=1"]),
    ("robot_grid, published map_10", [f"map={REFERENCE / 'maps' / 'map_10.csv'}"]),
]


def prepared(name: str, options: list[str], width: int | None) -> Prepared:
    case = load_registry().get(name)
    small = family(name, options, width=width)
    return Prepared(case=case, options=case.options(options), system=small.system, family=small)


def exact_table(seeds: int) -> None:
    print(
        "| family | policies | branch and bound (s) | front | nodes | pruned | evaluated | enumeration (s) | same front |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    fronts = []
    for label, name, options, width in EXACT:
        prep = prepared(name, options, width)
        fam = prep.family
        quotient = build_quotient(fam)
        solver = QuotientSolver(quotient)

        def evaluate(rows, solver=solver):
            return np.array([solver.solve(row) for row in rows], dtype=float)

        size = int(np.prod([len(d.service.values) for d in fam.decisions]))
        start = time.perf_counter()
        result = branch_and_bound(fam, quotient, evaluate)
        seconds = time.perf_counter() - start
        if size <= 50_000:
            start = time.perf_counter()
            rows = np.array(list(itertools.product(*(d.service.values for d in fam.decisions))), dtype=np.int64)
            values = evaluate(rows)
            enumeration = time.perf_counter() - start
            missed, foreign = metrics.front_disagreements(result.values, values, [o.direction for o in fam.objectives])
            same = (
                "yes"
                if not len(missed) and not len(foreign)
                else f"NO ({len(missed)} missed, {len(foreign)} not on it)"
            )
            enum_text = f"{enumeration:.1f}"
        else:
            same, enum_text = "not enumerated", "-"
        print(
            f"| {label} | {size} | {seconds:.1f} | {len(result.values)} | {result.nodes} | {result.pruned} | "
            f"{result.evaluated} | {enum_text} | {same} |"
        )
        fronts.append((label, prep, result))
    nsga_table([(label, prep, result.values) for label, prep, result in fronts], seeds, workers=1)


def nsga_table(fronts: list[tuple[str, Prepared, np.ndarray]], seeds: int, workers: int) -> None:
    """NSGA-II with the paper's budget against exact fronts (label, family, the exact front's
    values), ``seeds`` seeds: the fraction of the exact hypervolume its front reaches."""
    print()
    print(f"NSGA-II (default search) against the exact front, {seeds} seeds: fraction of the exact hypervolume")
    print()
    print("| family | min | median | max | evaluations (median) |")
    print("|---|---|---|---|---|")
    for label, prep, exact in fronts:
        directions = [o.direction for o in prep.family.objectives]
        fractions, evaluations = [], []
        for seed in range(seeds):
            found = run(prep, SearchSettings(seed=seed), verify=False, bound="none", workers=workers)
            reference = metrics.reference_point(prep.family.objectives, exact, np.array(found.baseline.values))
            exact_hv = metrics.hypervolume(exact, directions, reference)
            fractions.append(metrics.hypervolume(np.array(found.front.values), directions, reference) / exact_hv)
            evaluations.append(found.search.evaluations)
        print(
            f"| {label} | {min(fractions):.5f} | {np.median(fractions):.5f} | {max(fractions):.5f} | "
            f"{int(np.median(evaluations))} |",
            flush=True,
        )


def enumerated_front(prep: Prepared, workers: int) -> tuple[np.ndarray, float]:
    """Every policy of the family solved on the quotient (in boxes over ``workers``), each
    box cut to its own front: values that hold the family's whole front, and the seconds."""
    fam = prep.family
    sizes = [len(d.service.values) for d in fam.decisions]
    signs = -np.array([o.direction.sign for o in fam.objectives])
    # boxes: the leading decisions enumerated, the rest whole (at most 65,536 policies a box)
    split, rest = 0, int(np.prod(sizes))
    while split < len(sizes) and rest > 65_536:
        rest //= sizes[split]
        split += 1
    boxes = []
    for lead in itertools.product(*(range(n) for n in sizes[:split])):
        lo = np.array([*lead, *([0] * (len(sizes) - split))], dtype=np.int64)
        hi = np.array([*lead, *(n - 1 for n in sizes[split:])], dtype=np.int64)
        boxes.append(Box(lo, hi))
    start = time.perf_counter()
    kept = []
    with QuotientEvaluator(fam, workers=workers) as engine:
        inflight = deque()  # two batches at a time keep the workers busy
        for first in range(0, len(boxes), 16):
            inflight.append(engine.submit_box_fronts(boxes[first : first + 16], signs))
            if len(inflight) > 2:
                kept.append(inflight.popleft().result().values)
        kept.extend(batch.result().values for batch in inflight)
    return np.vstack(kept), time.perf_counter() - start


def full_table(time_limit: float, enumerate_too: bool, seeds: int) -> None:
    """``parley exact`` on the case studies' default families (2 workers), against exhaustive
    enumeration on the quotient; then NSGA-II against those exact fronts."""
    print()
    print(
        "| family | policies | parley exact (s) | exact | front (Storm) | nodes | pruned | evaluated "
        "| enumeration (s) | µs a policy a core | exact / enumeration | same front |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    exact = []
    for label, name, options in FULL:
        case = load_registry().get(name)
        prep = prepare(case, case.options(options))
        size = int(np.prod([len(d.service.values) for d in prep.family.decisions]))
        start = time.perf_counter()
        result = run(prep, SearchSettings(seed=1), bound="refine", bound_time=time_limit)
        seconds = time.perf_counter() - start
        assert result.bound is not None
        counts = result.bound.search
        front = np.array(result.front.values)
        same, enum_text, each, ratio = "not enumerated", "-", "-", "-"
        if enumerate_too:
            values, enumeration = enumerated_front(prep, workers=2)
            missed, foreign = metrics.front_disagreements(front, values, [o.direction for o in prep.family.objectives])
            same = (
                "yes"
                if not len(missed) and not len(foreign)
                else f"NO ({len(missed)} missed, {len(foreign)} not on it)"
            )
            enum_text, ratio = f"{enumeration:.1f}", f"{seconds / enumeration:.2f}"
            each = f"{enumeration * 2 / size * 1e6:.0f}"
        print(
            f"| {label} | {size} | {seconds:.1f} | {'yes' if result.bound.exact else 'no'} | {len(front)} | "
            f"{counts.nodes if counts else '-'} | {counts.pruned if counts else '-'} | {counts.evaluated if counts else '-'} | "
            f"{enum_text} | {each} | {ratio} | {same} |",
            flush=True,
        )
        if result.bound.exact:
            exact.append((label, prep, front))
    nsga_table(exact, seeds, workers=2)


def gap_table(bound_time: float) -> None:
    print()
    print(
        f"| case study | ideal-point gap | Pareto outer gap | bound (s) | refined gap ({bound_time:g} s) "
        "| nodes | pruned | evaluated |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for label, name, options in GAPS:
        case = load_registry().get(name)
        prep = prepare(case, case.options(options))
        row = [label]
        for mode in ("ideal", "pareto", "refine"):
            result = run(prep, SearchSettings(seed=1), bound=mode, bound_time=bound_time, verify=False)
            assert result.bound is not None
            directions = [o.direction for o in prep.family.objectives]
            front_hv = metrics.hypervolume(np.array(result.front.values), directions, result.reference)
            bound_hv = result.bound.hypervolume(result.reference)
            gap = (bound_hv - front_hv) / bound_hv if np.isfinite(bound_hv) and bound_hv > 0 else float("nan")
            row.append(f"{100 * gap:.2f}%" + (" (exact)" if result.bound.exact else ""))
            if mode == "pareto":
                row.append(f"{result.bound.seconds:.1f}")
            elif mode == "refine":
                counts = result.bound.search
                assert counts is not None
                row += [str(counts.nodes), str(counts.pruned), str(counts.evaluated)]
        print("| " + " | ".join(row) + " |", flush=True)


def robot_table(seconds: float) -> None:
    """robot_grid's full families: branch and bound after the default search for at most
    ``seconds`` (``parley run robot_grid --bound refine --bound-time S``), the gap it leaves
    against the Pareto outer approximation's."""
    print()
    print(
        f"| family | decisions | policies | Pareto outer gap | gap after {seconds:g} s of branch and bound "
        "| exact | nodes | pruned | evaluated | wall (s) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for label, options in ROBOT:
        case = load_registry().get("robot_grid")
        prep = prepare(case, case.options(options))
        directions = [o.direction for o in prep.family.objectives]
        size = math.prod(len(d.service.values) for d in prep.family.decisions)
        gaps = []
        for mode in ("pareto", "refine"):
            start = time.perf_counter()
            result = run(prep, SearchSettings(seed=1), bound=mode, bound_time=seconds, verify=False)
            wall = time.perf_counter() - start
            assert result.bound is not None
            front_hv = metrics.hypervolume(np.array(result.front.values), directions, result.reference)
            bound_hv = result.bound.hypervolume(result.reference)
            gaps.append(f"{100 * (bound_hv - front_hv) / bound_hv:.2f}%")
        counts = result.bound.search
        assert counts is not None
        print(
            f"| {label} | {len(prep.family.decisions)} | {size:.2e} | {gaps[0]} | {gaps[1]} | "
            f"{'yes' if result.bound.exact else 'no'} | {counts.nodes} | {counts.pruned} | "
            f"{counts.evaluated} | {wall:.0f} |",
            flush=True,
        )


METHODS = [
    *ROBOT,
    ("tas (defaults)", None),
]


def _gap(bound, front: np.ndarray, directions, reference) -> str:
    """The gap as a percentage (a gap that rounds to zero, of either sign, is 0.00%)."""
    bound_hv = bound.hypervolume(reference)
    text = f"{100 * (bound_hv - metrics.hypervolume(front, directions, reference)) / bound_hv:.2f}%"
    return "0.00%" if text == "-0.00%" else text


def methods_table(seconds: float) -> None:
    """The bound methods side by side on the same front (the default search's, seed 1, on the
    quotient evaluator): the ideal point, the Pareto outer approximation, the ideal point of
    the relaxation read as a POMDP (Storm's belief exploration, 60 s a query), and
    ``seconds`` of branch and bound from the Pareto bound, splitting either where the bound's
    schedulers disagree (PAYNT's inconsistent holes; for step-bounded weighted sums the best
    scheduler of the node's first new sum votes by its expected steps) or, without a
    scheduler, in the widest decision. The gap is the share of the bound's hypervolume the
    front (with branch and bound's finds) does not cover, at the run's reference point."""
    from parley_core.optimality import after_search
    from parley_core.optimality.bound import intersect, refined_bound

    print()
    print(
        f"| family | ideal point | Pareto outer | belief (POMDP) | branch and bound {seconds:g} s, widest decision "
        f"| branch and bound {seconds:g} s, scheduler votes |"
    )
    print("|---|---|---|---|---|---|")
    for label, options in METHODS:
        name = "tas" if options is None else "robot_grid"
        case = load_registry().get(name)
        prep = prepare(case, case.options(options or []))
        fam = prep.family
        directions = [o.direction for o in fam.objectives]
        result = run(prep, SearchSettings(seed=1), bound="none", verify=False)
        front = np.array(result.front.values)
        policies = np.array([p.values for p in result.front.policies], dtype=np.int64)
        cells = []
        for method in ("ideal", "pareto", "belief"):
            began = time.perf_counter()
            found, bounds = after_search.outer(fam, None, method, seconds=60.0)
            cells.append(
                f"{100 * _gap(found, front, directions, result.reference):.2f}% ({time.perf_counter() - began:.0f} s)"
            )
            if method == "pareto":
                pareto, relaxed = found, bounds
        quotient = relaxed.quotient
        engine = QuotientEvaluator(fam, quotient=quotient, workers=2)
        try:
            for vote in (False, True):
                began = time.perf_counter()
                exact = branch_and_bound(
                    fam, quotient, engine.evaluate, seeds=engine.box_seeds(policies, front), time_limit=seconds,
                    root_cuts=pareto.cuts, bounds=relaxed, fronts=engine.submit_box_fronts,
                    whole=engine.walks_boxes(), sums_vote=vote,
                )  # fmt: skip
                refined = refined_bound(fam, exact)
                bound = refined if refined.exact else intersect(pareto, refined, "within the Pareto bound")
                both = np.vstack([front, exact.values])
                mark = " exact" if refined.exact else ""
                cells.append(
                    f"{_gap(bound, both, directions, result.reference)}{mark} "
                    f"({time.perf_counter() - began:.0f} s; {exact.nodes} nodes, {exact.pruned} pruned)"
                )
        finally:
            engine.close()
        print(f"| {label} | " + " | ".join(cells) + " |", flush=True)


def votes_table(seconds: float, rounds: int) -> None:
    """Branch and bound from the default search's front (2 workers) on web_ids and tas, split
    by width or where the weighted sums' best schedulers disagree, in alternating runs of at
    most ``seconds``: time to the exact front, nodes, pruned, policies evaluated."""
    from parley_core.optimality import after_search

    print()
    print("| case study | split by | exact | seconds | nodes | pruned | evaluated |")
    print("|---|---|---|---|---|---|---|")
    for name in ("web_ids", "tas"):
        case = load_registry().get(name)
        prep = prepare(case, case.options([]))
        fam = prep.family
        result = run(prep, SearchSettings(seed=1), bound="none", verify=False)
        front = np.array(result.front.values)
        policies = np.array([p.values for p in result.front.policies], dtype=np.int64)
        pareto, relaxed = after_search.outer(fam, None, "pareto")
        engine = QuotientEvaluator(fam, quotient=relaxed.quotient, workers=2)
        try:
            for vote in [False, True] * rounds:
                began = time.perf_counter()
                exact = branch_and_bound(
                    fam, relaxed.quotient, engine.evaluate, seeds=engine.box_seeds(policies, front),
                    time_limit=seconds, root_cuts=pareto.cuts, bounds=relaxed, fronts=engine.submit_box_fronts,
                    whole=engine.walks_boxes(), sums_vote=vote,
                )  # fmt: skip
                print(
                    f"| {name} | {'scheduler votes' if vote else 'width'} | {'yes' if exact.exact else 'no'} | "
                    f"{time.perf_counter() - began:.1f} | {exact.nodes} | {exact.pruned} | {exact.evaluated} |",
                    flush=True,
                )
        finally:
            engine.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--bound-time", type=float, default=60.0)
    parser.add_argument("--skip-gaps", action="store_true")
    parser.add_argument("--only-gaps", action="store_true")
    parser.add_argument("--skip-full", action="store_true", help="leave out parley exact on web_ids and tas")
    parser.add_argument("--only-full", action="store_true")
    parser.add_argument("--no-enumeration", action="store_true", help="do not enumerate the full families")
    parser.add_argument("--time-limit", type=float, default=600.0, help="parley exact's limit on the full families")
    parser.add_argument(
        "--robot-time", type=float, default=600.0, help="branch and bound's budget on robot_grid's full families"
    )
    parser.add_argument("--only-robot", action="store_true", help="only the robot_grid table")
    parser.add_argument(
        "--only-methods",
        type=float,
        metavar="SECONDS",
        help="only the bound methods side by side (branch and bound's budget)",
    )
    parser.add_argument(
        "--only-votes", type=float, metavar="SECONDS", help="only web_ids and tas split by width against by votes"
    )
    args = parser.parse_args()
    if args.only_votes:
        votes_table(args.only_votes, 2)
        return 0
    if args.only_methods:
        methods_table(args.only_methods)
        return 0
    if args.only_robot:
        robot_table(args.robot_time)
        return 0
    if args.only_full:
        full_table(args.time_limit, not args.no_enumeration, args.seeds)
        return 0
    if not args.only_gaps:
        exact_table(args.seeds)
    if not args.only_gaps and not args.skip_full:
        full_table(args.time_limit, not args.no_enumeration, args.seeds)
    if not args.skip_gaps:
        gap_table(args.bound_time)
        robot_table(args.robot_time)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
