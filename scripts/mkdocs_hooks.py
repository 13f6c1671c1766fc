"""MkDocs hooks: the CLI reference page (reference/cli.md), generated at build time from the
typer application itself, so it cannot drift from the commands; the module table of
docs/architecture.md, generated from the layers of tests/test_layout.py and each module's
own docstring; and the Sphinx roles of parley's docstrings (:class:`~parley_core.model.Policy`),
which mkdocstrings leaves as text, shown as the code they name (``Policy``)."""

from __future__ import annotations

import ast
import importlib.util
import re
from pathlib import Path

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


ROOT = Path(__file__).resolve().parents[1]
LAYER_NAMES = ["base", "languages and contracts", "engine", "methods", "one run", "products", "faces"]
MODULE_TABLE = "<!-- module table -->"


def _layers() -> list[list[str]]:
    """The layers as tests/test_layout.py keeps them (one list, read from the test)."""
    spec = importlib.util.spec_from_file_location("parley_test_layout", ROOT / "tests" / "test_layout.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.LAYERS


def _summary(path: Path) -> str:
    """The first paragraph of a module's docstring, on one line."""
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    return " ".join(doc.split("\n\n")[0].split()).replace("|", "\\|")


def module_table() -> str:
    """One table per layer: each room's modules (a package's in its own rows) with the first
    paragraph of their docstrings."""
    package = ROOT / "parley_core"
    out = []
    for number, (name, rooms) in enumerate(zip(LAYER_NAMES, _layers()), start=1):
        out += [f"### Layer {number}: {name}", "", "| module | role |", "|---|---|"]
        for room in rooms:
            folder = package / room
            paths = [package / f"{room}.py"] if not folder.is_dir() else sorted(folder.glob("*.py"))
            for path in paths:
                shown = path.relative_to(package).as_posix()
                out.append(f"| `{shown}` | {_summary(path)} |")
        out.append("")
    return "\n".join(out)


def on_page_markdown(markdown, page, config, files):
    if MODULE_TABLE in markdown:
        return markdown.replace(MODULE_TABLE, module_table())
    return markdown


def on_files(files, config):
    files.append(File.generated(config, "reference/cli.md", content=cli_markdown()))
    return files


_ROLE = re.compile(r":(?:class|mod|func|meth|data|attr|exc|obj):<code>(~?)([^<]*)</code>")


def _code(match: re.Match[str]) -> str:
    name = match.group(2)
    return f"<code>{name.rsplit('.', 1)[-1] if match.group(1) else name}</code>"


def on_page_content(html, page, config, files):
    return _ROLE.sub(_code, html)
