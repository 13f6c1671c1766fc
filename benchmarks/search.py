"""How fast does each search configuration approach the best front? (Can it reach the same
fronts with a quarter of the budget?)

Every configuration of ``--algorithms`` searches every instance with ``--seeds`` seeds and a
budget of ``--budget`` evaluations (the archive of everything evaluated is the front, as in
``parley run``). Printed, per instance: the hypervolume of the archive after 250, 500, 1000,
2000 and 4000 evaluations as a fraction of the exact front's (where one is known) or of the
best known front's (the union of every run of this benchmark, a long run and, on the
published maps, the published EvoChecker fronts of all ten repetitions), median (min) over
seeds, with the median wall time of a run; then the same over all published maps and seeds,
and the evaluations at which each configuration's median reaches the ``paper``
configuration's median at the full budget. Same reference point throughout an instance (the
one ``parley run`` would take from the yardstick front and the baseline).

Instances:

- exact: web_ids and tas (their full families, 3.0 and 1.8 million policies, enumerated once
  on the quotient evaluator and cached in ``benchmarks/.cache``: about 10 minutes the first
  time), and a generated 4x4 map (intervals cut to 3) whose front branch and bound proves;
- published: ``--maps`` of the paper's maps (map_10, map_11, ...);
- generated: a 20x20 map (``--skip-20`` leaves it out) and a 50x50 one (``--with-50``), with
  ``--big-seeds`` seeds.

The figure (``--plot``, default docs/img/search.png) draws the median fraction against
evaluations, one panel per instance group. ``--json FILE`` keeps every run's curve.

``--no-enumeration`` measures web_ids and tas against the union of the runs (their own group,
"small families") instead of enumerating them: a comparison between configurations, not a
distance to the optimum.

Usage: python benchmarks/search.py [--seeds 10] [--algorithms paper,archive,sms] [--maps 10]
       [--budget 4000] [--big-seeds 3] [--skip-exact] [--no-enumeration] [--skip-20]
       [--with-50] [--jobs 2]
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import itertools
import json
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from parley_core import metrics
from parley_core.evaluate.cache import CachingEvaluator
from parley_core.evaluate.quotient import QuotientEvaluator
from parley_core.search import SearchSettings, search
from parley_core.testing import family as make_family

ROOT = Path(__file__).resolve().parent
REFERENCE = ROOT.parent.parent / "shared" / "reference" / "parley2024"
CACHE = ROOT / ".cache"
CHECKPOINTS = (250, 500, 1000, 2000, 4000)
LONG_RUN = 16_000
"""Evaluations of the long run that joins the best known front (configuration ``archive``)."""


def instances(args) -> list[dict]:
    found = []
    if not args.skip_exact:
        for case in ("web_ids", "tas"):
            if args.no_enumeration:
                found.append({"key": case, "group": "small families", "case": case, "options": []})
            else:
                found.append({"key": case, "group": "exact", "case": case, "options": [], "exact": "enumerate"})
        found += [
            {
                "key": "robot 4x4, intervals 1..3",
                "group": "exact",
                "case": "robot_grid",
                "options": ["size=4", "seed=1"],
                "width": 3,
                "exact": "branch and bound",
            },
        ]
    for i in range(10, 10 + args.maps):
        path = REFERENCE / "maps" / f"map_{i}.csv"
        found.append(
            {"key": f"map_{i}", "group": "published", "case": "robot_grid", "options": [f"map={path}"], "map": i}
        )
    if not args.skip_20:
        found.append({"key": "20x20", "group": "generated", "case": "robot_grid", "options": ["size=20", "seed=1"]})
    if args.with_50:
        found.append({"key": "50x50", "group": "generated", "case": "robot_grid", "options": ["size=50", "seed=1"]})
    return found


@functools.lru_cache(maxsize=2)
def _prepared(case: str, options: tuple[str, ...], width: int | None):
    family = make_family(case, list(options), width=width)
    return family, QuotientEvaluator(family, workers=1)


def one_run(instance: dict, algorithm: str, seed: int, budget: int) -> dict:
    """A search's archive values in evaluation order, with the time each was known.
    ``algorithm`` may name a budget of its own (``polished@1000``): configurations that
    split their budget between stages (``polished``) are measured at the budget they were
    given, not at a checkpoint of a longer run."""
    name, _, own = algorithm.partition("@")
    budget = min(budget, int(own)) if own else budget
    family, evaluator = _prepared(instance["case"], tuple(instance["options"]), instance.get("width"))
    archive = CachingEvaluator(evaluator, len(family.decisions), len(family.objectives))
    stamps: list[tuple[int, float]] = []
    start = time.perf_counter()

    def progress(_done: int) -> None:
        stamps.append((len(archive), time.perf_counter() - start))

    settings = SearchSettings(algorithm=name, generations=None, max_evaluations=budget, seed=seed)
    search(family, evaluator, settings, archive=archive, progress=progress)
    return {
        "instance": instance["key"],
        "algorithm": algorithm,
        "seed": seed,
        "budget": budget,
        "values": archive.values.tolist(),
        "stamps": stamps,
        "baseline": [list(map(float, row)) for row in evaluator.evaluate(_baseline_rows(family))],
    }


def _baseline_rows(family) -> np.ndarray:
    return np.array([p.values for p in family.baseline_policies()], dtype=np.int64).reshape(-1, len(family.decisions))


def _enumerate_chunk(case: str, options: tuple[str, ...], start: int, stop: int) -> np.ndarray:
    family, evaluator = _prepared(case, options, None)
    spaces = [np.array(d.service.values, dtype=np.int64) for d in family.decisions]
    index = np.arange(start, stop, dtype=np.int64)
    rows = np.empty((len(index), len(spaces)), dtype=np.int64)
    for j in range(len(spaces) - 1, -1, -1):  # the last decision varies fastest
        index, digit = np.divmod(index, len(spaces[j]))
        rows[:, j] = spaces[j][digit]
    values = evaluator.evaluate(rows)
    keep = metrics.front_candidates(values)
    values = values[keep]
    return values[metrics.nondominated(values, [o.direction for o in family.objectives])]


def exact_front(instance: dict, pool: ProcessPoolExecutor) -> np.ndarray:
    """The family's exact front (values), cached by case and options."""
    tag = hashlib.sha1(json.dumps([instance["case"], instance["options"], instance.get("width")]).encode()).hexdigest()
    path = CACHE / f"exact-{instance['case']}-{tag[:10]}.npy"
    if path.exists():
        return np.load(path)
    family = make_family(instance["case"], instance["options"], width=instance.get("width"))
    directions = [o.direction for o in family.objectives]
    start = time.perf_counter()
    if instance["exact"] == "enumerate":
        size = int(np.prod([len(d.service.values) for d in family.decisions]))
        step = 50_000
        futures = [
            pool.submit(_enumerate_chunk, instance["case"], tuple(instance["options"]), lo, min(size, lo + step))
            for lo in range(0, size, step)
        ]
        parts = [f.result() for f in futures]
        values = np.vstack(parts)
        front = values[metrics.nondominated(values, directions)]
        what = f"{size} policies enumerated"
    else:
        from parley_core.optimality.branch_and_bound import branch_and_bound
        from parley_core.quotient.coloring import build_quotient
        from parley_core.quotient.solver import QuotientSolver

        quotient = build_quotient(family)
        solver = QuotientSolver(quotient)
        result = branch_and_bound(family, quotient, lambda rows: np.array([solver.solve(r) for r in rows], dtype=float))
        front = result.values
        what = f"branch and bound, {result.nodes} nodes"
    print(f"exact front of {instance['key']}: {len(front)} points ({what}, {time.perf_counter() - start:.0f} s)")
    CACHE.mkdir(exist_ok=True)
    np.save(path, front)
    return front


def published_fronts(instance: dict) -> np.ndarray:
    rows = []
    for path in sorted((REFERENCE / "fronts").glob(f"map_{instance['map']}_rep*.front.tsv")):
        rows += [list(map(float, line.split("\t"))) for line in path.read_text().splitlines()[1:] if line.strip()]
    return np.array(rows, dtype=float).reshape(-1, 2)


def fraction_curve(values: np.ndarray, directions, reference, best: float, budget: int, own: int) -> list[float]:
    """The fraction after each checkpoint up to ``budget``; NaN past the run's ``own`` budget
    (a run that stopped early, having nothing left to try, keeps its last value)."""
    return [
        metrics.hypervolume(values[:k], directions, reference) / best if k <= own else float("nan")
        for k in CHECKPOINTS
        if k <= budget
    ]


def _cell(fractions: np.ndarray) -> str:
    """Median (min) of a checkpoint's fractions; a dash past a configuration's own budget."""
    return "-" if np.isnan(fractions).all() else f"{np.median(fractions):.4f} ({fractions.min():.4f})"


def seconds_at(stamps: list, k: int) -> float:
    return next((t for n, t in stamps if n >= k), stamps[-1][1] if stamps else float("nan"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--big-seeds", type=int, default=3)
    parser.add_argument("--algorithms", default="paper,archive,sms")
    parser.add_argument("--maps", type=int, default=10)
    parser.add_argument("--budget", type=int, default=4000)
    parser.add_argument("--skip-exact", action="store_true")
    parser.add_argument(
        "--no-enumeration",
        action="store_true",
        help="measure web_ids and tas against the best known front (the union of the runs) instead of enumerating them",
    )
    parser.add_argument("--skip-20", action="store_true")
    parser.add_argument("--with-50", action="store_true")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--long", type=int, default=LONG_RUN, help="evaluations of the long run (0: none)")
    parser.add_argument("--plot", type=Path, default=ROOT.parent / "docs" / "img" / "search.png")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--replot", type=Path, default=None, help="only draw the figure from a --json file")
    args = parser.parse_args()
    if args.replot:
        replot(args.replot, args.plot)
        return
    algorithms = args.algorithms.split(",")
    chosen = instances(args)
    checkpoints = [k for k in CHECKPOINTS if k <= args.budget]
    started = time.perf_counter()
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(args.jobs, mp_context=context) as pool:
        yardsticks: dict[str, np.ndarray] = {}
        for instance in chosen:
            if instance.get("exact"):
                yardsticks[instance["key"]] = exact_front(instance, pool)
        jobs = []
        for instance in chosen:
            seeds = args.big_seeds if instance["group"] == "generated" else args.seeds
            for algorithm, seed in itertools.product(algorithms, range(1, seeds + 1)):
                jobs.append(pool.submit(one_run, instance, algorithm, seed, args.budget))
            if not instance.get("exact") and args.long:
                jobs.append(pool.submit(one_run, instance, "archive", 0, args.long))
        runs = []
        for done, job in enumerate(jobs, 1):
            runs.append(job.result())
            if done % 20 == 0 or done == len(jobs):
                print(f"  {done}/{len(jobs)} runs, {time.perf_counter() - started:.0f} s", flush=True)

    table: dict[str, dict[str, list]] = {}
    for instance in chosen:
        key = instance["key"]
        family = make_family(instance["case"], instance["options"], width=instance.get("width"))
        directions = [o.direction for o in family.objectives]
        mine = [r for r in runs if r["instance"] == key]
        baseline = np.array(mine[0]["baseline"])
        if key in yardsticks:
            best_front, label = yardsticks[key], "exact"
        else:
            union = [np.array(r["values"]) for r in mine]
            if instance["group"] == "published":
                union.append(published_fronts(instance))
            stacked = np.vstack(union)
            stacked = stacked[metrics.front_candidates(stacked)]
            best_front, label = stacked[metrics.nondominated(stacked, directions)], "best known"
        reference = metrics.reference_point(family.objectives, best_front, baseline)
        best = metrics.hypervolume(best_front, directions, reference)
        print(
            f"\n### {key} ({label} front: {len(best_front)} points)\n\n"
            "| configuration | " + " | ".join(str(k) for k in checkpoints) + " | seconds (median) |"
        )
        print("|---|" + "---|" * (len(checkpoints) + 1))
        table[key] = {}
        for algorithm in algorithms:
            curves = np.array(
                [
                    fraction_curve(
                        np.array(r["values"]), directions, reference, best, args.budget, r.get("budget", args.budget)
                    )
                    for r in mine
                    if r["algorithm"] == algorithm and r["seed"] > 0
                ]
            )
            seconds = [seconds_at(r["stamps"], args.budget) for r in mine if r["algorithm"] == algorithm and r["seed"]]
            table[key][algorithm] = curves.tolist()
            cells = [_cell(curves[:, i]) for i in range(len(checkpoints))]
            print(f"| {algorithm} | " + " | ".join(cells) + f" | {np.median(seconds):.1f} |")

    print("\n### every published map and seed: median (min) fraction\n")
    print("| configuration | " + " | ".join(str(k) for k in checkpoints) + " | reaches paper's final median at |")
    print("|---|" + "---|" * (len(checkpoints) + 1))
    published = [i["key"] for i in chosen if i["group"] == "published"]
    medians = {}
    for algorithm in algorithms:
        if not published:
            break
        curves = np.vstack([table[k][algorithm] for k in published])
        medians[algorithm] = np.median(curves, axis=0)
    for algorithm, median in medians.items():
        target = medians.get("paper", median)[-1]
        reach = next((str(k) for k, m in zip(checkpoints, median) if m >= target), "not within the budget")
        curves = np.vstack([table[k][algorithm] for k in published])
        cells = [_cell(curves[:, i]) for i in range(len(checkpoints))]
        print(f"| {algorithm} | " + " | ".join(cells) + f" | {reach} |")
    print(f"\ntotal {time.perf_counter() - started:.0f} s")

    groups_of = {i["key"]: i["group"] for i in chosen}
    if args.json:
        args.json.write_text(json.dumps({"checkpoints": checkpoints, "fractions": table, "groups": groups_of}))
    if args.plot:
        plot(args.plot, checkpoints, table, groups_of, algorithms)


def plot(path: Path, checkpoints: list[int], table: dict, groups_of: dict[str, str], algorithms: list[str]) -> None:
    """Median fraction against evaluations, one panel per instance group."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = sorted(set(groups_of.values()))
    fig, axes = plt.subplots(1, len(groups), figsize=(4.5 * len(groups), 3.6), squeeze=False)
    for ax, group in zip(axes[0], groups):
        keys = [k for k, g in groups_of.items() if g == group]
        for algorithm in algorithms:
            curves = np.vstack([table[k][algorithm] for k in keys])
            ax.plot(checkpoints, np.median(curves, axis=0), marker="o", label=algorithm)
        ax.set_xscale("log")
        ax.minorticks_off()
        ax.set_xticks(checkpoints, [str(k) for k in checkpoints])
        ax.set_title(f"{group} ({len(keys)} instance{'s' if len(keys) > 1 else ''})")
        ax.set_xlabel("evaluations")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("hypervolume / exact or best known")
    axes[0][0].legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    print(f"figure: {path}")


def replot(source: Path, path: Path) -> None:
    """Draw the figure again from a ``--json`` file."""
    data = json.loads(source.read_text())
    table = data["fractions"]
    groups_of = data["groups"]
    plot(path, data["checkpoints"], table, groups_of, list(next(iter(table.values()))))


if __name__ == "__main__":
    main()
