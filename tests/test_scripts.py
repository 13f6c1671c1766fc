"""The Python API from plain script files and from stdin, in a subprocess, without an
``if __name__ == "__main__":`` guard (as most scripts are written): the worker processes
must not re-run the user's main module, and a worker that dies ends the call in one
:class:`parley.WorkerError`, never a hang."""

from __future__ import annotations

import multiprocessing
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from parley_core.errors import WorkerError
from parley_core.evaluate.pool import default_workers, spawn_pool

ROOT = Path(__file__).resolve().parents[1]


def _python(path: Path | None, cwd: Path, stdin: str | None = None, timeout: float = 60) -> subprocess.CompletedProcess:
    command = [sys.executable, str(path) if path else "-"]
    return subprocess.run(command, cwd=cwd, input=stdin, capture_output=True, text=True, timeout=timeout)


UNGUARDED_POOL = """
from parley_core.evaluate.pool import spawn_pool

with spawn_pool(2) as pool:
    print("sum", sum(pool.submit(abs, -i).result() for i in range(10)))
"""


@pytest.mark.parametrize("how", ["file", "stdin"])
def test_a_pool_starts_from_an_unguarded_script(tmp_path, how):
    script = tmp_path / "pool.py"
    script.write_text(UNGUARDED_POOL)
    result = _python(script if how == "file" else None, tmp_path, None if how == "file" else UNGUARDED_POOL)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split() == ["sum", "45"]
    assert "bootstrapping phase" not in result.stderr


CRASH = """
import ctypes, time
import parley
from parley_core.evaluate.pool import spawn_pool

start = time.monotonic()
with spawn_pool(2) as pool:
    try:
        pool.submit(ctypes.string_at, 0).result()  # reads address 0: a segfault in the worker
    except parley.WorkerError as error:
        print("caught", round(time.monotonic() - start), error)
"""


def test_a_worker_that_crashes_ends_in_one_parley_error(tmp_path):
    script = tmp_path / "crash.py"
    script.write_text(CRASH)
    result = _python(script, tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    (line,) = result.stdout.splitlines()
    caught, seconds, message = line.split(" ", 2)
    assert caught == "caught" and int(seconds) < 20
    assert "worker process ended" in message and "SIGSEGV" in message and "--workers 1" in message


def _in_a_daemon(answer) -> None:
    try:
        spawn_pool(2)
    except WorkerError as error:
        answer.put((default_workers(4), str(error)))


def test_a_daemonic_process_works_in_itself():
    context = multiprocessing.get_context("spawn")
    answer = context.Queue()
    process = context.Process(target=_in_a_daemon, args=(answer,), daemon=True)
    process.start()
    workers, message = answer.get(timeout=60)
    process.join(30)
    assert workers == 1  # the evaluators work in the process itself, with the same values
    assert "daemonic" in message


def _readme_block() -> str:
    (block,) = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.S)
    return block


README_CHECK = """
print("front", len(run.front.to_pandas()))
print("decision", urc.decide({"xhat": 0, "yhat": 0}))
print("loaded", parley.load(run.directory) == run)
"""


@pytest.mark.slow
@pytest.mark.parametrize("how", ["file", "stdin"])
def test_the_readmes_example_as_a_plain_script(tmp_path, how):
    """README's block verbatim (the default run of ``parley run robot_grid``), then its
    documented results printed."""
    text = _readme_block() + README_CHECK
    script = tmp_path / "readme.py"
    script.write_text(text)
    result = _python(script if how == "file" else None, tmp_path, None if how == "file" else text, timeout=400)
    assert result.returncode == 0, result.stderr[-3000:]
    lines = dict(line.split(" ", 1) for line in result.stdout.splitlines() if " " in line)
    assert int(lines["front"]) > 10
    assert re.fullmatch(r"\{'c': \d+\}", lines["decision"])
    assert lines["loaded"] == "True"
    assert (tmp_path / "runs").is_dir()


@pytest.mark.slow
@pytest.mark.parametrize("how", ["file", "stdin"])
def test_the_api_pages_examples_as_one_plain_script(tmp_path, how):
    """docs/api.md's blocks in order, as one script without a guard: a file, or stdin."""
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "api.md").read_text(), flags=re.S)
    for name in ("pump.prism", "pump.pctl"):
        shutil.copy(ROOT / "docs" / "tutorial" / name, tmp_path / name)
    text = "\n".join(blocks) + textwrap.dedent(README_CHECK)
    script = tmp_path / "api.py"
    script.write_text(text)
    result = _python(script if how == "file" else None, tmp_path, None if how == "file" else text, timeout=900)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "loaded True" in result.stdout
    assert "robot_grid" in result.stdout and "holes" in result.stdout
    assert (tmp_path / "runs" / "demo" / "controller.json").is_file()
