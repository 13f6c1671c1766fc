"""Worker processes: how many, and a pool that starts them fresh (spawn, not fork).

Workers are spawned rather than forked so that no Storm or numba state of the parent is
shared. A worker's per-process state (the quotient solver, Storm's parsed program) is set
by the pool's initializer or filled on first use; that module-level cache, one per worker
process, is the one sanctioned exception to "no module state" (docs/architecture.md).
"""

from __future__ import annotations

import multiprocessing
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from typing import Any

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


def default_workers(workers: int | None = None) -> int:
    """``workers`` if given, else one per core; at least 1."""
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


def stop_pool(pool: ProcessPoolExecutor, abort: bool = False) -> None:
    """Shut a pool down: wait for its work, or with ``abort`` (an error or Ctrl-C is on its
    way up) end its processes at once, even one deep inside Storm."""
    if abort:
        for process in list(getattr(pool, "_processes", {}).values()):
            process.terminate()
    pool.shutdown(wait=not abort, cancel_futures=True)


def spawn_pool(
    workers: int, initializer: Callable[..., Any] | None = None, initargs: tuple[Any, ...] = ()
) -> ProcessPoolExecutor:
    """A process pool of ``workers`` spawned processes, each started by ``initializer(*initargs)``."""
    return ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_start,
        initargs=(initializer, initargs, os.getpid()),
    )


class PoolOwner:
    """An evaluator's worker pool, started on first use (:meth:`_executor`), and its release:
    ``close`` and use as a context manager (an exception on its way up ends the workers at once)."""

    workers: int
    _pool: ProcessPoolExecutor | None = None

    def _executor(self) -> ProcessPoolExecutor:
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
