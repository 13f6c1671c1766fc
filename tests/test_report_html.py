"""report.html in a real headless browser (tests/browser.py): for each case study and for a
campaign, the page loads from the file with no console error or warning, the front plot
draws as many points as front.csv has rows, a click on a point shows that policy, and the
requirement sliders filter the front. A screenshot of each page is kept in test-artefacts/."""

from __future__ import annotations

import csv
import json
import re

import pytest

import parley
from tests.browser import ARGS, ARTEFACTS, POINT, Page, require_browser

SMALL = {"population": 10, "generations": 2, "bound": "ideal", "progress": False}
CASES = {
    "robot_grid": {"size": 4},
    "turtlebot": {"size": 4, "start": "0:0", "target": "3:3", "obstacles": "1:1", "samples": 3001},
    "web_ids": {"rounds": 10},
    "tas": {"rounds": 5},
}


@pytest.fixture(scope="module")
def browser():
    sync_playwright, chromium = require_browser()
    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=chromium, args=ARGS)
        yield launched
        launched.close()


def front_rows(directory) -> list[dict]:
    with open(directory / "front.csv") as handle:
        return list(csv.DictReader(handle))


def offline(html: str) -> bool:
    """No script, style or image is fetched from anywhere: everything is inline."""
    return not re.search(r"<(script|link|img)[^>]+(src|href)=[\"']?(https?:)?//", html)


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES))
def test_run_report_in_a_browser(case, browser, tmp_path):
    run = parley.run(case, seed=2, **SMALL, out=tmp_path / case, options=CASES[case])
    report = run.directory / "report.html"
    assert report.is_file() and offline(report.read_text())
    rows = front_rows(run.directory)
    firsts = [next(r for r in rows if r["point"] == point) for point in dict.fromkeys(r["point"] for r in rows)]
    page = Page(browser, report)
    assert page.problems == []
    assert page.data("front-source", "policy") == [r["policy"] for r in firsts]  # one point per tie
    assert page.rendered_points("front-plot", "front-points") == len(firsts)

    # clicks on two points in turn, neither the knee: the heading and the rows the table draws
    # (its cells' texts) are each time that policy's decisions as policies.csv has them
    others = [k for k, r in enumerate(firsts) if r["policy"] != run.summary.selected]
    targets = others[:2] if len(others) >= 2 else [*others, 0]
    assert len(set(targets)) == 2
    observed = list(run.files.observation)
    constants = [s.constant for s in run.files.services]
    for target in targets:
        name = firsts[target]["policy"]
        page.click_point("front-plot", "front-points", target)
        assert f"policy {name}" in page.text("policy-heading")
        expected: dict[tuple[int, ...], dict[str, int]] = {}
        for decision, value in zip(run.files.decisions, run.policy(name).values):
            expected.setdefault(tuple(decision.valuation), {})[decision.service.constant] = value
        drawn = page.table_cells("decision-table")
        assert drawn, "the decision table draws no rows"
        for cells in drawn:
            valuation = tuple(int(v) for v in cells[: len(observed)])
            shown = dict(zip(constants, cells[len(observed) :]))
            assert {c: int(shown[c]) for c in expected[valuation]} == expected[valuation], (name, valuation)

    # hovering a point names that one point (the nearest), not every point under the pointer
    x, y = page.page.evaluate(POINT, ["front-plot", "front-points", targets[0]])
    page.page.mouse.move(x, y)
    page.page.wait_for_timeout(200)
    assert page.text("hover-readout").startswith(f"<b>{firsts[targets[0]]['policy']}</b>")

    # the requirement slider on the first objective fades what misses it
    objective = run.objectives[0]
    values = sorted(float(r[objective.name]) for r in firsts)
    middle = values[len(values) // 2]
    page.page.evaluate(
        "([name, value]) => { Bokeh.documents[0].get_model_by_name(name).value = value; }",
        [f"requirement-{objective.name}", middle],
    )
    page.page.wait_for_timeout(100)
    meets = sum(1 for v in values if (v >= middle if objective.direction.value == "max" else v <= middle))
    assert page.text("requirement-count").startswith(f"{meets} of {len(firsts)} points")
    faded = page.data("front-source", "alpha").count(0.12)
    assert faded == len(firsts) - meets
    if case in ("robot_grid", "turtlebot"):  # the plugin's map: obstacles and marks where map.json puts them
        found = json.loads((run.directory / "map.json").read_text())
        blocked = found["blocked"]
        if blocked:
            drawn = zip(page.renderer_data("map-blocked", "x"), page.renderer_data("map-blocked", "y"))
            assert sorted(map(list, drawn)) == sorted(blocked)
        assert sorted(page.renderer_data("map-marks", "text")) == ["S", "T"]
    if case == "turtlebot":  # the heading menu picks the slice of the grid
        menu = "slice-directionhat"
        options = page.page.evaluate("(n) => Bokeh.documents[0].get_model_by_name(n).options", menu)
        headings = page.data("policy-table", "directionhat")
        for option in options:
            page.page.evaluate("([n, v]) => { Bokeh.documents[0].get_model_by_name(n).value = v; }", [menu, option])
            shown = page.page.evaluate(
                "() => Bokeh.documents[0].get_model_by_name('policy-cells-c').view.filter.booleans"
            )
            assert shown == [h == int(option) for h in headings]
    page.screenshot(f"report-{case}.png")
    page.page.set_viewport_size({"width": 1280, "height": 800})  # a laptop's screen: nothing cut off sideways
    page.page.wait_for_timeout(200)
    assert page.page.evaluate("() => document.documentElement.scrollWidth") <= 1280
    page.screenshot(f"report-{case}-1280x800.png")
    assert page.problems == []


@pytest.mark.slow
def test_the_inline_page_fits_a_documentation_pages_width(browser, tmp_path):
    """Jupyter's view of a run (run.report): in a 740 px column, as a documentation page has,
    the whole page is there (stacked, nothing cut off at the frame's edge) and a click works."""
    run = parley.run("robot_grid", seed=2, **SMALL, out=tmp_path / "run", options=CASES["robot_grid"])
    host = tmp_path / "host.html"
    host.write_text(
        f"<html><body style='margin:0'><div style='width:740px'>{run.report._repr_html_()}</div></body></html>"
    )
    page = browser.new_page(viewport={"width": 800, "height": 900})
    page.goto(host.resolve().as_uri())
    frame = page.frames[1]
    frame.wait_for_function("() => window.Bokeh && Bokeh.index.roots.length > 0", timeout=30_000)
    page.wait_for_timeout(500)
    assert frame.evaluate("() => document.documentElement.scrollWidth") <= 740
    names = frame.evaluate("() => Array.from(Bokeh.documents[0].get_model_by_name('front-source').data.policy)")
    target = next(k for k, n in enumerate(names) if n != run.summary.selected)
    x, y = frame.evaluate(POINT, ["front-plot", "front-points", target])
    page.mouse.move(x, y)
    page.wait_for_timeout(100)
    page.mouse.click(x, y)
    page.wait_for_timeout(500)
    heading = frame.evaluate("() => Bokeh.documents[0].get_model_by_name('policy-heading').text")
    assert f"policy {names[target]}" in heading
    ARTEFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTEFACTS / "report-inline-740.png"), full_page=True)
    page.close()


@pytest.mark.slow
def test_campaign_report_in_a_browser(browser, tmp_path):
    from typer.testing import CliRunner

    from parley_core.cli import app

    store = tmp_path / "campaign.sqlite"
    campaign = parley.experiment(
        "robot_grid", store=store, grid=["size=4,5"], reps=3, population=10, generations=2, workers=1, progress=False
    )
    assert campaign.stored == 6 and not campaign.failures
    result = CliRunner().invoke(app, ["experiment", "report", "--store", str(store), "--out", str(tmp_path / "report")])
    assert result.exit_code == 0, result.stderr
    report = tmp_path / "report" / "report.html"
    assert offline(report.read_text())
    page = Page(browser, report)
    assert page.problems == []
    settings = page.page.evaluate("() => Bokeh.documents[0].get_model_by_name('setting').options")
    table2 = page.text("table2")
    assert table2.count("<tr>") == 1 + len(settings) + 1  # the head, one row per setting, the total
    first = page.data("boxes-hv", "q2")
    assert sorted(page.data("boxes-hv", "instance")) == ["size=4", "size=5"]
    assert page.rendered_points("gains-hv", "gains-hv-boxes") == 2
    other = next(
        s for s in settings if s != page.page.evaluate("() => Bokeh.documents[0].get_model_by_name('setting').value")
    )
    page.page.select_option("select", other)  # the real widget, as a user changes it
    page.page.wait_for_timeout(200)
    assert page.page.evaluate("() => Bokeh.documents[0].get_model_by_name('setting').value") == other
    # the page now shows that setting's boxes, as the report's own statistics give them
    from parley_core.experiment.page import boxes
    from parley_core.experiment.report import analyze
    from parley_core.experiment.store import Store
    from parley_core.plugin.manager import load_registry

    case = load_registry().get("robot_grid")
    with Store(store) as results:
        rows = analyze(list(results.runs("robot_grid")), case.requirement_settings)
    setting = case.requirement_settings[settings.index(other)]
    expected = boxes(rows, setting, "hv", "baseline_hv")
    assert page.data("boxes-hv", "q2") == pytest.approx(expected["q2"])
    assert page.data("boxes-hv", "verdict") == expected["verdict"]
    assert first == pytest.approx(boxes(rows, case.figure_setting, "hv", "baseline_hv")["q2"])
    page.screenshot("report-campaign.png")
    assert page.problems == []


def test_stable_ids_renumber_bokeh_ids_but_not_data():
    from parley_core.views.stable import stable_ids

    page = (
        '<script>var lib = {"id":"p9"};</script>'
        '<div id="0861057a-4ada-4e2d-9937-cfbfeb2edd67" data-root-id="p1141"></div>'
        '{"roots":{"p1141":"x"},"root_ids":["p1141"]} {"id":"p1142","data":["p1142","p1141"]} {"id":"p1141"}'
    )
    stable = stable_ids(page)
    assert stable.startswith('<script>var lib = {"id":"p9"};</script>')  # the library is left alone
    assert 'data-root-id="p1001"' in stable and '"root_ids":["p1001"]' in stable and '{"id":"p1001"}' in stable
    assert '{"id":"p1002","data":["p1142","p1141"]}' in stable  # data that looks like an id stays
    assert "00000000-0000-4000-8000-000000000001" in stable


@pytest.mark.slow
def test_a_run_report_shows_inline_in_jupyter(tmp_path):
    run = parley.run("robot_grid", seed=2, **SMALL, out=tmp_path / "r", options=CASES["robot_grid"])
    inline = run.report._repr_html_()
    assert inline.startswith("<iframe srcdoc=") and "front-points" in inline
    (run.directory / "report.html").unlink()  # an old run directory: the page is made on the fly
    assert "front-points" in run.report.html()


@pytest.mark.slow
def test_parley_report_writes_the_page_again(tmp_path):
    from typer.testing import CliRunner

    from parley_core.cli import app

    run = parley.run("web_ids", seed=2, **SMALL, out=tmp_path / "w", options=CASES["web_ids"])
    before = (run.directory / "report.html").read_bytes()
    (run.directory / "report.html").unlink()
    result = CliRunner().invoke(app, ["report", str(run.directory)])
    assert result.exit_code == 0, result.stderr
    assert (run.directory / "report.html").read_bytes() == before
    missing = CliRunner().invoke(app, ["report", str(tmp_path / "nothing")])
    assert missing.exit_code == 2 and "does not exist" in missing.stderr
