"""How long work reports how far it got, at two levels.

- :data:`Progress` is a callable taking the number of units finished since the last call
  (policies evaluated, generations done, campaign runs stored). Evaluators, the search and
  campaign executors take one; they never print.
- A :class:`Reporter` announces the stages of a run (``stage``), lends its ``advance`` as the
  current stage's :data:`Progress`, and passes on notes for the user. The CLI draws one
  progress bar per stage from it; library users pass nothing (:class:`NullReporter`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Protocol

Progress = Callable[[int], None]
"""Called with the number of units finished since the last call."""


class Reporter(Protocol):
    def stage(self, name: str, total: int | None = None) -> None:
        """A stage starts; ``total`` units of work are expected (None: unknown)."""

    def advance(self, n: int = 1) -> None:
        """``n`` units of the current stage are done."""

    def note(self, text: str) -> None:
        """Something the user should know (a warning, an interruption)."""


class NullReporter:
    """A reporter that reports nothing."""

    def stage(self, name: str, total: int | None = None) -> None:
        pass

    def advance(self, n: int = 1) -> None:
        pass

    def note(self, text: str) -> None:
        pass


@contextmanager
def timed(timings: dict[str, float], name: str) -> Iterator[None]:
    """Add the time the block takes to ``timings[name]``."""
    start = time.perf_counter()
    try:
        yield
    finally:
        timings[name] = timings.get(name, 0.0) + time.perf_counter() - start
