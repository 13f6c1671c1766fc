"""Worker processes end with the process that started them, and at once on an abort."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time

import pytest

from parley_core.evaluate.pool import spawn_pool, stop_pool


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        with open(f"/proc/{pid}/stat") as handle:  # a zombie is gone too
            return handle.read().split()[2] != "Z"
    except (FileNotFoundError, ProcessLookupError):  # it ended between the two looks (reading gives ESRCH)
        return False


def _wait_gone(pids: list[int], seconds: float = 10.0) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if not any(_alive(p) for p in pids):
            return True
        time.sleep(0.2)
    return False


@pytest.mark.slow
def test_workers_end_when_their_parent_is_killed(tmp_path):
    script = tmp_path / "parent.py"
    script.write_text(
        textwrap.dedent(
            """
            import os, time
            from parley_core.evaluate.pool import spawn_pool

            def stuck(_):
                time.sleep(600)

            if __name__ == "__main__":
                pool = spawn_pool(2)
                futures = [pool.submit(stuck, i) for i in range(2)]
                time.sleep(2)
                print(" ".join(str(p) for p in pool._processes), flush=True)
                os._exit(0)  # dies without shutting the pool down, as a killed parley would
            """
        )
    )
    result = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=60)
    pids = [int(p) for p in result.stdout.split()]
    assert len(pids) == 2
    assert _wait_gone(pids), "workers outlived their parent"


@pytest.mark.slow
def test_an_abort_ends_busy_workers_at_once():
    pool = spawn_pool(2)
    for _ in range(2):
        pool.submit(time.sleep, 600)
    time.sleep(1.5)
    pids = list(pool._processes)
    start = time.monotonic()
    stop_pool(pool, abort=True)
    assert time.monotonic() - start < 5
    assert _wait_gone(pids)
