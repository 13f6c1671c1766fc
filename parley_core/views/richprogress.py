"""Progress bars on stderr for long work: one bar per pipeline stage (:class:`RichReporter`,
a :class:`~parley_core.progress.Reporter`), shared by the ``parley`` command and the
:mod:`parley` library's ``progress=True``. Nothing here runs at import."""

from __future__ import annotations

import importlib.util
import sys
import time
from contextlib import AbstractContextManager, nullcontext

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    SpinnerColumn,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
)

from parley_core.progress import NullReporter, Reporter


def stderr() -> Console:
    """The console of progress and notes: stderr. In a Jupyter kernel without ipywidgets
    (which rich draws live bars with, and warns about, with its file's path, when it is
    missing), plain text: the bars as they end, no terminal escapes."""
    if "ipykernel" in sys.modules and importlib.util.find_spec("ipywidgets") is None:
        return Console(stderr=True, force_jupyter=False, force_terminal=False)
    return Console(stderr=True)


def progress_bars(console: Console | None = None, description: str = "{task.description}") -> Progress:
    """The progress bars of every command: spinner, what, bar, done of total, time (on stderr)."""
    return Progress(
        SpinnerColumn(),
        TextColumn(description),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console or stderr(),
    )


LOG_EVERY = 60.0
"""Where stderr is not a terminal (a batch job, ``nohup``, a pipe), bars are drawn only when
they stop: a line says how far the stage is at most this often (seconds) instead."""


class RichReporter:
    """Draws one progress bar per pipeline stage on stderr (a :class:`~parley_core.progress.Reporter`);
    where stderr is not a terminal, a line every :data:`LOG_EVERY` seconds of a stage."""

    def __init__(self, console: Console) -> None:
        self.console = console
        self.progress = progress_bars(console, "{task.description:<18}")
        self.task: TaskID | None = None
        self.plain = not console.is_terminal
        """Bars show only when they stop: a line every LOG_EVERY seconds says how far a stage is."""
        self.logged = time.monotonic()

    def __enter__(self) -> RichReporter:
        self.progress.start()
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is None:
            self._finish()
        else:  # an error: leave nothing behind but its message (not even rich's last newline)
            self.progress.live.transient = True
            self.console.quiet = True
        self.progress.stop()

    def _finish(self) -> None:
        # a stage without a known size is done when the next starts; a sized one shows
        # how far it got (less than its total if interrupted)
        if self.task is not None and self.progress.tasks[-1].total is None:
            self.progress.update(self.task, total=1, completed=1)

    def stage(self, name: str, total: int | None = None) -> None:
        self._finish()
        self.task = self.progress.add_task(name, total=total)
        self.logged = time.monotonic()

    def advance(self, n: int = 1) -> None:
        if self.task is not None:
            self.progress.advance(self.task, n)
            if self.plain and time.monotonic() - self.logged >= LOG_EVERY:
                self.logged = time.monotonic()
                task = self.progress.tasks[-1]
                done = f"{task.completed:,.0f}" + (f" of {task.total:,.0f}" if task.total else "")
                minutes, seconds = divmod(int(task.elapsed or 0), 60)
                self.console.print(f"{task.description}: {done} after {minutes}:{seconds:02d}", highlight=False)

    def note(self, text: str) -> None:
        self.progress.console.print(f"[yellow]note:[/] {text}")


def reporting(progress: bool | Reporter) -> AbstractContextManager[Reporter]:
    """The reporter of ``progress``: rich bars on stderr (True), none (False), or the caller's."""
    if progress is True:
        return RichReporter(stderr())
    if progress is False or progress is None:
        return nullcontext(NullReporter())
    return nullcontext(progress)
