"""The parley command runs watched (parley_core.guard): a crash of its process, inside Storm
say, ends in one line and exit status 3, not a bare segmentation fault."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

GUARD = "import sys; from parley_core.guard import supervise; sys.exit(supervise([sys.executable, '-c', {code!r}]))"


def _guarded(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", GUARD.format(code=code)], capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize(
    ("code", "said"),
    [
        ("import ctypes; ctypes.string_at(0)", "it crashed (SIGSEGV), most likely inside Storm"),
        ("import os, signal; os.kill(os.getpid(), signal.SIGKILL)", "most likely by the system's memory killer"),
    ],
    ids=["segfault", "killed"],
)
def test_a_crash_of_the_command_is_one_line_and_status_3(code, said):
    ended = _guarded("import faulthandler; faulthandler.disable(); " + code)
    assert ended.returncode == 3
    (line,) = ended.stderr.strip().splitlines()
    assert line.startswith("error: parley's process ended abnormally: ") and said in line


def test_the_exit_status_of_the_command_passes_through():
    assert _guarded("import sys; sys.exit(2)").returncode == 2
    assert _guarded("pass").returncode == 0


def test_the_installed_command_is_guarded_and_named_parley():
    command = Path(sys.executable).parent / "parley"
    if not command.is_file():
        pytest.skip("no parley script beside this interpreter (not installed)")
    shown = subprocess.run([str(command), "--version"], capture_output=True, text=True, timeout=60)
    assert shown.returncode == 0 and shown.stdout.startswith("parley ")
    helped = subprocess.run([str(command), "run", "--help"], capture_output=True, text=True, timeout=60)
    assert helped.stdout.startswith("Usage: parley run [OPTIONS] {CASE}")
    refused = subprocess.run([str(command), "run", "nope"], capture_output=True, text=True, timeout=60)
    assert refused.returncode == 2 and refused.stderr.strip().startswith("error: unknown case study 'nope'")


def test_a_killed_guard_leaves_no_command_running(tmp_path):
    import os
    import signal
    import time

    marker = tmp_path / "child.pid"
    code = f"import os, time; open({str(marker)!r}, 'w').write(str(os.getpid())); time.sleep(60)"
    guard = subprocess.Popen([sys.executable, "-c", GUARD.format(code=code)])
    for _ in range(100):
        if marker.is_file() and marker.read_text():
            break
        time.sleep(0.1)
    child = int(marker.read_text())
    guard.send_signal(signal.SIGKILL)
    guard.wait()
    for _ in range(50):
        try:
            os.kill(child, 0)
        except ProcessLookupError:
            return
        try:
            with open(f"/proc/{child}/stat") as handle:
                if handle.read().split()[2] == "Z":
                    return
        except (FileNotFoundError, ProcessLookupError):  # it ended between the two looks
            return
        time.sleep(0.1)
    raise AssertionError("the command outlived its killed guard")
