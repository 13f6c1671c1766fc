"""The library API (`import parley`): the same run directories as the CLI, the same objects
from disk, no printing, parley's errors, and docs/api.md's examples as written."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import attrs
import pytest
from typer.testing import CliRunner

import parley
from parley_core.cli import app
from parley_core.search.settings import default

DOCS = Path(__file__).resolve().parents[1] / "docs"
SMALL = {"population": 10, "generations": 2}
runner = CliRunner()


def comparable(summary: dict) -> dict:
    """summary.json without what differs between two runs of the same arguments: times."""
    if isinstance(summary, dict):
        return {
            k: comparable(v) for k, v in summary.items() if k not in ("seconds", "timings_seconds", "evaluator_details")
        }
    if isinstance(summary, list):
        return [comparable(v) for v in summary]
    return summary


def same_directories(a: Path, b: Path) -> None:
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir())
    for name in names:
        if name.endswith(".png"):
            continue
        if name == "summary.json":
            assert comparable(json.loads((a / name).read_text())) == comparable(json.loads((b / name).read_text()))
        else:
            assert (a / name).read_bytes() == (b / name).read_bytes(), name


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    root = tmp_path_factory.mktemp("api")
    run = parley.run("robot_grid", size=4, seed=3, **SMALL, out=root / "api", progress=False)
    return root, run


@pytest.mark.slow
def test_the_api_and_the_cli_write_the_same_run_directory(made):
    root, run = made
    result = runner.invoke(
        app,
        ["run", "robot_grid", "--set", "size=4", "--seed", "3", "--population", "10", "--generations", "2"]
        + ["--out", str(root / "cli")],
    )
    assert result.exit_code == 0, result.stderr
    same_directories(root / "api", root / "cli")
    assert attrs.evolve(parley.load(root / "cli"), directory=run.directory) == run


def test_a_loaded_run_is_the_run(made):
    root, run = made
    again = parley.load(root / "api")
    assert again == run and again.result is None and run.result is not None
    assert [p.name for p in run.front.policies] == [p.name for p in run.result.front.policies]
    assert run.front.values == run.result.front.values
    assert run.baseline.values == run.result.baseline.values
    assert [p.values for p in run.baseline.policies] == [p.values for p in run.result.baseline.policies]
    assert run.summary.seed == 3 and run.summary.options["size"] == 4
    assert run.summary.evaluations == run.result.search.evaluations
    assert run.optimality is not None and run.optimality.points == tuple(
        tuple(r) for r in run.result.bound.points.tolist()
    )


def test_select_gives_the_controller_of_parley_select(made, tmp_path):
    root, run = made
    choice = run.select(["success>=0.3"], prefer="cost")
    result = runner.invoke(
        app,
        ["select", str(root / "api"), "--constraint", "success>=0.3", "--prefer", "cost"]
        + ["--out", str(tmp_path / "c.json"), "--json"],
    )
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["policy"] == choice.name
    choice.controller().save(tmp_path / "api.json")
    assert json.loads((tmp_path / "api.json").read_text()) == json.loads((tmp_path / "c.json").read_text())
    assert run.knee().name == run.summary.selected
    assert dict(choice.values) == dict(
        zip(["success", "cost"], run.front.values[run.front.policies.index(choice.policy)])
    )


def test_front_as_a_table(made):
    _, run = made
    frame = run.front.to_pandas()
    assert list(frame.columns) == ["success", "cost"] and list(frame.index) == [p.name for p in run.front.policies]
    assert frame.to_numpy().tolist() == [list(v) for v in run.front.values]
    page = run._repr_html_()
    assert f"{len(run.front)} policies" in page and run.front.policies[0].name in page


def test_plot_is_a_figure_of_the_front(made):
    _, run = made
    figure = run.plot()
    axes = figure.axes[0]
    assert axes.get_xlabel() == "cost (min)" and axes.get_ylabel() == "success (max)"
    counts = sorted(len(c.get_offsets()) for c in axes.collections if hasattr(c, "get_offsets"))
    assert len(run.front) in counts and len(run.baseline) in counts


def test_nothing_is_printed_and_errors_are_parleys(capfd, tmp_path):
    with pytest.raises(parley.OptionError, match="unknown option 'nope'"):
        parley.run("robot_grid", nope=1, progress=False)
    with pytest.raises(parley.ParleyError, match="no_such_case"):
        parley.run("no_such_case", progress=False)
    with pytest.raises(parley.OptionError, match="does not exist"):
        parley.load(tmp_path / "missing")
    run = parley.run("robot_grid", size=3, **SMALL, bound="none", out=tmp_path / "quiet", progress=False)
    assert run.optimality is None
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_a_reporter_receives_the_stages(tmp_path):
    class Recorder:
        def __init__(self):
            self.stages, self.done = [], 0

        def stage(self, name, total=None):
            self.stages.append(name)

        def advance(self, n=1):
            self.done += n

        def note(self, text):
            pass

    recorder = Recorder()
    parley.run("robot_grid", size=3, **SMALL, bound="none", out=tmp_path / "r", progress=recorder)
    assert recorder.stages[:2] == ["build model", "augment"] and "search" in recorder.stages
    assert recorder.stages[-1] == "write report" and recorder.done > 0


def test_the_defaults_are_the_clis():
    import inspect

    parameters = inspect.signature(parley.run).parameters
    assert parameters["population"].default == default("population")
    assert parameters["seed"].default == default("seed")


def python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", (DOCS / "api.md").read_text(), flags=re.S)


@pytest.mark.slow
def test_the_docs_examples_run(tmp_path, monkeypatch, capsys):
    for name in ("pump.prism", "pump.pctl"):
        shutil.copy(DOCS / "tutorial" / name, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    blocks = python_blocks()
    assert len(blocks) >= 9
    for block in blocks:
        exec(compile(block, "docs/api.md", "exec"), namespace)
    out = capsys.readouterr().out
    assert namespace["again"] == namespace["run"]
    with pytest.raises(parley.OptionError) as refused:  # the docs' bad input, to know its message
        parley.run("robot_grid", horizon=0, progress=False)
    assert str(refused.value) in out.splitlines()  # the block printed exactly that one line
    assert (tmp_path / "runs" / "demo" / "controller.json").is_file()
    assert namespace["campaign"].planned == 4 and not namespace["campaign"].failures
    assert namespace["exact"].optimality.method
    validated = namespace["checked"].policies
    assert validated and all([e.objective for e in p.estimates] == ["success", "energy"] for p in validated)
    assert "robot_grid" in out and "holes" in out
    assert namespace["report"].page.is_file() and "| all |" in out


@pytest.mark.slow
def test_the_readmes_example_runs(tmp_path, monkeypatch):
    """README's block as written, with a small budget and the run directory in tmp_path."""
    readme = (DOCS.parent / "README.md").read_text()
    (block,) = re.findall(r"```python\n(.*?)```", readme, flags=re.S)
    real = parley.run

    def small(case, **kwargs):
        return real(case, **{**kwargs, **SMALL, "progress": False, "out": tmp_path / "readme"})

    monkeypatch.setattr(parley, "run", small)
    namespace: dict = {}
    exec(compile(block, "README.md", "exec"), namespace)
    assert namespace["run"].directory == tmp_path / "readme" and "urc" in namespace
