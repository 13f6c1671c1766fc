"""A user's own PRISM model: `parley augment`, `parley synthesize`, their errors, and fuzzing."""

from __future__ import annotations

import csv
import json

import pytest
import stormpy
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from conftest import TOY, storm_values
from parley_core.cli import app

runner = CliRunner()

# The toy of conftest.py as a user would write it: c defined (its value is kept as a
# baseline) and used in the counter's bound, like the paper's published baseline models.
USER = TOY.replace("const int c;", "const int c = 2;").replace("step : [1..K] init 1;", "step : [1..c] init 1;")
PROPS = """// name: cost, min
R{"cost"}=? [C<=10]
// the probability of a degraded server within 3 steps
// name: degraded, min
P=? [F<=3 !"healthy"]
"""


@pytest.fixture
def files(tmp_path):
    (tmp_path / "server.prism").write_text(USER)
    (tmp_path / "server.pctl").write_text(PROPS)
    return tmp_path


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_augment_writes_a_parametric_model_with_exactly_the_decision_constants(files):
    result = invoke(
        "augment", files / "server.prism", "--decision", "c=1..3", "--observe", "phase", "--out", files / "aug.prism"
    )
    assert result.exit_code == 0, result.stderr
    assert "2 of 2 observation valuations of (phase) consult a service" in result.stderr
    program = stormpy.parse_prism_program(str(files / "aug.prism"))
    assert sorted(c.name for c in program.constants if not c.defined) == ["c_0", "c_1"]
    # the counter's bound c became the decisions' largest value
    assert "step: [1..3]" in (files / "aug.prism").read_text()
    # values: the policy c_0=1, c_1=3 equals the original model with c as that function of phase
    by_hand = USER.replace("const int c = 2;", "formula c = (phase=0 ? 1 : 3);").replace(
        "step : [1..c]", "step : [1..3]"
    )
    formulas = ['R{"cost"}=? [C<=10]', 'P=? [F<=3 !"healthy"]']
    assert storm_values((files / "aug.prism").read_text(), formulas, {"c_0": 1, "c_1": 3}) == pytest.approx(
        storm_values(by_hand, formulas), abs=1e-12
    )


@pytest.mark.parametrize(
    ("form", "declaration"), [("evochecker", "evolve int c_0 [1..3];"), ("paynt", "hole int c_0 in {1,2,3};")]
)
def test_exports_for_other_tools(files, form, declaration):
    result = invoke("augment", files / "server.prism", "--decision", "c=1..3", "--observe", "phase", "--format", form)
    assert result.exit_code == 0, result.stderr
    assert declaration in result.stdout


def test_synthesize_runs_the_pipeline_on_a_user_model(files):
    out = files / "run"
    result = invoke(
        "synthesize",
        files / "server.prism",
        "--props",
        files / "server.pctl",
        "--decision",
        "c=1..3",
        "--observe",
        "phase",
        "--population",
        "10",
        "--generations",
        "4",
        "--workers",
        "1",
        "--out",
        out,
    )
    assert result.exit_code == 0, result.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert [o["name"] for o in summary["objectives"]] == ["cost", "degraded"]
    assert summary["front"]["hypervolume"] >= summary["baseline"]["hypervolume"]
    with open(out / "baseline.csv") as handle:
        names = [row["policy"] for row in csv.DictReader(handle)]
    assert names == ["model (c=2)", "c=1", "c=3"]  # the model's own value, then the other fixed ones
    with open(out / "policies.csv") as handle:
        rows = list(csv.DictReader(handle))
    with open(out / "front.csv") as handle:
        front = list(csv.DictReader(handle))
    model = (out / "model.prism").read_text()
    for policy, values in zip(rows, front):
        constants = {k: int(v) for k, v in policy.items() if k != "policy"}
        expected = storm_values(model, ['R{"cost"}=? [C<=10]', 'P=? [F<=3 !"healthy"]'], constants)
        assert [float(values["cost"]), float(values["degraded"])] == pytest.approx(expected, rel=1e-6, abs=1e-7)


def test_synthesize_exact_proves_the_whole_front_and_refuses_another_bound(files):
    out = files / "run"
    common = [files / "server.prism", "--props", files / "server.pctl", "--decision", "c=1..3",
              "--observe", "phase", "--population", "10", "--generations", "2", "--workers", "1"]  # fmt: skip
    result = invoke("synthesize", *common, "--exact", "--out", out)
    assert result.exit_code == 0, result.stderr
    optimality = json.loads((out / "summary.json").read_text())["optimality"]
    assert optimality["exact"] and optimality["search"]["stopped_by"] == "complete"
    assert "exact: the front is the family's whole Pareto front" in result.stdout
    refused = invoke("synthesize", *common, "--exact", "--bound", "belief", "--out", files / "other")
    assert refused.exit_code == 2 and "--exact" in refused.stderr and "Traceback" not in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1


def test_exact_has_no_time_limit_unless_bound_time_gives_one(files, monkeypatch):
    import parley_core.api.commands as commands

    asked = []
    monkeypatch.setattr(commands, "synthesize", lambda *args, **kw: asked.append((kw["bound"], kw["bound_time"])))
    common = [files / "server.prism", "--props", files / "server.pctl", "--decision", "c=1..3"]
    for extra in (["--exact"], ["--exact", "--bound-time", "5"], [], ["--bound", "refine"]):
        invoke("synthesize", *common, *extra)
    assert asked == [("refine", None), ("refine", 5.0), ("pareto", 60.0), ("refine", 60.0)]


def test_constraints_keep_only_policies_that_meet_them(files):
    out = files / "run"
    result = invoke(
        "synthesize",
        files / "server.prism",
        "--props",
        files / "server.pctl",
        "--decision",
        "c=1..3",
        "--observe",
        "phase",
        "--population",
        "10",
        "--generations",
        "3",
        "--workers",
        "1",
        "--constraint",
        "degraded<=0.5",
        "--out",
        out,
    )
    assert result.exit_code == 0, result.stderr
    with open(out / "front.csv") as handle:
        assert all(float(row["degraded"]) <= 0.5 for row in csv.DictReader(handle))
    impossible = invoke(
        "synthesize",
        files / "server.prism",
        "--props",
        files / "server.pctl",
        "--decision",
        "c=1..3",
        "--observe",
        "phase",
        "--population",
        "6",
        "--generations",
        "1",
        "--workers",
        "1",
        "--constraint",
        "cost<=-1",
        "--out",
        files / "none",
    )
    assert impossible.exit_code == 2
    assert "no evaluated policy meets cost<=-1" in impossible.stderr


def _error(result, message):
    assert result.exit_code == 2, (result.stdout, result.stderr, result.exception)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], result.stderr


@pytest.mark.parametrize(
    ("model", "props", "args", "message"),
    [
        (
            USER.replace("endmodule", "  [] h=2 -> (h'=0)\nendmodule"),
            PROPS,
            [],
            'does not parse: Parsing error at 12:1: expecting ";"',
        ),
        (USER.replace("dtmc", "mdp"), PROPS, [], "is a MDP but parley needs a DTMC"),
        (USER, PROPS, ["--decision", "q=1..3"], "--decision q: the model declares no constant of that name"),
        (
            USER.replace("const int c = 2;", "const int c;\nconst int d = 1;"),
            PROPS,
            ["--decision", "d=1..3"],
            "leaves constants c undefined",
        ),
        (
            USER.replace("const int c = 2;", "const int c = 2;\nconst int d = 1;"),
            PROPS,
            ["--decision", "c=1..3", "--decision", "d=1..3"],
            "constant(s) d are used in no command",
        ),
        (USER, PROPS, ["--observe", "nothing"], "--observe variable 'nothing' is not a variable of the model"),
        (USER, PROPS, ["--decision", "c=3..1"], "the range 3..1 is empty"),
        (USER, PROPS, ["--decision", "c=a..b"], "LOW and HIGH must be integers"),
        (USER, PROPS, ["--decision", "c"], "malformed --decision 'c'"),
        (USER, '// name: cost, min\nR{"cost"}=? [C<=\n', [], "does not parse"),
        (
            USER,
            '// name: cost, min\nR{"energy"}=? [C<=10]\n',
            [],
            'uses reward structure "energy", which the model lacks',
        ),
        (USER, '// name: gone, max\nP=? [F "nolabel"]\n', [], "nolabel"),
        (USER, 'R{"cost"}=? [C<=10]\n', [], "objective objective1 has no direction"),
        (USER, '// name: cost, sideways\nR{"cost"}=? [C<=10]\n', [], "direction 'sideways' is neither max nor min"),
        (USER, "", [], "holds no property"),
    ],
)
def test_user_errors(tmp_path, model, props, args, message):
    (tmp_path / "m.prism").write_text(model)
    (tmp_path / "p.pctl").write_text(props)
    decision = [] if any(a == "--decision" for a in args) else ["--decision", "c=1..3"]
    observe = [] if "--observe" in args else ["--observe", "phase"]
    result = invoke(
        "synthesize",
        tmp_path / "m.prism",
        "--props",
        tmp_path / "p.pctl",
        *decision,
        *observe,
        *args,
        "--population",
        "4",
        "--generations",
        "1",
        "--workers",
        "1",
        "--out",
        tmp_path / "out",
    )
    _error(result, message)


def test_missing_files_and_existing_output(files):
    _error(invoke("augment", files / "nope.prism", "--decision", "c=1..3", "--observe", "phase"), "model file")
    (files / "taken.prism").write_text("x")
    _error(
        invoke(
            "augment",
            files / "server.prism",
            "--decision",
            "c=1..3",
            "--observe",
            "phase",
            "--out",
            files / "taken.prism",
        ),
        "exists; choose another --out or add --force",
    )
    (files / "busy").mkdir()
    (files / "busy" / "keep").write_text("x")
    _error(
        invoke(
            "synthesize",
            files / "server.prism",
            "--props",
            files / "server.pctl",
            "--decision",
            "c=1..3",
            "--observe",
            "phase",
            "--out",
            files / "busy",
        ),
        "exists and is not empty",
    )


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("step : [1..c]", "step : [1..1/0]", "variable step has a bound (1 / 0) that is not a finite integer"),
        ("const int c = 2;", "const int c = 1/0;", "constant c = (1 / 0) is not a finite integer"),
        ("[wait] step<c & h=1", "[wait] step<c & h=1/0", "Storm crashes (SIGFPE)"),
        # only the decision value c=3 divides by zero, and only in states where h=1
        ("[wait] step<c & h=1 ", "[wait] step<c & h=1 & h!=1/(c-3) ", "Storm crashes (SIGFPE)"),
    ],
)
def test_a_division_by_zero_is_an_error_not_a_crash(tmp_path, old, new, message):
    # Storm's parser accepts these and its builder then kills the process with SIGFPE
    assert old in USER
    (tmp_path / "m.prism").write_text(USER.replace(old, new))
    _error(invoke("augment", tmp_path / "m.prism", "--decision", "c=1..3", "--observe", "phase"), message)


MUTATIONS = [
    ("delete", None),
    ("duplicate", None),
    ("swap", None),
    ("insert", "("),
    ("insert", ";"),
    ("insert", "'"),
    ("insert", "c"),
    ("insert", "]"),
    ("insert", "step"),
    ("insert", "-"),
    ("insert", "\n"),
    ("insert", "1/0"),
]


@pytest.mark.slow
@settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(
    position=st.integers(0, len(USER) - 1),
    mutation=st.sampled_from(MUTATIONS),
    decision=st.sampled_from(
        ["c=1..3", "c=0..2", "c=3..1", "c=1..3:threshold", "c=1..", "k=1..3", "c=-2..2", "c=1..3:often"]
    ),
    observe=st.sampled_from(["phase", "h,phase", "step", "nothing", "", "phase,phase"]),
    props=st.sampled_from(
        [PROPS, PROPS.replace("min", "max"), "P=? [F h=0]\n", 'R{"cost"}=? [C]\n// name: x, min\n', "junk\n"]
    ),
)
def test_fuzz_no_input_ends_in_a_traceback(tmp_path, position, mutation, decision, observe, props):
    kind, text = mutation
    if kind == "delete":
        model = USER[:position] + USER[position + 1 :]
    elif kind == "duplicate":
        model = USER[:position] + USER[position] + USER[position:]
    elif kind == "swap":
        model = (
            USER[:position] + USER[position + 1 : position + 2] + USER[position : position + 1] + USER[position + 2 :]
        )
    else:
        model = USER[:position] + text + USER[position:]
    (tmp_path / "m.prism").write_text(model)
    (tmp_path / "p.pctl").write_text(props)
    out = tmp_path / f"out{position}"
    result = invoke(
        "synthesize",
        tmp_path / "m.prism",
        "--props",
        tmp_path / "p.pctl",
        "--decision",
        decision,
        "--observe",
        observe,
        "--population",
        "4",
        "--generations",
        "1",
        "--workers",
        "1",
        "--out",
        out,
        "--force",
    )
    assert result.exit_code in (0, 2), (model, decision, observe, props, result.stderr, result.exception)
    if result.exit_code == 2:
        assert result.stderr.startswith("error: ") and len(result.stderr.strip().splitlines()) == 1, result.stderr


@pytest.mark.parametrize(
    "change, message",
    [
        (("x : [0..3] init 0;", "x : [0..3];"), None),
        (("dtmc", "ctmc"), "is a CTMC but parley needs a DTMC"),
        (("const int c;", "const int c;\nconst int d = c+1;"), None),
    ],
)
def test_misleading_errors_say_what_is_wrong(tmp_path, change, message):
    """Errors a new user met on other projects' models: each names the real cause."""
    base = """dtmc
const int c;
module m
 x : [0..3] init 0;
 [a] x<c -> (x'=x+1);
 [b] x>=c -> (x'=0);
endmodule
rewards "r" true : 1; endrewards
"""
    text = base.replace(*change)
    if change[0].startswith("x :"):
        text += "init x=0 endinit\n"
        message = "has an init ... endinit block; parley needs exactly one initial state"
    if change[1].startswith("const int c;\nconst int d"):
        text = text.replace("x<c", "x<d").replace("x>=c", "x>=d")
        message = "uses service constant(s) c (through d) only through other constants"
    (tmp_path / "m.prism").write_text(text)
    (tmp_path / "p.pctl").write_text("// name: r, min\nR=? [C<=5]\n")
    result = invoke(
        "synthesize",
        tmp_path / "m.prism",
        "--props",
        tmp_path / "p.pctl",
        "--decision",
        "c=1..3",
        "--observe",
        "x",
        "--population",
        "4",
        "--generations",
        "1",
        "--workers",
        "1",
        "--out",
        tmp_path / "out",
    )
    _error(result, message)


@pytest.mark.parametrize(
    "formula, message",
    [
        ('P<0.1 [ F !"healthy" ]', "a bounded query with a yes/no answer; write it as P=? [...]"),
        ("R=? [ C<=5 ]", None),
    ],
)
def test_objectives_must_be_queries(tmp_path, formula, message):
    (tmp_path / "m.prism").write_text(USER)
    (tmp_path / "p.pctl").write_text(f"// name: o, min\n{formula}\n")
    result = invoke(
        "synthesize",
        tmp_path / "m.prism",
        "--props",
        tmp_path / "p.pctl",
        "--decision",
        "c=1..3",
        "--observe",
        "phase",
        "--population",
        "4",
        "--generations",
        "1",
        "--workers",
        "1",
        "--out",
        tmp_path / "out",
    )
    if message is None:
        assert result.exit_code == 0, result.stderr
    else:
        _error(result, message)
