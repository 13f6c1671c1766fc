"""Typed case-study options from --set KEY=VALUE strings."""

from __future__ import annotations

from pathlib import Path

import pytest
from attrs import field, frozen, validators

from parley_core.errors import OptionError
from parley_core.plugin.casestudy import CaseStudy
from parley_core.plugin.options import option, options_as_dict, parse_assignments


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


@frozen(kw_only=True)
class Shapes:
    start: tuple[int, int] = option((1, 0), "a cell X:Y")
    cells: tuple[tuple[int, int], ...] = option(((0, 3), (0, 4)), "cells X:Y,X:Y")
    span: tuple[float, float] = option((0.7, 1.0), "a range LOW:HIGH")
    steps: tuple[int, ...] = option((1, 2, 3), "steps A:B:C")
    weight: float = option(1.0, "a weight", converter=float)


SHAPES = CaseStudy(name="shapes", description="tuples", options_type=Shapes, build=lambda o: None)


def test_tuple_options_read_and_write_their_text_form():
    opts = SHAPES.options(["start=2:5", "cells=1:1, 2:2,", "span=0.25:0.5", "steps=4:5"])
    assert opts == Shapes(start=(2, 5), cells=((1, 1), (2, 2)), span=(0.25, 0.5), steps=(4, 5))
    written = options_as_dict(opts)
    assert written == {"start": "2:5", "cells": "1:1,2:2", "span": "0.25:0.5", "steps": "4:5", "weight": 1.0}
    assert SHAPES.options_from_json(written) == opts  # as a run directory's summary.json is read back
    assert SHAPES.options(start=(3, 4)).start == (3, 4)  # Python values too, as parley.run(..., start=(3, 4))
    assert SHAPES.options(["cells="]).cells == ()


@pytest.mark.parametrize(
    ("assignment", "message"),
    [
        ("start=1", "option start='1' for shapes: expected int:int"),
        ("start=1:2:3", "expected int:int"),
        ("cells=1-2", "expected a list X:Y,X:Y,... of int:int"),
        ("span=a:b", "expected float:float"),
    ],
)
def test_a_malformed_tuple_option_says_what_to_write(assignment, message):
    with pytest.raises(OptionError, match=message):
        SHAPES.options([assignment])


def test_an_options_converter_runs_before_its_validators():
    assert Shapes(weight=2).weight == 2.0 and isinstance(Shapes(weight=2).weight, float)
