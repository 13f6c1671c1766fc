"""Typed case-study options from --set KEY=VALUE strings."""

from __future__ import annotations

from pathlib import Path

import pytest
from attrs import field, frozen, validators

from parley_core.errors import OptionError
from parley_core.plugin.casestudy import CaseStudy
from parley_core.plugin.options import options_as_dict, parse_assignments


@frozen(kw_only=True)
class Opts:
    n: int = field(default=3, validator=validators.ge(1))
    rate: float = 0.5
    name: str = "x"
    flag: bool = False
    path: Path | None = None


CASE = CaseStudy(name="demo", description="demo", options_type=Opts, build=lambda o: None)


def test_defaults_and_conversions():
    assert CASE.options([]) == Opts()
    opts = CASE.options(["n=7", "rate=0.25", "name=abc", "flag=yes", "path=/tmp/m.csv"])
    assert opts == Opts(n=7, rate=0.25, name="abc", flag=True, path=Path("/tmp/m.csv"))
    assert CASE.options(["path=none"]).path is None
    assert options_as_dict(opts)["path"] == "/tmp/m.csv"


@pytest.mark.parametrize(
    ("assignment", "message"),
    [
        ("n", "malformed option 'n'; write KEY=VALUE"),
        ("=3", "malformed option '=3'"),
        ("size=3", "unknown option 'size' for demo; valid options: n, rate, name, flag, path"),
        ("n=three", "option n='three' for demo: expected int"),
        ("flag=maybe", "expected bool"),
        ("n=0", "demo: 'n' must be >= 1"),
    ],
)
def test_bad_options(assignment, message):
    with pytest.raises(OptionError, match=message.replace("(", r"\(").replace(")", r"\)")):
        CASE.options([assignment])


def test_an_option_given_twice():
    with pytest.raises(OptionError, match="given twice"):
        parse_assignments(["n=1", "n=2"])


def test_options_need_defaults():
    @frozen
    class NoDefault:
        n: int

    with pytest.raises(TypeError, match="needs a default"):
        CaseStudy(name="bad", description="bad", options_type=NoDefault, build=lambda o: None)
