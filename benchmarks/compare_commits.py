"""Paired benchmark of two commits: each installed in its own environment (a git worktree
and a virtual environment each), the same commands run alternately (A, B, A, B, ...), and
each phase's time from the run's summary.json printed with the ratio B/A of the medians.

Cases (``--cases``, comma-separated):

- ``map_10``: the paper's map_10 (``../shared/reference``) at the paper's budget;
- ``grid20``, ``grid50``, ``grid100``: generated robot_grid maps (seed 11) at the paper's
  budget (population 100, 40 generations);
- ``web_ids``, ``tas``: the case studies' defaults.

``--generations N`` overrides the budget for a quick look. Each commit first runs each case
once untimed (one generation), so that numba's compilation into the worktree's cache is
not counted. Every run writes a run directory
under the work directory; the table gives, per case and phase, the median seconds of each
commit, the ratio, the whole run's wall clock and peak memory (resident set, from
``/usr/bin/time`` where it exists).

Usage: python benchmarks/compare_commits.py A B [--cases map_10,grid50] [--repeats 2]
       [--generations N] [--workdir .bench/compare]
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAP_10 = ROOT.parent / "shared" / "reference" / "parley2024" / "maps" / "map_10.csv"

CASES: dict[str, list[str]] = {
    "map_10": ["robot_grid", "--set", f"map={MAP_10}"],
    "grid20": ["robot_grid", "--set", "size=20", "--set", "seed=11"],
    "grid50": ["robot_grid", "--set", "size=50", "--set", "seed=11"],
    "grid100": ["robot_grid", "--set", "size=100", "--set", "seed=11"],
    "web_ids": ["web_ids"],
    "tas": ["tas"],
}
PAPER_BUDGET = ["--population", "100", "--generations", "40"]


def environment(commit: str, workdir: Path) -> Path:
    """The ``parley`` command of ``commit``, installed (once) in a worktree of its own."""
    resolved = subprocess.run(["git", "-C", str(ROOT), "rev-parse", commit], capture_output=True, text=True)
    if resolved.returncode != 0:
        raise SystemExit(f"error: {commit!r} is not a commit of {ROOT}; give a hash, a tag or a branch")
    sha = resolved.stdout.strip()
    tree = workdir / sha[:12]
    command = tree / ".venv" / "bin" / "parley"
    if command.is_file():
        return command
    if not tree.is_dir():
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), sha], check=True)
    print(f"installing {sha[:12]} in {tree} ...", file=sys.stderr, flush=True)
    subprocess.run([sys.executable, "-m", "venv", str(tree / ".venv")], check=True)
    subprocess.run([str(tree / ".venv" / "bin" / "pip"), "install", "-q", "-e", str(tree)], check=True)
    return command


def run_once(command: Path, case: str, budget: list[str], out: Path) -> dict[str, float]:
    """One run: its phases' seconds (summary.json), its wall clock and its peak memory (MB)."""
    timer = ["/usr/bin/time", "-f", "%M"] if Path("/usr/bin/time").is_file() else []
    started = time.perf_counter()
    done = subprocess.run(
        [*timer, str(command), "run", *CASES[case], *budget, "--seed", "1", "--out", str(out), "--force"],
        capture_output=True,
        text=True,
    )
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"error: {command} failed on {case}:\n{done.stderr[-2000:]}")
    summary = json.loads((out / "summary.json").read_text())
    figures = {phase: float(seconds) for phase, seconds in summary["timings_seconds"].items()}
    figures["whole run"] = wall
    if timer:
        figures["peak MB"] = int(done.stderr.strip().splitlines()[-1]) / 1024
    figures["evaluations"] = float(summary["search"]["evaluations"])
    return figures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("a")
    parser.add_argument("b")
    parser.add_argument("--cases", default="map_10,grid20,grid50,grid100,web_ids,tas")
    parser.add_argument("--repeats", type=int, default=2, help="runs of each commit, alternating (default 2)")
    parser.add_argument("--generations", type=int, help="the search's generations instead of the paper's 40")
    parser.add_argument("--workdir", type=Path, default=ROOT / ".bench" / "compare")
    args = parser.parse_args()
    cases = args.cases.split(",")
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        raise SystemExit(f"error: unknown case(s) {', '.join(unknown)}; valid: {', '.join(CASES)}")
    if "map_10" in cases and not MAP_10.is_file():
        raise SystemExit(f"error: {MAP_10} is missing (the paper's data, ../shared/reference); leave map_10 out")
    args.workdir.mkdir(parents=True, exist_ok=True)
    commands = {"A": environment(args.a, args.workdir), "B": environment(args.b, args.workdir)}
    print(f"A = {args.a}, B = {args.b}; {args.repeats} runs each, alternating; {time.strftime('%Y-%m-%d %H:%M')}")
    for case in cases:
        budget = [] if case in ("web_ids", "tas") else list(PAPER_BUDGET)
        if args.generations is not None:
            budget = (
                [*budget[:2], "--generations", str(args.generations)]
                if budget
                else ["--generations", str(args.generations)]
            )
        seen: dict[str, list[dict[str, float]]] = {"A": [], "B": []}
        for side in ("A", "B"):  # untimed: numba compiles each worktree's kernels into its cache on first use
            run_once(commands[side], case, [*budget[:2], "--generations", "1"], args.workdir / "runs" / f"warm-{side}")
        for repeat in range(args.repeats):
            for side in ("A", "B"):
                out = args.workdir / "runs" / f"{case}-{side}-{repeat}"
                seen[side].append(run_once(commands[side], case, budget, out))
                print(f"  {case} {side} {repeat + 1}: {seen[side][-1]['whole run']:.1f} s", file=sys.stderr, flush=True)
        print(f"\n{case} ({' '.join(CASES[case] + budget)})\n")
        print("| phase | A (s) | B (s) | B/A |\n|---|---|---|---|")
        keys = list(dict.fromkeys(k for r in seen["A"] + seen["B"] for k in r))
        for key in keys:
            a = statistics.median(r.get(key, float("nan")) for r in seen["A"])
            b = statistics.median(r.get(key, float("nan")) for r in seen["B"])
            ratio = f"{b / a:.2f}" if a > 0 and a == a and b == b else "-"
            print(f"| {key} | {a:.2f} | {b:.2f} | {ratio} |")
    if shutil.which("git"):
        print(f"\nworktrees in {args.workdir} (remove with `git worktree remove`)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
