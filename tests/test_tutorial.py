"""docs/tutorial.md, step by step on its own files: augment, synthesize, select, decide, simulate.

The search budget is smaller than the tutorial's so the test stays quick; everything else,
including the tutorial's Python blocks, runs as written."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import re
from pathlib import Path

import pytest
import stormpy
from typer.testing import CliRunner

from parley_core.cli import app

DOCS = Path(__file__).resolve().parents[1] / "docs"
MODEL = DOCS / "tutorial" / "pump.prism"
PROPS = DOCS / "tutorial" / "pump.pctl"
runner = CliRunner()


def invoke(*args):
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.stderr
    return result


def python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", (DOCS / "tutorial.md").read_text(), flags=re.S)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """The tutorial's files as a reader has them after steps 2 and 3 (smaller search)."""
    root = tmp_path_factory.mktemp("tutorial")
    result = invoke("augment", MODEL, "--decision", "c=1..8", "--observe", "est,load", "--out", root / "pump-urc.prism")
    assert "4 of 6 observation valuations of (est, load) consult a service" in result.stderr
    invoke(
        "synthesize",
        MODEL,
        "--props",
        PROPS,
        "--decision",
        "c=1..8",
        "--observe",
        "est,load",
        "--population",
        "20",
        "--generations",
        "6",
        "--workers",
        "1",
        "--out",
        root / "runs" / "pump",
    )
    return root


def test_augment_gives_one_constant_per_consulted_valuation(workdir):
    program = stormpy.parse_prism_program(str(workdir / "pump-urc.prism"))
    assert sorted(c.name for c in program.constants if not c.defined) == ["c_0_0", "c_0_1", "c_1_0", "c_1_1"]


def test_the_stormpy_block_prints_what_the_tutorial_shows(workdir, monkeypatch):
    block = python_blocks()[0]
    expected = [line[2:] for line in block.splitlines() if line.startswith("# ")]
    monkeypatch.chdir(workdir)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(block, "tutorial.md", "exec"), {})
    printed = out.getvalue().splitlines()
    assert len(printed) == len(expected) == 2
    for line, shown in zip(printed, expected):
        assert line.rsplit(" ", 1)[0] == shown.rsplit(" ", 1)[0]
        assert float(line.rsplit(" ", 1)[1]) == pytest.approx(float(shown.rsplit(" ", 1)[1]), rel=1e-9)


def test_synthesis_beats_the_fixed_intervals_and_inspecting_every_hour_never_breaks_the_pump(workdir):
    run = workdir / "runs" / "pump"
    summary = json.loads((run / "summary.json").read_text())
    assert summary["front"]["hypervolume"] > summary["baseline"]["hypervolume"]
    with open(run / "baseline.csv") as handle:
        baseline = {row["policy"]: row for row in csv.DictReader(handle)}
    assert list(baseline)[0] == "model (c=4)"
    # wear grows by at most one level an hour, and an inspection every hour repairs at level 2
    assert float(baseline["c=1"]["broken"]) == 0.0
    assert float(baseline["c=8"]["broken"]) > float(baseline["c=2"]["broken"]) > 0


def test_select_takes_the_cheapest_controller_under_the_risk_bound(workdir):
    run = workdir / "runs" / "pump"
    result = invoke("select", run, "--constraint", "broken<=0.1", "--prefer", "cost", "--json")
    chosen = json.loads(result.stdout)
    with open(run / "front.csv") as handle:
        front = [row for row in csv.DictReader(handle) if float(row["broken"]) <= 0.1]
    cheapest = min(front, key=lambda row: float(row["cost"]))
    assert chosen["policy"] == cheapest["policy"]
    assert chosen["values"]["broken"] <= 0.1


def test_the_runtime_block_decides_and_refuses_observations_outside_the_domain(workdir, monkeypatch, capsys):
    invoke("select", workdir / "runs" / "pump", "--constraint", "broken<=0.1", "--prefer", "cost")
    monkeypatch.chdir(workdir)
    scope: dict = {}
    exec(compile(python_blocks()[1], "tutorial.md", "exec"), scope)
    assert "est=5, load=0 is outside the domain" in capsys.readouterr().out
    urc = scope["urc"]
    assert set(urc.decide({"est": 0, "load": 1})) == {"c"} and 1 <= urc.decide([1, 1])["c"] <= 8
    with pytest.raises(scope["ObservationError"], match="no service is ever consulted"):
        urc.decide({"est": 2, "load": 0})


def test_simulating_the_model_file_agrees_with_model_checking(workdir):
    run = workdir / "runs" / "pump"
    invoke("select", run, "--constraint", "broken<=0.1", "--prefer", "cost")
    result = invoke(
        "simulate",
        MODEL,
        "--props",
        PROPS,
        "--policy",
        run / "controller.json",
        "--episodes",
        "3000",
        "--seed",
        "3",
        "--json",
    )
    estimates = json.loads(result.stdout)
    assert [e["objective"] for e in estimates] == ["broken", "cost"]
    assert all(e["within_interval"] for e in estimates), estimates
    controller = json.loads((run / "controller.json").read_text())
    for estimate in estimates:  # the model file gives the same model-checked values as the run
        assert estimate["model_checked"] == pytest.approx(controller["values"][estimate["objective"]], rel=1e-9)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--policy", "c.json"], "needs --props FILE.pctl"),
        (["--props", str(PROPS), "--policy", "p.csv"], "--policy must be a controller file"),
    ],
)
def test_simulating_a_model_file_needs_properties_and_a_controller(args, message):
    result = runner.invoke(app, ["simulate", str(MODEL), *args])
    assert result.exit_code == 2
    assert message in result.stderr
