"""Parley against PAYNT on PAYNT's own family: dpm (dynamic power management, 16 holes of 3
values, 43 million policies; ``../shared/foreign-models/paynt-dpm``).

PAYNT answers one query at a time: the least expected power with at most 1 expected lost
high-priority request (``hard.props``: ``R{"power"}min`` subject to ``R{"lostH"}<=1``).
Parley computes the whole (power, lostH) Pareto front and a certified outer bound of the
family. Both answers to PAYNT's query come out of that:

- the least power of a Storm-verified front policy with lostH <= 1 (an upper limit of the
  optimum: a policy that reaches it);
- the least power of a bound point with lostH <= 1: every policy is weakly dominated by a
  bound point, so no policy with lostH <= 1 has less power (a lower limit of the optimum).

Printed: one row per configuration with its wall time, the front's size, the certified gap
of the whole front, and the interval [lower, upper] it gives PAYNT's optimum; then PAYNT's
own run for the same time (the best value it found and the share of the family it
explored), if ``--paynt PYTHON`` names an interpreter with PAYNT installed (PAYNT 0.5 is
on PyPI and pins stormpy 2.0.0: ``python3 -m venv /tmp/paynt && /tmp/paynt/bin/pip install
paynt``). PAYNT is not a dependency of parley and none of its code is used here.

Usage: python benchmarks/paynt_dpm.py [--seconds 600] [--paynt /tmp/paynt/bin/python]
"""

from __future__ import annotations

import argparse
import csv
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DPM = ROOT.parent / "shared" / "foreign-models" / "paynt-dpm"
LOST = 1.0


def parley_run(out: Path, extra: list[str]) -> dict:
    decisions = (DPM / "decisions.txt").read_text().split()
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "parley_core", "synthesize", str(DPM / "dpm.prism"), "--props", str(DPM / "dpm.pctl")]
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
    import json

    summary = json.loads((out / "summary.json").read_text())
    front = [(float(r["power"]), float(r["lostH"])) for r in csv.DictReader(open(out / "front.csv"))]
    bound = [(float(r["power"]), float(r["lostH"])) for r in csv.DictReader(open(out / "bound.csv"))]
    upper = min((p for p, lost in front if lost <= LOST), default=float("inf"))
    lower = min((p for p, lost in bound if lost <= LOST), default=float("inf"))
    return {
        "seconds": seconds,
        "front": len(front),
        "gap": summary["optimality"]["gap"],
        "exact": summary["optimality"]["exact"],
        "lower": lower,
        "upper": upper,
        "verified": summary["verification"]["by"],
    }


def paynt_run(python: str, seconds: int) -> dict:
    with tempfile.TemporaryDirectory() as scratch:
        project = Path(scratch) / "dpm"
        shutil.copytree(DPM, project)
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
    progress = re.findall(r"progress ([0-9.]+)%", text)
    optimum = re.findall(r"opt = ([0-9.]+)", text)
    return {
        "seconds": wall,
        "explored": float(progress[-1]) if progress else None,
        "best": float(optimum[-1]) if optimum else None,
        "returncode": done.returncode,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=int, default=600, help="branch and bound's and PAYNT's time limit")
    parser.add_argument("--paynt", default=None, help="a Python interpreter with PAYNT installed")
    args = parser.parse_args()
    if not DPM.is_dir():
        raise SystemExit(f"{DPM} is missing: this benchmark reads PAYNT's dpm family from ../shared/foreign-models")
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for name, extra in (
            ("parley synthesize (defaults)", []),
            (
                f"parley synthesize --bound refine --bound-time {args.seconds}",
                ["--bound", "refine"] + ["--bound-time", str(args.seconds)],
            ),
        ):
            rows.append((name, parley_run(Path(scratch) / name.split()[-1], extra)))
    print(f"dpm, {3**16:,} policies; PAYNT's query: least power with lostH <= {LOST:g}\n")
    print("| run | wall (s) | front | certified gap of the front | optimum of PAYNT's query lies in |")
    print("|---|---|---|---|---|")
    for name, r in rows:
        print(
            f"| {name} | {r['seconds']:.0f} | {r['front']} (values: {r['verified']}) | "
            f"{100 * r['gap']:.1f} %{' (exact)' if r['exact'] else ''} | [{r['lower']:.3f}, {r['upper']:.3f}] |"
        )
    if args.paynt:
        p = paynt_run(args.paynt, args.seconds)
        print(
            f"| PAYNT 0.5, ar, --timeout {args.seconds} | {p['seconds']:.0f} | - | - | best found {p['best']}, "
            f"{p['explored']} % of the family explored |"
        )
    else:
        print("\n(PAYNT not run: give --paynt PYTHON)")


if __name__ == "__main__":
    main()
