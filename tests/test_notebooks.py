"""docs/notebooks execute from top to bottom in a fresh kernel (nbclient), so they never rot;
and what they show is there: the front's table, the plot, the interactive report inline."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

NOTEBOOKS = Path(__file__).resolve().parents[1] / "docs" / "notebooks"


def execute(name: str, where: Path):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    shutil.copy(NOTEBOOKS / name, where / name)
    notebook = nbformat.read(where / name, as_version=4)
    client = nbclient.NotebookClient(
        notebook, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(where)}}
    )
    client.execute()
    return notebook


def outputs(notebook, kind: str) -> list[str]:
    found = []
    for cell in notebook.cells:
        for output in cell.get("outputs", []):
            data = output.get("data", {})
            if kind in data:
                found.append(data[kind])
    return found


@pytest.mark.slow
def test_the_robot_grid_notebook_runs(tmp_path):
    notebook = execute("robot_grid.ipynb", tmp_path)
    pages = outputs(notebook, "text/html")
    assert any("Storm-verified" in page or "verified by storm" in page for page in pages)
    assert any(page.startswith("<iframe srcdoc=") and "front-points" in page for page in pages)
    assert outputs(notebook, "image/png")  # run.plot()
    assert (tmp_path / "runs" / "notebook-robot_grid" / "controller.json").is_file()
    streams = "".join("".join(o.get("text", "")) for cell in notebook.cells for o in cell.get("outputs", []))
    assert "ipywidgets" not in streams and "site-packages" not in streams  # no warning with a path
    assert "\x1b[" not in streams and "search" in streams  # the bars as plain text, no terminal escapes


@pytest.mark.slow
def test_the_own_model_notebook_runs(tmp_path):
    notebook = execute("own_model.ipynb", tmp_path)
    assert (tmp_path / "sensor.prism").is_file() and (tmp_path / "runs" / "sensor" / "report.html").is_file()
    texts = "".join("".join(o.get("text", "")) for cell in notebook.cells for o in cell.get("outputs", []))
    assert "OptionError" in texts or "ModelError" in texts  # the cell showing a bad decision's error
    assert outputs(notebook, "image/png")
