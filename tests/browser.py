"""A real headless browser for the HTML reports' tests: Debian's Chromium driven by
Playwright (``executable_path``; Playwright's own browser download is not used).

Where Chromium or Playwright is missing, the tests that need them are skipped, unless
``PARLEY_BROWSER_TESTS=required`` (``.ci/run`` sets it after installing Chromium), which
makes the missing browser a failure."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
ARTEFACTS = Path(__file__).resolve().parents[1] / "test-artefacts"
"""Screenshots the tests keep (ignored by git)."""

FIND_VIEW = """
(name) => {
  const model = Bokeh.documents[0].get_model_by_name(name);
  const find = (view) => {
    if (view.model === model) return view;
    for (const child of view.child_views || []) { const found = find(child); if (found) return found; }
    return null;
  };
  for (const root of Bokeh.index.roots) { const found = find(root); if (found) return found; }
  return null;
}
"""

POINT = (
    """
([plotName, rendererName, index]) => {
  const findView = """
    + FIND_VIEW
    + """;
  const plot = findView(plotName);
  const renderer = Bokeh.documents[0].get_model_by_name(rendererName);
  const glyph = plot.renderer_views.get(renderer).glyph;
  const box = plot.canvas_view.el.getBoundingClientRect();
  return [box.left + glyph.sx[index], box.top + glyph.sy[index]];
}
"""
)


def require_browser():
    """(sync_playwright, chromium path), or skip (fail where the browser is required)."""
    required = os.environ.get("PARLEY_BROWSER_TESTS") == "required"
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        if required:
            pytest.fail("PARLEY_BROWSER_TESTS=required but playwright is not installed")
        pytest.skip("playwright is not installed (pip install -e '.[test]')")
    if CHROMIUM is None:
        if required:
            pytest.fail("PARLEY_BROWSER_TESTS=required but there is no chromium on PATH")
        pytest.skip("no chromium on PATH (Debian: apt-get install chromium)")
    return sync_playwright, CHROMIUM


class Page:
    """One loaded page and every console error or warning and uncaught exception it raised."""

    def __init__(self, browser, path: Path) -> None:
        self.page = browser.new_page(viewport={"width": 1280, "height": 1100})
        self.problems: list[str] = []
        self.page.on("console", self._console)
        self.page.on("pageerror", lambda error: self.problems.append(f"uncaught: {error}"))
        self.page.goto(path.resolve().as_uri())
        self.page.wait_for_function("() => window.Bokeh && Bokeh.index.roots.length > 0", timeout=30_000)
        self.page.wait_for_timeout(300)  # let the first render settle

    def _console(self, message) -> None:
        if message.type in ("error", "warning"):
            self.problems.append(f"{message.type}: {message.text}")

    def data(self, name: str, column: str) -> list:
        return self.page.evaluate(
            "([name, column]) => Array.from(Bokeh.documents[0].get_model_by_name(name).data[column])", [name, column]
        )

    def renderer_data(self, renderer: str, column: str) -> list:
        return self.page.evaluate(
            "([name, column]) => Array.from(Bokeh.documents[0].get_model_by_name(name).data_source.data[column])",
            [renderer, column],
        )

    def rendered_points(self, plot: str, renderer: str) -> int:
        """How many points the renderer's view drew (screen coordinates computed)."""
        return self.page.evaluate(
            "([plot, renderer]) => { const find = " + FIND_VIEW + "; const view = find(plot);"
            " const r = Bokeh.documents[0].get_model_by_name(renderer);"
            " return view.renderer_views.get(r).glyph.sx.length; }",
            [plot, renderer],
        )

    def click_point(self, plot: str, renderer: str, index: int) -> None:
        x, y = self.page.evaluate(POINT, [plot, renderer, index])
        self.page.mouse.move(x, y)
        self.page.wait_for_timeout(100)
        self.page.mouse.click(x, y)
        self.page.wait_for_timeout(500)  # two taps closer in time are one double tap to Bokeh

    def table_cells(self, name: str) -> list[list[str]]:
        """The rows a DataTable has drawn (its DOM's cell texts, as the reader sees them)."""
        return self.page.evaluate(
            "(name) => { const find = " + FIND_VIEW + "; const view = find(name);"
            " const root = view.shadow_el || view.el;"
            " const rows = Array.from(root.querySelectorAll('.slick-row'));"
            " rows.sort((a, b) => parseFloat(a.style.top) - parseFloat(b.style.top));"
            " return rows.map((r) => Array.from(r.querySelectorAll('.slick-cell')).map((c) => c.textContent)); }",
            name,
        )

    def text(self, name: str) -> str:
        return self.page.evaluate("(name) => Bokeh.documents[0].get_model_by_name(name).text", name)

    def screenshot(self, name: str) -> Path:
        ARTEFACTS.mkdir(exist_ok=True)
        self.page.mouse.move(0, 0)  # no tooltip left over from a click
        self.page.wait_for_timeout(100)
        path = ARTEFACTS / name
        self.page.screenshot(path=str(path), full_page=True)
        return path
