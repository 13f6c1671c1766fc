"""The price and the value of robustness: nominal fronts against robust fronts.

For each case study, a nominal run (one model, the default numbers) and a robust run (the
worst case over a scenario set that contains the nominal numbers) with the same seed and
budget (the paper's, 4,000 evaluations). Storm then checks the nominal front in every
scenario and the robust front in the nominal model, and the script prints, with one
reference point per case (the worst value of each objective over everything compared):

- the hypervolume of each front in the nominal model and in the worst case;
- what the nominal front loses in the worst case (the value of robustness: what a robust
  front gains there) and what the robust front gives up in the nominal model (its price);
- the knee policies' values.

    .venv/bin/python benchmarks/robustness.py [--quick]

``--quick`` runs a 5x5 robot map only (a smoke test, a minute).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from parley_core import metrics
from parley_core.family.prepare import prepare, prepare_scenarios
from parley_core.family.scenarios import ScenarioSet
from parley_core.pipeline import run
from parley_core.plugin.manager import load_registry
from parley_core.robust import worst
from parley_core.search import SearchSettings
from parley_core.verify import storm_verifier

MAPS = Path(__file__).resolve().parents[2] / "shared" / "reference" / "parley2024" / "maps"

CASES = [
    ("robot_grid", {"map": str(MAPS / "map_10.csv")}, ["p=0.005,0.01,0.02"]),
    ("web_ids", {}, ["attack_a=0.15,0.3,0.45"]),
    ("tas", {}, ["degrade=0.025,0.05,0.1"]),
]
QUICK = [("robot_grid", {"size": "5", "seed": "1", "horizon": "45", "max_interval": "4"}, ["p=0.005,0.01,0.02"])]


def storm_values(family, rows: np.ndarray) -> np.ndarray:
    storm, _ = storm_verifier(family, "batch", workers=2)
    with storm:
        return storm.evaluate(rows)


def compare(name: str, options: dict[str, str], specs: list[str], settings: SearchSettings) -> dict:
    case = load_registry().get(name)
    start = time.perf_counter()
    nominal = run(prepare(case, case.options_from(options)), settings, workers=2, bound="none")
    nominal_seconds = time.perf_counter() - start
    start = time.perf_counter()
    robust = run(prepare_scenarios(case, dict(options), ScenarioSet.parse(specs)), settings, workers=2, bound="none")
    robust_seconds = time.perf_counter() - start
    objectives = nominal.family.objectives
    directions = [o.direction for o in objectives]
    nominal_rows = np.array([p.values for p in nominal.front.policies])
    robust_rows = np.array([p.values for p in robust.front.policies])
    # the nominal front in every scenario, the robust front in the nominal model: Storm's values
    each = np.stack([storm_values(m.family, nominal_rows) for m in robust.scenarios], axis=1)
    sets = {
        ("nominal front", "nominal"): np.array(nominal.front.values),
        ("nominal front", "worst case"): worst(each, objectives),
        ("robust front", "nominal"): storm_values(nominal.family, robust_rows),
        ("robust front", "worst case"): np.array(robust.front.values),
    }
    everything = np.vstack(list(sets.values()))
    reference = metrics.reference_point(objectives, everything, everything)
    hv = {key: metrics.hypervolume(values, directions, reference) for key, values in sets.items()}
    picks = requirement_picks(sets, objectives)
    knees = {
        front: sets[front, "worst case"][
            metrics.knee(sets[front, "nominal" if front == "nominal front" else "worst case"], directions)
        ]
        for front in ("nominal front", "robust front")
    }
    return {
        "case": name,
        "scenarios": ", ".join(m.label for m in robust.scenarios),
        "hv": hv,
        "sizes": (len(nominal.front), len(robust.front)),
        "seconds": (nominal_seconds, robust_seconds),
        "knees": knees,
        "picks": picks,
        "objectives": [o.name for o in objectives],
        "reference": reference,
    }


def requirement_picks(sets: dict, objectives) -> dict:
    """A requirement on the first objective (the median of the robust front's worst cases, so
    that both fronts have policies that meet it) and the best
    second objective under it: the policy a user would pick from the nominal front by its
    nominal values, and from the robust front by its worst cases; each one's values nominally
    and in the worst case."""
    first, second = objectives[0], objectives[1]
    level = float(np.median(sets["robust front", "worst case"][:, 0]))

    def meets(values):
        return values[:, 0] >= level if first.direction.value == "max" else values[:, 0] <= level

    def best(values, feasible):
        column = values[:, 1] * (1 if second.direction.value == "min" else -1)
        return int(np.flatnonzero(feasible)[np.argmin(column[feasible])])

    out = {"level": level}
    for front, judged in (("nominal front", "nominal"), ("robust front", "worst case")):
        chosen = best(sets[front, judged], meets(sets[front, judged]))
        out[front] = {where: sets[front, where][chosen] for where in ("nominal", "worst case")}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a 5x5 robot map only")
    args = parser.parse_args()
    settings = SearchSettings(population=100, generations=40, seed=1)
    print(
        "| case | scenarios | HV nominal: nominal front / robust front | HV worst case: nominal / robust | "
        "robust front's price (nominal) | value (worst case) | fronts | seconds nominal / robust |"
    )
    print("|---|---|---|---|---|---|---|---|")
    rows = []
    for name, options, specs in QUICK if args.quick else CASES:
        r = compare(name, options, specs, settings)
        rows.append(r)
        hv = r["hv"]
        price = 100 * (hv["robust front", "nominal"] / hv["nominal front", "nominal"] - 1)
        value = 100 * (hv["robust front", "worst case"] / hv["nominal front", "worst case"] - 1)
        print(
            f"| {name} | {r['scenarios']} | {hv['nominal front', 'nominal']:.6g} / {hv['robust front', 'nominal']:.6g} | "
            f"{hv['nominal front', 'worst case']:.6g} / {hv['robust front', 'worst case']:.6g} | {price:+.2f} % | "
            f"{value:+.2f} % | {r['sizes'][0]} / {r['sizes'][1]} | {r['seconds'][0]:.0f} / {r['seconds'][1]:.0f} |",
            flush=True,
        )
    print()
    print("knee policies in the worst case (the nominal front's knee chosen on nominal values):")
    for r in rows:
        for front, values in r["knees"].items():
            shown = ", ".join(f"{n} {v:.4g}" for n, v in zip(r["objectives"], values))
            print(f"  {r['case']}: {front}'s knee: {shown}")
    print()
    print(
        "a requirement on the first objective (the median of the robust front's worst cases), "
        "the best second objective under it:"
    )
    for r in rows:
        picks = r["picks"]
        first, second = r["objectives"][:2]
        for front in ("nominal front", "robust front"):
            by = "nominal values" if front == "nominal front" else "worst cases"
            shown = "; ".join(
                f"{where}: {first} {picks[front][where][0]:.4g}, {second} {picks[front][where][1]:.4g}"
                for where in ("nominal", "worst case")
            )
            print(f"  {r['case']} ({first} bound {picks['level']:.4g}), picked from the {front} by its {by}: {shown}")
    print(
        "reference points: "
        + "; ".join(f"{r['case']} {tuple(round(float(v), 4) for v in r['reference'])}" for r in rows)
    )


if __name__ == "__main__":
    main()
