"""turtlebot in MuJoCo: what its phases take, measured in one run, printed as Markdown.

1. the MuJoCo motion table from scratch (an empty cache), with and without heading memory;
2. a whole `parley run turtlebot` with the table cached, against the kinematic default;
3. `parley validate` of that run: 1,000 closed-loop episodes for the knee and each baseline.

Targets (2 cores): the table in at most 3 minutes; a run with cached MuJoCo motions no slower
than the kinematic one; validation in at most 3 minutes.

Usage: python benchmarks/turtlebot_physics.py [--episodes 1000] [--memory]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--memory", action="store_true", help="also with heading_memory=true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="parley-bench-") as scratch:
        os.environ["PARLEY_CACHE"] = str(Path(scratch) / "cache")
        from parley_core.family.prepare import prepare
        from parley_core.pipeline import run
        from parley_core.plugin.manager import load_registry
        from parley_core.progress import NullReporter
        from parley_core.rundir.write import write_run
        from parley_core.search import SearchSettings
        from parley_core.simulation.validate import validate

        case = load_registry().get("turtlebot")
        rows = []
        variants = [("kinematic", [])] + [("mujoco", ["motions=mujoco"])]
        if args.memory:
            variants.append(("mujoco, heading memory", ["motions=mujoco", "heading_memory=true"]))
        for label, assignments in variants:
            options = case.options(assignments)
            start = time.perf_counter()
            if case.warm_up is not None:
                case.warm_up(options, NullReporter())
            table = time.perf_counter() - start
            start = time.perf_counter()
            result = run(prepare(case, options), SearchSettings(seed=1), workers=2)
            whole = time.perf_counter() - start
            directory = Path(scratch) / label.replace(" ", "_").replace(",", "")
            write_run(result, directory)
            start = time.perf_counter()
            checked = validate(directory, episodes=args.episodes, seed=1)
            closed = time.perf_counter() - start
            chosen = checked.policies[0]
            success = next(e for e in chosen.estimates if e.objective == "success")
            rows.append((label, table, whole, closed, chosen.policy, success))
        print(
            f"| motions | table (s) | `parley run`, table cached (s) | `parley validate`, {args.episodes} episodes x 6 (s) | knee: Storm / closed-loop success |"
        )
        print("|---|---|---|---|---|")
        for label, table, whole, closed, policy, success in rows:
            print(
                f"| {label} | {table:.1f} | {whole:.1f} | {closed:.1f} | {policy}: {success.checked:.3f} / "
                f"{success.mean:.3f} ({success.low:.3f}-{success.high:.3f}) |"
            )


if __name__ == "__main__":
    main()
