"""The ``parley`` command runs in a child process of its own, watched by this guard.

A crash inside Storm's C++ code (a segmentation fault), or the kernel's memory killer,
would otherwise end the command with a bare "Segmentation fault" and a core dump. Watched,
it ends in one line that says what happened and exit status 3. Run directories are written
whole or not at all (they are staged, then renamed), so nothing partial is left. The guard
imports nothing heavy; Ctrl-C reaches the command itself (the same process group), which
stops cleanly; the guard waits for it.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys

GUARDED = "PARLEY_GUARDED"
"""Set in the command's own process: it runs the command instead of guarding it."""

CRASHED = 3
"""The exit status of a crash (as of any defect of parley's)."""


def explain(returncode: int) -> str:
    """The one line for a command killed by signal ``-returncode``."""
    try:
        name = signal.Signals(-returncode).name
    except ValueError:
        name = f"signal {-returncode}"
    if name == "SIGKILL":
        cause = "it was killed (SIGKILL), most likely by the system's memory killer: try a smaller instance"
    elif name in ("SIGSEGV", "SIGBUS", "SIGABRT", "SIGFPE", "SIGILL"):
        cause = f"it crashed ({name}), most likely inside Storm"
    else:
        cause = f"it was stopped by {name}"
    return (
        f"error: parley's process ended abnormally: {cause}; no partial run directory was left. "
        "Rerun the command, and report it with the command line if it recurs"
    )


def _end_with_the_guard() -> None:
    """In the child, before it runs: end it when the guard ends (Linux's parent-death
    signal), so that a guard killed outright leaves no command running on its own."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):  # not Linux: the child outlives a killed guard
        pass


def supervise(command: list[str]) -> int:
    """Run ``command`` (the parley command in a child process) to its end: its exit status,
    or :data:`CRASHED` with :func:`explain`'s line when a signal ended it."""
    child = subprocess.Popen(command, env={**os.environ, GUARDED: "1"}, preexec_fn=_end_with_the_guard)
    interrupt = signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the child's to handle
    terminate = signal.signal(signal.SIGTERM, lambda number, _frame: child.send_signal(number))
    try:
        returncode = child.wait()
    finally:
        signal.signal(signal.SIGINT, interrupt)
        signal.signal(signal.SIGTERM, terminate)
    if returncode < 0 and -returncode != signal.SIGINT:
        print(explain(returncode), file=sys.stderr)
        return CRASHED
    return 130 if returncode < 0 else returncode


def main() -> None:
    """The ``parley`` command: in its own process (:data:`GUARDED` set), or guarded."""
    if os.environ.get(GUARDED) == "1":
        from parley_core.cli import main as command

        command()
        return
    program = os.path.basename(sys.argv[0]) or "parley"
    os.environ.setdefault("PARLEY_PROGRAM", "parley" if program == "__main__.py" else program)
    sys.exit(supervise([sys.executable, "-m", "parley_core", *sys.argv[1:]]))
