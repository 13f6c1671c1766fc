"""The parley command: outputs, JSON documents, run directories and one-line user errors."""

from __future__ import annotations

import csv
import json

import pytest
from typer.testing import CliRunner

from conftest import assert_points_are_not_ties
from parley_core.cli import app

runner = CliRunner()
QUICK = ["--set", "size=5", "--set", "seed=1", "--set", "max_interval=4", "--set", "horizon=45", "--workers", "1"]


def summary_size(run_dir) -> int:
    return json.loads((run_dir / "summary.json").read_text())["front"]["size"]


def invoke(*args: str):
    return runner.invoke(app, list(args))


def assert_user_error(result, message: str) -> None:
    assert result.exit_code == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: ")
    assert message in lines[0]
    assert "Traceback" not in result.stderr and result.exception is None or isinstance(result.exception, SystemExit)


@pytest.fixture
def free_map(tmp_path):
    """A 3x3 map without obstacles: with p=0 the robot never deviates."""
    path = tmp_path / "free.csv"
    path.write_text("0,0,0\n0,0,0\n0,0,0\n")
    return path


def test_list_shows_the_builtin_case_study():
    result = invoke("list")
    assert result.exit_code == 0
    assert "robot_grid" in result.stdout


def test_options_lists_defaults():
    result = invoke("options", "robot_grid")
    assert result.exit_code == 0
    assert "horizon" in result.stdout and "100" in result.stdout


def test_baseline_json_on_a_map_without_uncertainty(free_map):
    # p=0: four moves to the target, always successful; interval k localises floor(4/k) times.
    result = invoke("baseline", "robot_grid", "--set", f"map={free_map}", "--set", "p=0", "--json", "--workers", "1")
    assert result.exit_code == 0, result.stderr
    document = json.loads(result.stdout)
    assert document["case_study"] == "robot_grid"
    assert [o["name"] for o in document["objectives"]] == ["success", "cost"]
    assert len(document["policies"]) == 10
    for entry in document["policies"]:
        k = entry["decisions"]["c"]
        assert entry["values"]["success"] == pytest.approx(1.0, abs=1e-12)
        assert entry["values"]["cost"] == pytest.approx(4 + 5 * (4 // k), abs=1e-9)


def test_evaluate_constant_and_policies_file_agree_with_the_baseline(free_map, tmp_path):
    baseline = json.loads(invoke("baseline", "robot_grid", *QUICK, "--json").stdout)
    by_name = {p["policy"]: p["values"] for p in baseline["policies"]}
    result = invoke("evaluate", "robot_grid", *QUICK, "--constant", "2", "--json")
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["policies"][0]["values"] == pytest.approx(by_name["interval-2"])

    rows = ["policy,xhat,yhat,c"] + [f"two,{x},{y},2" for x in range(5) for y in range(5)]
    (tmp_path / "p.csv").write_text("\n".join(rows) + "\n")
    result = invoke("evaluate", "robot_grid", *QUICK, "--policies", str(tmp_path / "p.csv"), "--json")
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["policies"][0]["values"] == pytest.approx(by_name["interval-2"])


@pytest.mark.slow
def test_run_writes_the_run_directory_and_is_reproducible(tmp_path):
    first, second = tmp_path / "a", tmp_path / "b"
    for out in (first, second):
        result = invoke(
            "run", "robot_grid", *QUICK, "--population", "8", "--generations", "3", "--seed", "7", "--out", str(out)
        )
        assert result.exit_code == 0, result.stderr
    names = {p.name for p in first.iterdir()}
    assert names == {
        "model.prism",
        "properties.pctl",
        "front.csv",
        "policies.csv",
        "decisions.csv",
        "baseline.csv",
        "bound.csv",
        "summary.json",
        "front.png",
        "policy.png",
        "report.html",
        "map.json",
    }
    assert (first / "front.csv").read_text() == (second / "front.csv").read_text()
    assert (first / "report.html").read_bytes() == (second / "report.html").read_bytes()
    assert (first / "policies.csv").read_text() == (second / "policies.csv").read_text()
    with open(first / "front.csv") as handle:
        header = next(csv.reader(handle))
    assert header == ["policy", "success", "cost", "point"]
    assert assert_points_are_not_ties(first) <= summary_size(first)
    with open(first / "policies.csv") as handle:
        header = next(csv.reader(handle))
    assert header[:3] == ["policy", "c_0_0", "c_0_1"] and len(header) == 26
    summary = json.loads((first / "summary.json").read_text())
    assert summary["seed"] == 7 and summary["search"]["population"] == 8
    assert summary["front"]["hypervolume"] >= summary["baseline"]["hypervolume"]
    # the quotient evaluator searched; Storm re-checked every front policy
    assert summary["evaluator"] == "quotient"
    assert summary["verification"]["by"] == "storm"
    assert summary["verification"]["policies"] == len((first / "front.csv").read_text().splitlines()) - 1
    assert summary["verification"]["max_difference"] <= 1e-6
    assert "Pareto front" in result.stdout and "hypervolume" in result.stdout


def test_run_and_evaluate_with_the_storm_evaluator(tmp_path):
    result = invoke(
        "run",
        "robot_grid",
        *QUICK,
        "--population",
        "6",
        "--generations",
        "2",
        "--evaluator",
        "storm",
        "--out",
        str(tmp_path / "r"),
    )
    assert result.exit_code == 0, result.stderr
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["evaluator"] == "storm" and summary["verification"]["max_difference"] == 0.0
    storm = json.loads(
        invoke("evaluate", "robot_grid", *QUICK, "--constant", "3", "--evaluator", "storm", "--json").stdout
    )
    quotient = json.loads(invoke("evaluate", "robot_grid", *QUICK, "--constant", "3", "--json").stdout)
    assert quotient["evaluator"] == "quotient"
    assert quotient["policies"][0]["values"] == pytest.approx(storm["policies"][0]["values"], abs=1e-9)
    assert_user_error(
        invoke("evaluate", "robot_grid", *QUICK, "--constant", "3", "--evaluator", "fast"),
        "unknown evaluator 'fast'; valid: quotient, storm",
    )


@pytest.mark.slow
def test_run_stops_at_an_evaluation_budget_or_a_time_limit(tmp_path):
    result = invoke(
        "run", "robot_grid", *QUICK, "--population", "8", "--max-evaluations", "30", "--out", str(tmp_path / "b")
    )
    assert result.exit_code == 0, result.stderr
    search = json.loads((tmp_path / "b" / "summary.json").read_text())["search"]
    assert search["evaluations"] == 30 and search["stopped_by"] == "evaluations" and search["generations"] is None
    assert "stopped by evaluations" in result.stdout
    result = invoke(
        "run", "robot_grid", *QUICK, "--population", "8", "--time-limit", "0.5", "--out", str(tmp_path / "t")
    )
    assert result.exit_code == 0, result.stderr
    search = json.loads((tmp_path / "t" / "summary.json").read_text())["search"]
    assert search["stopped_by"] == "time" and search["time_limit_seconds"] == 0.5
    result = invoke(
        "run", "robot_grid", *QUICK, "--generations", "2", "--max-evaluations", "1000", "--out", str(tmp_path / "g")
    )
    assert json.loads((tmp_path / "g" / "summary.json").read_text())["search"]["stopped_by"] == "generations"
    assert invoke("run", "robot_grid", *QUICK, "--max-evaluations", "0", "--out", str(tmp_path / "z")).exit_code == 2


def test_run_takes_a_search_configuration_by_name(tmp_path):
    result = invoke(
        "run", "robot_grid", *QUICK, "--algorithm", "archive", "--max-evaluations", "40", "--out", str(tmp_path / "a")
    )
    assert result.exit_code == 0, result.stderr
    search = json.loads((tmp_path / "a" / "summary.json").read_text())["search"]
    assert search["algorithm"] == "archive" and search["evaluations"] == 40
    assert_user_error(
        invoke("run", "robot_grid", *QUICK, "--algorithm", "nsga3", "--out", str(tmp_path / "n")),
        "unknown search algorithm 'nsga3'; valid: paper, ordinal, archive, sms, blend",
    )


def test_run_refuses_a_non_empty_output_directory(tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    result = invoke("run", "robot_grid", *QUICK, "--out", str(tmp_path))
    assert_user_error(result, "exists and is not empty; choose another --out or add --force")
    assert (tmp_path / "keep.txt").read_text() == "mine"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "robot"], "unknown case study 'robot'; valid: robot_grid"),
        (["baseline", "robot_grid", "--set", "size"], "malformed option 'size'; write KEY=VALUE"),
        (["baseline", "robot_grid", "--set", "color=red"], "unknown option 'color' for robot_grid"),
        (["baseline", "robot_grid", "--set", "size=big"], "option size='big' for robot_grid: expected int"),
        (["baseline", "robot_grid", "--set", "p=0.5"], "'p' must be <= 0.333"),
        (["baseline", "robot_grid", "--set", "map=/no/such/map.csv"], "map file /no/such/map.csv does not exist"),
        (["evaluate", "robot_grid", "--set", "size=3"], "give exactly one of --policies FILE and --constant K"),
        (["evaluate", "robot_grid", "--set", "size=3", "--constant", "11"], "is outside 1..10"),
        (
            ["evaluate", "robot_grid", "--set", "size=3", "--policies", "/no/such.csv"],
            "policies file /no/such.csv does not exist",
        ),
    ],
)
def test_user_errors_are_one_line_with_status_2(args, message):
    assert_user_error(invoke(*args), message)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("0,0,0\n0,x,0\n0,0,0\n", "line 2: '0,x,0' is not a list of integer weights"),
        ("0,0,0\n0,0\n0,0,0\n", "rows have different lengths"),
        ("", "is empty"),
        ("0,0,0\n10,10,10\n0,0,0\n", "has no obstacle-free path from the start (0, 0) to the target (2, 2)"),
        ("0,0,10\n0,0,0\n0,0,0\n", "the target cell (2,2) is an obstacle"),
    ],
)
def test_malformed_maps(tmp_path, content, message):
    path = tmp_path / "map.csv"
    path.write_text(content)
    assert_user_error(invoke("baseline", "robot_grid", "--set", f"map={path}"), message)


def test_malformed_policies_file(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text("policy,xhat,yhat,c\nmine,0,0,3\n")
    result = invoke("evaluate", "robot_grid", "--set", "size=3", "--set", "seed=2", "--policies", str(path))
    assert_user_error(result, "policy 'mine' lacks xhat=0, yhat=1 and 7 more valuations; give one row per valuation")


def test_where_stderr_is_no_terminal_a_line_tells_how_far_a_stage_is(monkeypatch):
    # a batch job sees no bars until they stop: it gets a line per LOG_EVERY seconds instead
    import io

    from rich.console import Console

    from parley_core.views import richprogress

    out = io.StringIO()
    monkeypatch.setattr(richprogress, "LOG_EVERY", 0.0)
    with richprogress.RichReporter(Console(file=out, force_terminal=False, width=100)) as reporter:
        reporter.stage("branch and bound", 1000)
        reporter.advance(250)
    assert "branch and bound: 250 of 1,000 after 0:00" in out.getvalue()
    # at the usual interval a short stage prints no such line
    monkeypatch.setattr(richprogress, "LOG_EVERY", 60.0)
    out = io.StringIO()
    with richprogress.RichReporter(Console(file=out, force_terminal=False, width=100)) as reporter:
        reporter.stage("branch and bound", 1000)
        reporter.advance(250)
    assert " of 1,000 after" not in out.getvalue()


def test_version_and_the_case_argument_in_help():
    import parley

    result = invoke("--version")
    assert result.exit_code == 0 and result.stdout.strip() == f"parley {parley.__version__}"
    shown = invoke("run", "--help").stdout
    assert "run [OPTIONS] {CASE}" in shown and "{case}" not in shown
    assert "robot_grid, turtlebot, web_ids, tas" in shown
    assert "are not counted" in invoke("exact", "--help").stdout  # what --time-limit covers


def test_a_baseline_table_of_many_constants_stays_readable():
    """A family of 16 holes (a pole-balancing model's, say): the baselines' constants as one
    column of their values, not 16 columns squeezed to '…' in an 80-column terminal."""
    from rich.console import Console

    from parley_core.cli.console import front_table
    from parley_core.model import Direction, Objective, Policy, Valued

    objectives = [Objective(name="fall", formula="P=? [F x]", direction=Direction.MIN)]
    constants = {f"h{i}": [1, 2, 3] for i in range(16)}
    constants["same"] = [5, 5, 5]  # a constant every baseline sets alike is left out
    valued = Valued(objectives=objectives, policies=[Policy(name=f"all-{v}", values=()) for v in (1, 2, 3)],
                    values=[[0.1], [0.2], [0.3]])  # fmt: skip
    console = Console(width=80, record=True)
    console.print(front_table("Baseline", valued, constants))
    text = console.export_text()
    assert "…" not in text and "h0..h15 (16 varying)" in text and "same" not in text
    assert "1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1" in text


@pytest.mark.slow
def test_a_loose_bound_says_where_and_branch_and_bound_closes_it(tmp_path):
    """A family in the shape of a two-agent meeting grid (tests/data/meet.prism, 8 holes, no
    observation): most policies never meet, the front is one point, and the cheap bound's
    schedulers see both agents. The run says which objective the gap comes from; --exact
    proves the front."""
    from pathlib import Path

    data = Path(__file__).parent / "data"
    holes = [arg for h in ("a0", "a1", "a2", "a3", "b0", "b1", "b2", "b3") for arg in ("--decision", f"{h}=0..2")]
    common = ["synthesize", str(data / "meet.prism"), "--props", str(data / "meet.pctl"), *holes, "--workers", "1"]
    loose = invoke(*common, "--population", "20", "--generations", "10", "--out", str(tmp_path / "loose"))
    assert loose.exit_code == 0, loose.stderr
    text = " ".join(loose.stdout.split())
    assert "where the bound is loose: the front's best and the bound's, moves " in text
    assert "branch and bound (--bound refine, or --exact) narrows the gap" in text
    assert "have an infinite moves" in text
    exact = invoke(*common, "--population", "20", "--generations", "10", "--exact", "--out", str(tmp_path / "exact"))
    assert exact.exit_code == 0, exact.stderr
    summary = json.loads((tmp_path / "exact" / "summary.json").read_text())
    assert summary["optimality"]["exact"] is True and summary["optimality"]["gap"] <= 1e-6
    assert "where the bound is loose" not in exact.stdout
