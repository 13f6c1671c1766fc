"""Campaigns: the store, planning, statistics, reports, resuming after SIGKILL, and Dask."""

from __future__ import annotations

import csv
import os
import signal
import sqlite3
import subprocess
import sys
import time

import numpy as np
import pytest

from parley_core.errors import OptionError, OutputError
from parley_core.experiment import report, table2
from parley_core.experiment.campaign import Budget, execute, instance_label, instances_from, plan
from parley_core.experiment.stats import a12, compare
from parley_core.experiment.store import RunRecord, Store, baseline_from_json, front_from_json
from parley_core.model import Direction, Objective
from parley_plugins.robot_grid import CASE_STUDY as ROBOT

TINY = Budget(population=6, generations=2)
OBJECTIVES = (
    Objective(name="success", direction=Direction.MAX, formula='P=? [F "goal"]'),
    Objective(name="cost", direction=Direction.MIN, formula="R=? [C<=9]"),
)


def record(instance: str, repetition: int, front, baseline, campaign: str = "c") -> RunRecord:
    return RunRecord(
        campaign=campaign,
        instance=instance,
        repetition=repetition,
        seed=repetition + 1,
        options={},
        objectives=OBJECTIVES,
        front=front_from_json(OBJECTIVES, {"policies": [[1]] * len(front), "values": front}),
        baseline=baseline_from_json(OBJECTIVES, {"names": ["b"] * len(baseline), "values": baseline}),
        summary={},
    )


def test_store_keeps_each_run_once_and_checks_campaign_settings(tmp_path):
    with Store(tmp_path / "s.sqlite") as store:
        store.begin_campaign("c", "robot_grid", {"population": 6})
        assert store.add(record("map_1", 0, [[0.9, 10.0]], [[0.8, 12.0]]))
        assert not store.add(record("map_1", 0, [[0.1, 1.0]], [[0.8, 12.0]]))
        assert store.done("c") == {("map_1", 0)}
        assert [[list(v) for v in r.front.values] for r in store.runs("c")] == [[[0.9, 10.0]]]
        store.begin_campaign("c", "robot_grid", {"population": 6})
        with pytest.raises(OutputError, match="already holds campaign 'c' with other settings"):
            store.begin_campaign("c", "robot_grid", {"population": 7})


def test_planning(tmp_path):
    (tmp_path / "map_10.csv").write_text("0,0\n0,0\n")
    (tmp_path / "map_9.csv").write_text("0,0\n0,0\n")
    instances = instances_from(ROBOT, ["p=0.01,0.02"], str(tmp_path))
    assert [instance_label(i) for i in instances] == ["p=0.01 map_9", "p=0.01 map_10", "p=0.02 map_9", "p=0.02 map_10"]
    specs = plan("c", ROBOT, instances, ["horizon=30"], 2, TINY, first_seed=5)
    assert len(specs) == 8 and {s.seed for s in specs} == {5, 6}
    assert specs[0].assignments == ("horizon=30", "p=0.01", f"map={tmp_path / 'map_9.csv'}")
    with pytest.raises(OptionError, match="malformed --grid"):
        instances_from(ROBOT, ["seed"])
    with pytest.raises(OptionError, match="matches no file"):
        instances_from(ROBOT, [], str(tmp_path / "nothing*.csv"))
    with pytest.raises(OptionError, match="unknown option 'color'"):
        plan("c", ROBOT, [("color=red",)], [], 1, TINY)


def test_a12_and_mann_whitney():
    assert a12([2, 3, 4], [1, 1, 1]) == 1.0
    assert a12([1, 2], [2, 1]) == 0.5
    assert a12([1, 1], [1, 2]) == pytest.approx(0.25)
    ten = np.arange(1, 11) / 10
    assert compare(ten, np.zeros(10)).verdict == "better"
    assert compare(-ten, np.zeros(10)).verdict == "worse"
    assert compare(np.zeros(10), np.zeros(10)).verdict == "same"
    assert compare([0.1, -0.1, 0.2, -0.2], [0, 0, 0, 0]).verdict == "same"


def test_report_on_fronts_with_known_hypervolumes():
    # baseline: one point (0.8, 60): hypervolume in the box (0.7, 80) is 0.1 * 20 = 2.
    # "better" repetitions add (0.9, 70): + 0.1 * 10 -> 3; "worse" ones only have (0.75, 70): 0.05 * 10.
    baseline = [[0.8, 60.0], [0.5, 10.0]]
    records = [record("better", r, [[0.8, 60.0], [0.9, 70.0 - r * 0.1]], baseline) for r in range(10)]
    records += [record("worse", r, [[0.75, 70.0 - r * 0.1]], baseline) for r in range(10)]
    rows = report.analyze(records, [(0.7, 80.0)])
    by = {r.instance: r for r in rows}
    assert by["better"].baseline_hv == pytest.approx(2.0)
    assert by["better"].hv[0] == pytest.approx(3.0)
    assert (by["better"].hv_verdict, by["worse"].hv_verdict) == ("better", "worse")
    assert table2.counts(rows, (0.7, 80.0), "hv_verdict") == (1, 1, 0)
    # the paper's spread: 1.5 for a single point, the diagonal of the unit square for two
    assert by["better"].baseline_gap == 1.5 and by["better"].gap[0] == pytest.approx(2**0.5)
    assert (by["better"].gap_verdict, by["worse"].gap_verdict) == ("better", "same")
    # IGD+ against the union's non-dominated points in the box, (0.8, 60) and (0.9, 69.1),
    # normalized by the box from the ideal (0.9, 10) to the bounds: the baseline misses the
    # second by 0.1 / 0.2 in success; repetition 9 of "better" holds both points
    assert by["better"].baseline_igd == pytest.approx(0.25)
    assert by["better"].igd[9] == pytest.approx(0.0)
    assert (by["better"].igd_verdict, by["worse"].igd_verdict) == ("better", "worse")
    assert "| 0.7 | 80 | 1/1/0 |" in table2.table2_markdown(rows, [(0.7, 80.0)], ["success >=", "cost <="], False)


def test_report_compares_with_published_fronts(tmp_path):
    baseline = [[0.8, 60.0]]
    records = [record("map_1", r, [[0.85, 60.0]], baseline) for r in range(10)]
    for r in range(10):
        (tmp_path / f"map_1_rep{r}.front.tsv").write_text("P\tcost\n0.81\t60.0\n")
    rows = report.analyze(records, [(0.7, 80.0)], published=tmp_path)
    assert rows[0].published_hv[0] == pytest.approx(0.11 * 20)
    assert rows[0].published_verdict == "better"


def _campaign_command(store, name="k"):
    return [
        sys.executable,
        "-m",
        "parley_core",
        "experiment",
        "run",
        "robot_grid",
        "--store",
        str(store),
        "--name",
        name,
        "--grid",
        "seed=1,2,3,4",
        "--set",
        "size=4",
        "--set",
        "max_interval=3",
        "--reps",
        "2",
        "--population",
        "6",
        "--generations",
        "2",
        "--workers",
        "1",
    ]


@pytest.mark.slow
def test_a_campaign_killed_with_sigkill_resumes_without_losing_or_repeating(tmp_path):
    store = tmp_path / "k.sqlite"
    process = subprocess.Popen(
        _campaign_command(store), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    try:
        deadline = time.time() + 120
        stored = 0
        while time.time() < deadline and stored < 2:
            time.sleep(0.2)
            if store.exists():
                try:
                    with sqlite3.connect(store) as connection:
                        stored = connection.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
                except sqlite3.OperationalError:
                    pass
        assert stored >= 2, "the campaign did not store runs in time"
    finally:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    with sqlite3.connect(store) as connection:
        before = dict(((i, r), f) for i, r, f in connection.execute("SELECT instance, repetition, finished FROM runs"))
    assert 2 <= len(before) < 8
    finished = subprocess.run(_campaign_command(store), capture_output=True, text=True, timeout=300)
    assert finished.returncode == 0, finished.stderr
    assert f"{len(before)} already stored, {8 - len(before)} stored now" in " ".join(finished.stdout.split())
    with sqlite3.connect(store) as connection:
        rows = connection.execute("SELECT instance, repetition, finished FROM runs").fetchall()
    keys = [(i, r) for i, r, _ in rows]
    assert len(keys) == len(set(keys)) == 8
    assert all(before[(i, r)] == f for i, r, f in rows if (i, r) in before), "a stored run was computed again"


@pytest.mark.slow
def test_the_dask_path_on_a_local_cluster(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    specs = plan("d", ROBOT, [("seed=1",), ("seed=2",)], ["size=4", "max_interval=3"], 1, TINY)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with Store(tmp_path / "d.sqlite") as store:
            store.begin_campaign("d", "robot_grid", {})
            outcome = execute(specs, store, scheduler=cluster.scheduler_address)
            assert (outcome.stored, outcome.failures) == (2, [])
            local = execute(specs, store, workers=1)
            assert (local.skipped, local.stored) == (2, 0)
            values = [[list(v) for v in r.front.values] for r in store.runs("d")]
    # the same runs computed locally give the same fronts
    with Store(tmp_path / "l.sqlite") as store:
        store.begin_campaign("d", "robot_grid", {})
        execute(specs, store, workers=1)
        assert [[list(v) for v in r.front.values] for r in store.runs("d")] == values


@pytest.mark.slow
def test_scheduler_that_cannot_be_reached(tmp_path):
    pytest.importorskip("dask.distributed")
    specs = plan("d", ROBOT, [("seed=1",)], ["size=4"], 1, TINY)
    with Store(tmp_path / "d.sqlite") as store, pytest.raises(OptionError, match="cannot reach the Dask scheduler"):
        execute(specs, store, scheduler="tcp://127.0.0.1:1")


@pytest.mark.slow
def test_unverified_fronts_are_verified_later_by_storm(tmp_path):
    from parley_core.experiment.campaign import verify_stored

    specs = plan(
        "v",
        ROBOT,
        [("seed=1",), ("seed=2",)],
        ["size=4", "max_interval=3"],
        2,
        Budget(population=6, generations=2, verify=False),
    )
    with Store(tmp_path / "v.sqlite") as store:
        store.begin_campaign("v", "robot_grid", {})
        execute(specs, store, workers=1)
        before = list(store.runs("v"))
        assert len(before) == 4 and not any(r.verified for r in before)
        # a sample first: repetition 1 of each instance
        assert verify_stored(store, "v", "robot_grid", workers=1, repetitions={1})[:2] == (2, 0)
        assert sorted(r.repetition for r in store.runs("v") if r.verified) == [1, 1]
        document = table2.table2_document(
            "v", "robot_grid", {}, list(store.runs("v")), [], [], ["success >=", "cost <="], False
        )
        assert "Front values: Storm's for 2 of 4 runs" in document
        now, already, worst = verify_stored(store, "v", "robot_grid", workers=1)
        assert (now, already) == (2, 2) and worst <= 1e-9
        after = list(store.runs("v"))
        assert all(r.verified for r in after)
        for old, new in zip(before, after):
            assert np.allclose(old.front.values, new.front.values, atol=1e-9)
        assert verify_stored(store, "v", "robot_grid", workers=1)[:2] == (0, 4)
        document = table2.table2_document("v", "robot_grid", {}, after, [], [], ["success >=", "cost <="], False)
        assert "Front values: Storm's, every front re-checked" in document


def test_campaign_bounds_are_stored_once_and_give_the_reports_gap_column(tmp_path):
    import parley
    from parley_core import metrics
    from parley_core.experiment.store import Store

    store = tmp_path / "c.sqlite"
    campaign = parley.experiment(
        "robot_grid", store=store, grid=["size=4,5"], reps=2, population=10, generations=2, workers=1, progress=False
    )
    assert campaign.bound(workers=1, progress=False) == 2
    assert campaign.bound(workers=1, progress=False) == 0  # stored: skipped
    with Store(store) as results:
        bounds = results.bounds("robot_grid")
        records = list(results.runs("robot_grid"))
    assert sorted(bounds) == ["size=4", "size=5"]
    for record in records:  # sound on every stored (Storm-verified) front: each point is weakly dominated
        front = np.array(record.front.values)
        directions = [o.direction for o in record.objectives]
        signs = np.array([d.sign for d in directions])  # +1 minimised
        bound = bounds[record.instance] * signs
        for point in front * signs:
            assert (bound <= point + 1e-9).all(axis=1).any()
        for setting in [(0.6, 60.0), (0.8, 100.0)]:
            assert (
                metrics.hypervolume(front, directions, setting)
                <= metrics.hypervolume(bounds[record.instance], directions, setting) + 1e-9
            )
    made = campaign.report(tmp_path / "report")
    header = next(line for line in made.table2.splitlines() if line.startswith("| success"))
    assert header.endswith("median gap to the bound |")
    total = made.table2.strip().splitlines()[-1]
    assert total.startswith("| all |") and "%" in total.split("|")[-2]
    assert "median gap to the bound" in (tmp_path / "report" / "report.html").read_text()
    with open(tmp_path / "report" / "table2.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert all(float(r["median_bound_gap"]) >= -1e-9 for r in rows if r["median_bound_gap"])


def test_the_scalability_row_measures_both_evaluators_on_the_same_policies():
    from parley_core.experiment.scalability import measure, table3_markdown
    from parley_core.plugin.manager import load_registry

    row = measure(
        load_registry().get("robot_grid"),
        ["size=3", "seed=1", "max_interval=3"],
        storm_policies=3,
        quotient_policies=5,
        population=4,
        generations=2,
        workers=1,
    )
    assert row["max_difference"] < 1e-9  # the quotient's values are Storm's (the reference and policy programs)
    assert row["search_evaluations"] == 8 and row["quotient_states"] > 0 and row["decisions"] > 0
    assert (
        row["storm_ms"] > 0
        and row["quotient_ms"] > 0
        and row["ratio"] == pytest.approx(row["storm_ms"] / row["quotient_ms"])
    )
    table = table3_markdown([row])
    assert "size=3 seed=1 max_interval=3" in table.splitlines()[-1]


@pytest.mark.slow
def test_campaign_cells_are_answered_as_enumeration_says_and_counted_in_the_report(tmp_path):
    """``experiment check`` on a campaign of two small maps: every cell's answer is what
    enumerating the family says (a feasible one's values are Storm's and inside the box), a
    second call answers nothing again, and Table 2 and its CSV count them per setting."""
    import itertools

    import parley
    from parley_core.experiment.store import Store
    from parley_core.quotient.coloring import build_quotient
    from parley_core.quotient.solver import QuotientSolver
    from parley_core.testing import family

    store = tmp_path / "c.sqlite"
    options = {"max_interval": 2, "horizon": 30}
    campaign = parley.experiment(
        "robot_grid", store=store, grid=["size=3", "seed=1,2"], options=options, reps=1, population=6,
        generations=1, workers=1, progress=False,
    )  # fmt: skip
    campaign.bound(workers=1, progress=False)
    settings = [(0.5, 20.0), (0.9, 20.0), (0.99, 5.0), (0.3, 100.0)]
    assert campaign.check(settings=settings, workers=1, progress=False, seconds=60) == 8
    assert campaign.check(settings=settings, workers=1, progress=False) == 0  # stored: skipped
    with Store(store) as results:
        answers = results.answers("robot_grid")
    seen = set()
    for seed in (1, 2):
        fam = family("robot_grid", ["size=3", f"seed={seed}", "max_interval=2", "horizon=30"])
        solver = QuotientSolver(build_quotient(fam))
        rows = itertools.product(*(d.service.values for d in fam.decisions))
        values = np.array([solver.solve(np.array(r)) for r in rows])
        for setting in settings:
            cell = answers[(f"size=3 seed={seed}", setting)]
            inside = ((values[:, 0] >= setting[0] - 1e-9) & (values[:, 1] <= setting[1] + 1e-9)).any()
            assert cell["answer"] == ("feasible" if inside else "infeasible"), (seed, setting, cell)
            if inside:
                assert cell["values"][0] >= setting[0] - 1e-9 and cell["values"][1] <= setting[1] + 1e-9
            seen.add(cell["answer"])
    assert seen == {"feasible", "infeasible"}
    made = campaign.report(tmp_path / "report", settings=settings)
    header = next(line for line in made.table2.splitlines() if line.startswith("| success"))
    assert header.endswith("policy in the box: feasible/infeasible/unknown |")
    with open(tmp_path / "report" / "table2.csv") as handle:
        assert {r["answer"] for r in csv.DictReader(handle)} == seen
