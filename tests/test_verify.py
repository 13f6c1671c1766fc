"""Verification: a disagreement between the search's evaluator and Storm is a defect that
stops the run (exit status 3) and writes nothing; agreement is measured and recorded."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from parley_core.cli import app
from parley_core.errors import EvaluatorDisagreement
from parley_core.quotient import kernels
from parley_core.testing import family, values
from parley_core.verify import TOLERANCE, check_with_storm, differences

QUICK = ["--set", "size=5", "--set", "seed=1", "--set", "max_interval=4", "--set", "horizon=45", "--workers", "1"]


def test_a_wrong_fast_evaluator_stops_the_run_with_exit_status_3(tmp_path, monkeypatch):
    right = kernels.cumulative

    def wrong(*args):
        return right(*args) * (1 + 1e-6)  # the cost objective, a millionth too high

    monkeypatch.setattr(kernels, "cumulative", wrong)
    out = tmp_path / "run"
    result = CliRunner().invoke(
        app, ["run", "robot_grid", *QUICK, "--population", "6", "--generations", "2", "--out", str(out)]
    )
    assert result.exit_code == 3, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        "error: parley defect: the search's evaluator and Storm disagree on policy "
    )
    assert "objective cost" in lines[0] and "against Storm's" in lines[0]
    assert not out.exists()


def test_an_agreeing_run_records_the_agreement(tmp_path):
    out = tmp_path / "run"
    result = CliRunner().invoke(
        app, ["run", "robot_grid", *QUICK, "--population", "6", "--generations", "2", "--out", str(out)]
    )
    assert result.exit_code == 0, result.stderr
    verification = json.loads((out / "summary.json").read_text())["verification"]
    assert verification["by"] == "storm" and verification["tolerance"] == TOLERANCE
    assert verification["baselines"] == 4 and 0 <= verification["max_relative_difference"] <= TOLERANCE


def test_the_baselines_are_checked_too(toy):
    toy_family = family(toy)
    rows = np.array([p.values for p in toy_family.baseline_policies()])
    right = values(toy_family, rows)
    names = ["baseline every-1", "baseline every-2", "baseline every-3"]
    verification, checked = check_with_storm(toy_family, rows, right, workers=1, names=names, baselines=3)
    assert verification.baselines == 3 and verification.policies == 0 and (checked == right).all()
    wrong = right.copy()
    wrong[1, 1] *= 1 + 1e-8
    with pytest.raises(EvaluatorDisagreement, match="policy baseline every-2, objective healthy"):
        check_with_storm(toy_family, rows, wrong, workers=1, names=names)


def test_differences_treat_infinities_as_values():
    absolute, relative = differences(np.array([[np.inf, 1.0, 2e6]]), np.array([[np.inf, np.inf, 2e6 + 1]]))
    assert list(absolute[0]) == [0.0, np.inf, 1.0]
    assert relative[0][2] == pytest.approx(5e-7)
