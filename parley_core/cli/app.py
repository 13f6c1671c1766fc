"""The typer applications the command modules register on."""

from __future__ import annotations

import typer

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    help="Synthesize uncertainty reduction controllers (URCs) with formal guarantees.",
)

experiment_app = typer.Typer(
    no_args_is_help=True,
    rich_markup_mode=None,
    help="Campaigns: many instances x repetitions, a resumable store, reports (Tables 2 and 3, Fig. 4).",
)
app.add_typer(experiment_app, name="experiment")


@app.callback()
def _entry() -> None:
    """Synthesize uncertainty reduction controllers (URCs) with formal guarantees."""
    from parley_core.prism.program import quiet_storm

    quiet_storm()  # parley reports Storm's errors itself, in one line; set once per process
