"""A plugin author's mistakes, made in the example plugin installed beside the built-ins:
each ends in one line that names what is wrong (exit status 2 on the command line), and
the conformance suite reports a contract failure in its message alone."""

from __future__ import annotations

import subprocess
import sys

import pytest
from test_plugins import _install_example, _parley

RUN = ("run", "thermostat", "--set", "rounds=3", "--population", "4", "--generations", "1", "--workers", "1")

MISTAKES = [
    ("service name with a space", 'Service(name="calibration"', 'Service(name="battery calibration"',
     "service name 'battery calibration' is not an identifier: use letters, digits and underscores, "
     "not starting with a digit (say 'battery_calibration')"),
    ("objective over a missing label", '"uncomfortable"]', '"too_hot"]',
     "objective 'discomfort' (P=? [F<=6 \"too_hot\"]) uses label \"too_hot\", which the thermostat model lacks; "
     "its labels: \"uncomfortable\""),
    ("undeclared identifier in the model", 'probability="1-2*drift"', 'probability="1-2*drif"',
     "the thermostat model does not parse: 'drif' (line "),
    ("undeclared identifier in an objective", 'f\'P=? [F<={horizon} "uncomfortable"]\'',
     "f'P=? [F<={horizon} temp=hot]'", "objective 'discomfort' 'P=? [F<=6 temp=hot]' does not parse: "
     "'hot' is not declared in the model"),
]  # fmt: skip


@pytest.mark.parametrize(("label", "old", "new", "message"), MISTAKES, ids=[m[0] for m in MISTAKES])
def test_a_plugin_mistake_is_one_line_naming_it(tmp_path, label, old, new, message):
    env = _install_example(tmp_path)
    source = tmp_path / "parley_thermostat.py"
    assert old in source.read_text(), label
    source.write_text(source.read_text().replace(old, new))
    ran = _parley(env, *RUN, "--out", str(tmp_path / "run"))
    assert ran.returncode == 2, ran.stderr[-2000:]
    (line,) = ran.stderr.strip().splitlines()
    assert line.startswith("error: ") and message in line, line


CONTRACT = [
    ("an option without help", 'rounds: int = option(20, "rounds the objectives look at", positive)',
     "rounds: int = 20", "thermostat: option(s) rounds have no help text"),
    ("options not frozen", "@frozen(kw_only=True)\nclass ThermostatOptions", "@define(kw_only=True)\nclass ThermostatOptions",
     "thermostat: the options class ThermostatOptions is not frozen; use @frozen"),
]  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize(("label", "old", "new", "message"), CONTRACT, ids=[c[0] for c in CONTRACT])
def test_the_conformance_suite_says_what_breaks_the_contract_in_a_few_lines(
    tmp_path, pytester, monkeypatch, label, old, new, message
):
    site = tmp_path / "site"
    site.mkdir()
    env = _install_example(site)
    source = site / "parley_thermostat.py"
    text = source.read_text().replace("from attrs import frozen,", "from attrs import define, frozen,")
    assert old in text, label
    source.write_text(text.replace(old, new))
    monkeypatch.setenv("PYTHONPATH", env["PYTHONPATH"])
    result = pytester.runpytest_subprocess("--parley-case", "thermostat", "-p", "no:cacheprovider", "-rf")
    result.assert_outcomes(passed=4, failed=1)
    failure = result.stdout.str()
    assert f"ConformanceError: {message}" in failure
    section = failure[failure.index("= FAILURES =") : failure.index("short test summary")]
    assert len(section.splitlines()) < 12, section  # the message, not parley's frames
    assert "parley_core/" not in section and "Traceback" not in section


def test_a_hook_function_without_hookimpl_says_so(tmp_path):
    env = _install_example(tmp_path)
    source = tmp_path / "parley_thermostat.py"
    source.write_text(source.read_text().replace("@hookimpl\ndef parley_case_studies(", "def parley_case_studies("))
    listed = subprocess.run(
        [sys.executable, "-m", "parley_core", "list"], env=env, capture_output=True, text=True, timeout=120
    )
    assert listed.returncode == 0 and "robot_grid" in listed.stdout
    assert "was loaded but provides no case study" in listed.stderr
