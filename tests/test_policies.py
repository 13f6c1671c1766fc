"""Policies files in long and wide form."""

from __future__ import annotations

import pytest

from parley_core.errors import PolicyError
from parley_core.family.augment import augment
from parley_core.model import Policy
from parley_core.rundir.policies import long_csv, read_policies, table, wide_csv


@pytest.fixture
def family(toy):
    return augment(toy)


def test_long_and_wide_forms_round_trip(family, tmp_path):
    policies = [Policy(name="a", values=[1, 3]), Policy(name="b", values=[2, 2])]
    (tmp_path / "long.csv").write_text(long_csv(family, policies))
    (tmp_path / "wide.csv").write_text(wide_csv(family, policies))
    assert read_policies(tmp_path / "long.csv", family) == policies
    assert read_policies(tmp_path / "wide.csv", family) == policies
    assert (tmp_path / "long.csv").read_text().splitlines() == ["policy,phase,c", "a,0,1", "a,1,3", "b,0,2", "b,1,2"]
    assert table(family, policies[0]) == {(0,): {"c": 1}, (1,): {"c": 3}}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "is empty"),
        ("name,phase,c\na,0,1\n", "the first column must be 'policy'"),
        ("policy,phase,k\na,0,1\n", "fits neither layout"),
        ("policy,phase,c\na,0,1\n", "policy 'a' lacks phase=1"),
        ("policy,phase,c\na,0,1\na,1,x\n", "line 3: c='x' is not an integer"),
        ("policy,phase,c\na,0,1\na,1,9\n", r"c_1=9 is outside 1..3"),
        ("policy,phase,c\na,0,1\na,0,2\n", "gives phase=0 twice"),
        ("policy,phase,c\na,0,1\na,1,2\na,5,2\n", "phase=5, which is not an observation valuation"),
        ("policy,phase,c\na,0\n", "expected 3 cells, found 2"),
        ("policy,phase,c\n", "no policies"),
    ],
)
def test_malformed_files(family, tmp_path, text, message):
    path = tmp_path / "p.csv"
    path.write_text(text)
    with pytest.raises(PolicyError, match=message):
        read_policies(path, family)


def test_missing_file(family, tmp_path):
    with pytest.raises(PolicyError, match="does not exist"):
        read_policies(tmp_path / "nope.csv", family)
