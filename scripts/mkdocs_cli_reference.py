"""MkDocs hook: the CLI reference page (reference/cli.md), generated at build time from the
typer application itself, so it cannot drift from the commands."""

from __future__ import annotations

import typer
from mkdocs.structure.files import File


def cli_markdown() -> str:
    from typer.cli import get_docs_for_click

    from parley_core.cli import app

    command = typer.main.get_command(app)
    text = get_docs_for_click(obj=command, ctx=typer.Context(command), name="parley", title="CLI reference")
    return (
        text.rstrip() + "\n\nThis page is generated from the commands' own help when the site is built; "
        "[cli.md](../cli.md) explains them with examples.\n"
    )


def on_files(files, config):
    files.append(File.generated(config, "reference/cli.md", content=cli_markdown()))
    return files
