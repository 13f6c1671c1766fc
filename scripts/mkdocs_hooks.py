"""MkDocs hooks: the CLI reference page (reference/cli.md), generated at build time from the
typer application itself, so it cannot drift from the commands; and the Sphinx roles of
parley's docstrings (:class:`~parley_core.model.Policy`), which mkdocstrings leaves as
text, shown as the code they name (``Policy``)."""

from __future__ import annotations

import re

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


_ROLE = re.compile(r":(?:class|mod|func|meth|data|attr|exc|obj):<code>(~?)([^<]*)</code>")


def _code(match: re.Match[str]) -> str:
    name = match.group(2)
    return f"<code>{name.rsplit('.', 1)[-1] if match.group(1) else name}</code>"


def on_page_content(html, page, config, files):
    return _ROLE.sub(_code, html)
