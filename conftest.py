"""Two test tiers: ``pytest`` runs the fast one (every test not marked ``slow``), ``pytest --all``
runs everything (what CI and the README's quick start run), ``pytest -m slow`` only the slow
ones. A test that takes longer than :data:`SLOW_SECONDS` without the mark is named in the
terminal summary, so that the fast tier stays fast; naming rather than failing, because a
time limit would fail on a slower machine."""

from __future__ import annotations

import pytest

SLOW_SECONDS = 5.0


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--all", action="store_true", help="run the slow tests too (the whole suite, as CI does)")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.getoption("--all") or config.getoption("-m"):
        return  # everything, or what the -m expression chooses
    slow = [item for item in items if item.get_closest_marker("slow")]
    if slow:
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if not item.get_closest_marker("slow")]
        config.stash[_DESELECTED] = len(slow)


_DESELECTED = pytest.StashKey[int]()
_UNMARKED = pytest.StashKey[list]()


def pytest_configure(config: pytest.Config) -> None:
    config.stash[_UNMARKED] = []


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    outcome = yield
    report = outcome.get_result()
    if report.when == "call" and report.duration > SLOW_SECONDS and not item.get_closest_marker("slow"):
        item.config.stash[_UNMARKED].append((item.nodeid, report.duration))


def pytest_terminal_summary(terminalreporter, exitstatus: int, config: pytest.Config) -> None:
    deselected = config.stash.get(_DESELECTED, 0)
    if deselected:
        terminalreporter.write_line(
            f"the fast tier: {deselected} slow tests deselected; `pytest --all` runs the whole suite, "
            "`pytest -m slow` only those"
        )
    unmarked = config.stash.get(_UNMARKED, [])
    if unmarked:
        terminalreporter.section(f"tests over {SLOW_SECONDS:g} s not marked slow")
        for nodeid, seconds in sorted(unmarked, key=lambda item: -item[1]):
            terminalreporter.write_line(f"{seconds:6.1f} s  {nodeid}  (mark it @pytest.mark.slow)")
