"""The typer applications the command modules register on."""

from __future__ import annotations

from typing import Annotated

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


def _version(shown: bool) -> None:
    if shown:
        from parley_core import __version__

        typer.echo(f"parley {__version__}")
        raise typer.Exit()


@app.callback()
def _entry(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print parley's version and exit."),
    ] = False,
) -> None:
    """Synthesize uncertainty reduction controllers (URCs) with formal guarantees."""
    from parley_core.prism.program import quiet_storm

    quiet_storm()  # parley reports Storm's errors itself, in one line; set once per process
