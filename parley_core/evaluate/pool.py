"""Worker processes: how many, and a pool that starts them fresh (spawn, not fork).

Workers are spawned rather than forked so that no Storm or numba state of the parent is
shared, and by loky rather than by ``multiprocessing`` so that a worker does not run the
user's main module: the standard spawn re-imports it, which re-runs a plain script's
unguarded ``parley.run(...)`` in every worker and cannot import a script read from stdin.
A worker that dies (a crash in Storm, the memory killer) or cannot start ends its call in
one :class:`~parley_core.errors.WorkerError`, never a hang. A worker's per-process state
(the quotient solver, Storm's parsed program) is set by the pool's initializer or filled
on first use; that module-level cache, one per worker
process, is the one sanctioned exception to "no module state" (docs/architecture.md).
"""

from __future__ import annotations

import multiprocessing
import os
import re
import threading
import time
from collections.abc import Callable
from concurrent.futures import BrokenExecutor, Future
from typing import Any

from loky.backend.context import get_context
from loky.process_executor import ProcessPoolExecutor as _LokyExecutor

from parley_core.errors import WorkerError

_WORKER_STATE: dict[tuple[Callable[..., Any], Any], Any] = {}
"""Per worker process: what :func:`worker_state` made for the last task (the sanctioned cache)."""


def worker_state(make: Callable[[Any], Any], task: Any) -> Any:
    """``make(task)``, made once per process and task: a worker keeps only the last task's
    (a checker or solver of one family), so a pool that moves on frees the one before."""
    key = (make, task)
    state = _WORKER_STATE.get(key)
    if state is None:
        _WORKER_STATE.clear()
        state = _WORKER_STATE[key] = make(task)
    return state


def may_start_processes() -> bool:
    """False in a daemonic process (a Dask worker, a ``multiprocessing`` daemon), which may
    not start processes of its own."""
    return not multiprocessing.current_process().daemon


def default_workers(workers: int | None = None) -> int:
    """``workers`` if given, else one per core; at least 1; 1 where no process may be
    started (:func:`may_start_processes`): the work is done in this process, with the same
    values."""
    if not may_start_processes():
        return 1
    return max(1, workers if workers is not None else (os.cpu_count() or 1))


def _watch(parent: int) -> None:
    """End this worker when the process that started it is gone (killed, say, while the
    worker was deep inside Storm, where it would not notice its pipe closing)."""
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            os._exit(1)


def _start(initializer: Callable[..., Any] | None, initargs: tuple[Any, ...], parent: int) -> None:
    from parley_core.prism.program import quiet_storm

    threading.Thread(target=_watch, args=(parent,), daemon=True, name="parley-parent-watch").start()
    quiet_storm()  # a worker is an entry point: Storm's log level is set once per process
    if initializer is not None:
        initializer(*initargs)


def _crashed(error: BaseException) -> WorkerError:
    text = str(error)
    codes = re.search(r"exit codes of the workers are \{(.*?)\}", text)
    status = f" with exit status {codes.group(1)}" if codes else ""
    cause = "" if codes or not text.strip() else f" ({text.strip().splitlines()[0].rstrip('.')})"
    return WorkerError(
        f"a worker process ended{status} or could not start{cause}, and the work was stopped; "
        "rerun with --workers 1 (workers=1) to work in this process, and report it if it recurs"
    )


class _Linked(Future):
    """The caller's future of a pool task: the task's outcome, with a broken pool's error as
    one :class:`WorkerError`; cancelling it cancels the task."""

    def __init__(self, task: Future) -> None:
        super().__init__()
        self._task = task
        task.add_done_callback(self._copy)

    def _copy(self, task: Future) -> None:
        if task.cancelled():
            super().cancel()
            self.set_running_or_notify_cancel()
            return
        error = task.exception()
        if isinstance(error, BrokenExecutor):
            self.set_exception(_crashed(error))
        elif error is not None:
            self.set_exception(error)
        else:
            self.set_result(task.result())

    def cancel(self) -> bool:
        return self._task.cancel() and super().cancel()


class ProcessPool(_LokyExecutor):
    """loky's process pool (concurrent.futures' interface) whose futures fail with one
    :class:`WorkerError` when a worker dies or cannot start."""

    def submit(self, fn, /, *args, **kwargs) -> Future:  # type: ignore[override]
        try:
            return _Linked(super().submit(fn, *args, **kwargs))
        except BrokenExecutor as error:
            raise _crashed(error) from None

    def __exit__(self, kind, *exc) -> None:
        stop_pool(self, abort=kind is not None)


def stop_pool(pool: ProcessPool, abort: bool = False) -> None:
    """Shut a pool down: wait for its work, or with ``abort`` (an error or Ctrl-C is on its
    way up) end its processes at once, even one deep inside Storm."""
    if abort:
        for process in list(pool._processes.values()):
            process.terminate()
    pool.shutdown(wait=not abort, kill_workers=abort)


def each_result(function: Callable[[Any], Any], tasks, workers: int | None = None):
    """``function(task)`` of every task, in order: in this process with one worker (or where
    none may be started), else over a pool of spawned processes, each result as it is
    ready in turn (what a campaign's per-instance steps need)."""
    workers = min(default_workers(workers), max(1, len(tasks)))
    if workers == 1:
        for task in tasks:
            yield function(task)
        return
    with spawn_pool(workers) as pool:
        for future in [pool.submit(function, task) for task in tasks]:
            yield future.result()


def spawn_pool(
    workers: int, initializer: Callable[..., Any] | None = None, initargs: tuple[Any, ...] = ()
) -> ProcessPool:
    """A process pool of ``workers`` spawned processes (which do not import the caller's main
    module), each started by ``initializer(*initargs)``."""
    if not may_start_processes():
        raise WorkerError(
            "cannot start worker processes from a daemonic process (a Dask worker, say); "
            "run this from a process that may start processes"
        )
    return ProcessPool(
        max_workers=workers,
        context=get_context("loky"),
        initializer=_start,
        initargs=(initializer, initargs, os.getpid()),
        # a crash is reported once, by the parent, as one WorkerError (not also as loky's
        # faulthandler dump), unless the user configured faulthandler
        env={} if "PYTHONFAULTHANDLER" in os.environ else {"PYTHONFAULTHANDLER": ""},
    )


class PoolOwner:
    """An evaluator's worker pool, started on first use (:meth:`_executor`), and its release:
    ``close`` and use as a context manager (an exception on its way up ends the workers at once)."""

    workers: int
    _pool: ProcessPool | None = None

    def _executor(self) -> ProcessPool:
        if self._pool is None:
            self._pool = spawn_pool(self.workers)
        return self._pool

    def close(self, abort: bool = False) -> None:
        """Release the workers (``abort``: end them at once, on an error or Ctrl-C)."""
        if self._pool is not None:
            stop_pool(self._pool, abort)
            self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, kind, *exc) -> None:
        self.close(abort=kind is not None)
