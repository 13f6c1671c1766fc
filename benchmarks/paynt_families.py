"""Parley against PAYNT on PAYNT's own families (``../shared/foreign-models``):

- dpm: dynamic power management, 16 holes of 3 values, 43 million policies; PAYNT's query
  (``hard.props``) is the least expected power with at most 1 expected lost high-priority
  request: ``R{"power"}min`` subject to ``R{"lostH"}<=1``;
- herman: Herman's self-stabilising ring with a family of coin biases, 4 holes of 25 values
  and 3 of 2, 3.1 million policies; PAYNT's query is the least expected number of steps to
  stabilise, ``R{"steps"}min``.

PAYNT answers one query at a time. Parley computes the whole Pareto front of the family's
two objectives (``dpm.pctl``: power and lostH, both min; ``herman.pctl``: steps min and the
probability to stabilise within 30 steps, max) and a certified outer bound. Both answers to
PAYNT's query come out of that:

- the least value of a Storm-verified front policy that meets PAYNT's constraint (an upper
  limit of the optimum: a policy that reaches it);
- the least value of a bound point that meets it: every policy is weakly dominated by a
  bound point, so no policy that meets the constraint does better (a lower limit).

When branch and bound finishes, the front is the family's whole Pareto front and the two
limits are equal. Printed, per family: one row per configuration with its wall time, the
front's size, the certified gap of the whole front, and the interval [lower, upper] it gives
PAYNT's optimum; then PAYNT's own run with the same time limit (the best value it found, the
share of the family it explored and its own synthesis time), if ``--paynt PYTHON`` names an
interpreter with PAYNT installed (PAYNT 0.5 is on PyPI and pins stormpy 2.0.0: ``python3
-m venv /tmp/paynt && /tmp/paynt/bin/pip install paynt``). PAYNT is not a dependency of
parley and none of its code is used here. PAYNT's time limit counts its parsing (about 40 s
on herman), its synthesis time does not.

With ``--exact`` a third parley run computes the whole front without a time limit, and PAYNT
then gets as long as that took (if longer than ``--seconds``): the question is whether the
whole front takes less time than PAYNT needs for its one optimum.

Usage: python benchmarks/paynt_families.py [--family dpm herman] [--seconds 600]
       [--paynt /tmp/paynt/bin/python] [--exact]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from attrs import frozen

ROOT = Path(__file__).resolve().parents[1]
FOREIGN = ROOT.parent / "shared" / "foreign-models"


@frozen
class Query:
    """A PAYNT family, its two objectives for parley, and PAYNT's single-objective query:
    minimise ``objective`` subject to ``limited <= limit`` (``limited`` None: no constraint)."""

    folder: str
    model: str
    objective: str
    limited: str | None
    limit: float
    policies: int


FAMILIES = {
    "dpm": Query("paynt-dpm", "dpm.prism", "power", "lostH", 1.0, 3**16),
    "herman": Query("paynt-herman", "herman.prism", "steps", None, 0.0, 25**4 * 2**3),
}


def feasible(row: dict[str, float], query: Query) -> bool:
    return query.limited is None or row[query.limited] <= query.limit


def parley_run(query: Query, out: Path, extra: list[str]) -> dict:
    folder = FOREIGN / query.folder
    decisions = (folder / "decisions.txt").read_text().split()
    props = folder / query.model.replace(".prism", ".pctl")
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "parley_core", "synthesize", str(folder / query.model), "--props", str(props)]
        + decisions
        + ["--out", str(out), "--force"]
        + extra,
        capture_output=True,
        text=True,
        check=False,
    )
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"parley failed: {done.stderr.strip().splitlines()[-1:]}")
    summary = json.loads((out / "summary.json").read_text())

    def rows(name: str) -> list[dict[str, float]]:
        return [{k: float(v) for k, v in r.items() if k != "policy"} for r in csv.DictReader(open(out / name))]

    front, bound = rows("front.csv"), rows("bound.csv")
    return {
        "seconds": seconds,
        "front": len(front),
        "gap": summary["optimality"]["gap"],
        "exact": summary["optimality"]["exact"],
        "lower": min((r[query.objective] for r in bound if feasible(r, query)), default=float("inf")),
        "upper": min((r[query.objective] for r in front if feasible(r, query)), default=float("inf")),
        "verified": summary["verification"]["by"],
    }


def paynt_run(query: Query, python: str, seconds: int) -> dict:
    with tempfile.TemporaryDirectory() as scratch:
        project = Path(scratch) / query.folder
        shutil.copytree(FOREIGN / query.folder, project)
        start = time.perf_counter()
        done = subprocess.run(
            [python, "-m", "paynt", str(project), "--sketch", "sketch.templ", "--props", "hard.props"]
            + ["--timeout", str(seconds)],
            capture_output=True,
            text=True,
            check=False,
        )
        wall = time.perf_counter() - start
    text = done.stdout + done.stderr
    explored = re.findall(r"explored: ([0-9.]+) %", text) or re.findall(r"progress ([0-9.]+)%", text)
    optimum = re.findall(r"optimum: ([0-9.]+)", text) or re.findall(r"opt = ([0-9.]+)", text)
    synthesis = re.findall(r"synthesis time: ([0-9.]+) s", text)
    return {
        "seconds": wall,
        "explored": float(explored[-1]) if explored else None,
        "best": float(optimum[-1]) if optimum else None,
        "synthesis": float(synthesis[-1]) if synthesis else None,
        "aborted": "time limit reached" in text,
        "returncode": done.returncode,
    }


def report(name: str, query: Query, seconds: int, paynt: str | None, exact: bool = False) -> None:
    folder = FOREIGN / query.folder
    if not folder.is_dir():
        raise SystemExit(f"{folder} is missing: this benchmark reads PAYNT's families from ../shared/foreign-models")
    rows = []
    runs: list[tuple[str, list[str]]] = [
        ("parley synthesize (defaults)", []),
        (
            f"parley synthesize --bound refine --bound-time {seconds}",
            ["--bound", "refine", "--bound-time", str(seconds)],
        ),
    ]
    if exact:
        runs.append(("parley synthesize --exact", ["--exact"]))
    with tempfile.TemporaryDirectory() as scratch:
        for label, extra in runs:
            rows.append((label, parley_run(query, Path(scratch) / label.split()[-1], extra)))
    if exact and rows[-1][1]["exact"]:
        # PAYNT gets as long as the exact front took: has it found its one optimum by then?
        seconds = max(seconds, math.ceil(rows[-1][1]["seconds"]))
    constraint = f" with {query.limited} <= {query.limit:g}" if query.limited else ""
    print(f"\n{name}, {query.policies:,} policies; PAYNT's query: least {query.objective}{constraint}\n")
    print("| run | wall (s) | front | certified gap of the front | optimum of PAYNT's query lies in |")
    print("|---|---|---|---|---|")
    for label, r in rows:
        print(
            f"| {label} | {r['seconds']:.0f} | {r['front']} (values: {r['verified']}) | "
            f"{100 * r['gap']:.1f} %{' (exact)' if r['exact'] else ''} | [{r['lower']:.4f}, {r['upper']:.4f}] |"
        )
    if paynt:
        p = paynt_run(query, paynt, seconds)
        state = "stopped by its time limit" if p["aborted"] else "finished"
        print(
            f"| PAYNT 0.5, ar, --timeout {seconds} | {p['seconds']:.0f} ({state}; synthesis {p['synthesis']} s) | - | - "
            f"| best found {p['best']}, {p['explored']} % of the family explored |"
        )
    else:
        print("\n(PAYNT not run: give --paynt PYTHON)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--family", nargs="+", choices=sorted(FAMILIES), default=sorted(FAMILIES))
    parser.add_argument("--seconds", type=int, default=600, help="branch and bound's and PAYNT's time limit")
    parser.add_argument("--paynt", default=None, help="a Python interpreter with PAYNT installed")
    parser.add_argument(
        "--exact",
        action="store_true",
        help="also run parley synthesize --exact (no time limit); PAYNT then gets as long as it took, if longer",
    )
    args = parser.parse_args()
    for name in args.family:
        report(name, FAMILIES[name], args.seconds, args.paynt, args.exact)


if __name__ == "__main__":
    main()
