"""parley's pytest plugin (entry point ``pytest11``), loaded wherever parley is installed.

It adds one option, ``--parley-case NAME`` (repeatable): run the conformance suite
(:mod:`parley_core.testing.suite`) on that installed case study, with no test file of
one's own; and restrict :class:`~parley_core.testing.suite.ConformanceSuite` subclasses
that name no case studies to the given ones. Without the option it does nothing: loading
it imports neither stormpy nor parley's plugins.
"""

from __future__ import annotations

import importlib.util

import pytest


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("parley")
    group.addoption(
        "--parley-case",
        action="append",
        default=None,
        metavar="NAME",
        help="run parley's conformance suite on this installed case study (repeatable)",
    )


def pytest_configure(config: pytest.Config) -> None:
    if config.getoption("parley_case", default=None):
        spec = importlib.util.find_spec("parley_core.testing.suite")
        if spec is not None and spec.origin is not None and spec.origin not in config.args:
            config.args.append(spec.origin)
