"""What the commands draw: progress bars on stderr, tables and JSON documents on stdout."""

from __future__ import annotations

from typing import Any

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
from rich.table import Table

from parley_core.casestudy import CaseStudy
from parley_core.model import Valued
from parley_core.options import options_as_dict


def stderr() -> Console:
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


class RichReporter:
    """Draws one progress bar per pipeline stage on stderr (a :class:`~parley_core.progress.Reporter`)."""

    def __init__(self, console: Console) -> None:
        self.console = console
        self.progress = progress_bars(console, "{task.description:<18}")
        self.task: TaskID | None = None

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

    def advance(self, n: int = 1) -> None:
        if self.task is not None:
            self.progress.advance(self.task, n)

    def note(self, text: str) -> None:
        self.progress.console.print(f"[yellow]note:[/] {text}")


def fmt(value: float) -> str:
    return f"{value:.6g}" if abs(value) >= 1e-3 or value == 0 else f"{value:.3e}"


def front_table(title: str, front: Valued, extra: dict[str, list[Any]] | None = None, limit: int = 40) -> Table:
    table = Table(title=title, title_justify="left")
    table.add_column("policy")
    for name in extra or {}:
        table.add_column(name, justify="right")
    for objective in front.objectives:
        table.add_column(f"{objective.name} ({objective.direction.value})", justify="right")
    rows = list(range(len(front)))
    if len(rows) > limit:
        step = (len(rows) - 1) / (limit - 1)
        rows = sorted({round(i * step) for i in range(limit)})
    for i in rows:
        cells = [front.policies[i].name]
        cells += [str(column[i]) for column in (extra or {}).values()]
        cells += [fmt(v) for v in front.values[i]]
        table.add_row(*cells)
    if len(rows) < len(front):
        table.caption = f"{len(rows)} of {len(front)} policies shown, evenly spaced; all are in front.csv"
    return table


def values_json(
    case: CaseStudy, options: Any, front: Valued, decisions: list[dict[str, int]] | None = None
) -> dict[str, Any]:
    policies = []
    for i, (policy, row) in enumerate(zip(front.policies, front.values)):
        entry: dict[str, Any] = {"policy": policy.name, "values": {o.name: v for o, v in zip(front.objectives, row)}}
        if decisions is not None:
            entry["decisions"] = decisions[i]
        policies.append(entry)
    return {
        "case_study": case.name,
        "options": options_as_dict(options),
        "objectives": [o.to_json() for o in front.objectives],
        "policies": policies,
    }
