"""Importing parley changes no process-wide state: not matplotlib's backend or settings,
not Storm's log level, not the warnings filters, logging, numpy's error handling, the
environment or signal handlers (tests/import_probe.py imports every module in a fresh
interpreter and compares)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

PROBE = Path(__file__).with_name("import_probe.py")


def probe(*extra: str, path: Path | None = None) -> dict:
    env = dict(os.environ)
    env.pop("MPLBACKEND", None)
    if path is not None:
        env["PYTHONPATH"] = str(path) + os.pathsep + env.get("PYTHONPATH", "")
    done = subprocess.run(
        [sys.executable, str(PROBE), *extra], capture_output=True, text=True, env=env, timeout=300, check=False
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_importing_every_module_changes_no_global_state():
    found = probe()
    assert found["modules"] > 100  # parley, every parley_core module and the plugins
    assert found["changed"] == []


@pytest.mark.slow
def test_the_probe_sees_a_module_that_meddles(tmp_path):
    (tmp_path / "meddler.py").write_text(
        "import warnings, matplotlib\n"
        "from parley_core.prism.program import quiet_storm\n"
        "matplotlib.use('pdf')\n"
        "warnings.simplefilter('ignore')\n"
        "quiet_storm()\n"
    )
    found = probe("meddler", path=tmp_path)
    assert {"matplotlib backend", "warnings filters", "Storm's log level"} <= set(found["changed"])
