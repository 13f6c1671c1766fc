"""Commands about case studies: list, options."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table

from parley_core.cli.app import app
from parley_core.cli.common import case_study, registry, user_errors
from parley_core.cli.options import CaseArgument
from parley_core.plugin.options import as_text


@app.command("list")
@user_errors
def list_command() -> None:
    """List the registered case studies."""
    found = registry()
    table = Table(title="case studies", title_justify="left")
    table.add_column("name", style="bold")
    table.add_column("description")
    table.add_column("plugin", style="dim")
    for name in found.names:
        table.add_row(name, found.case_studies[name].description, found.provider(name))
    Console().print(table)


@app.command("options")
@user_errors
def options_command(case: CaseArgument) -> None:
    """Show a case study's options (for --set KEY=VALUE) with their defaults."""
    study = case_study(case)
    table = Table(title=f"{study.name} options", title_justify="left")
    for column in ("option", "type", "default", "meaning"):
        table.add_column(column)
    for f in study.option_fields():
        if isinstance(f.type, type):
            kind = f.type.__name__
        else:
            kind = str(f.type).replace("pathlib.", "").replace("Path", "path")
        table.add_row(
            f.name,
            kind,
            as_text(f.default) if isinstance(f.default, tuple) else str(f.default),
            f.metadata.get("help", ""),
        )
    Console().print(table)
