"""Scenario sets: the model's numbers a URC should hold up against.

A scenario is a set of option values (``p=0.02``, or ``p=0.02, move_cost=2``) over a run's
options; a scenario set is what ``--scenarios`` gives: each ``KEY=V1,V2,...`` a list of
values of one option, several of them a grid (every combination), or a CSV file with one
column per option and one row per scenario. A robust run (:mod:`parley_core.robust`) scores
each policy by its worst value over the set.
"""

from __future__ import annotations

import csv
import itertools
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from attrs import field, frozen

from parley_core.errors import OptionError
from parley_core.files import read_text
from parley_core.model import Family, SystemModel


def _pairs(values: Mapping[str, str] | Sequence[tuple[str, str]]) -> tuple[tuple[str, str], ...]:
    items = values.items() if isinstance(values, Mapping) else values
    return tuple((str(k), str(v)) for k, v in items)


@frozen
class Scenario:
    """Option values (``KEY``, ``VALUE`` strings, as ``--set`` takes them) over a run's own."""

    assignments: tuple[tuple[str, str], ...] = field(converter=_pairs)

    @property
    def label(self) -> str:
        """``p=0.02`` or ``p=0.02 move_cost=2``: how files and tables name the scenario."""
        return " ".join(f"{k}={v}" for k, v in self.assignments)

    @property
    def values(self) -> dict[str, str]:
        return dict(self.assignments)

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(k for k, _ in self.assignments)


def _scenarios(items: Iterable[Scenario]) -> tuple[Scenario, ...]:
    return tuple(items)


@frozen
class ScenarioSet:
    scenarios: tuple[Scenario, ...] = field(converter=_scenarios)

    def __attrs_post_init__(self) -> None:
        if not self.scenarios:
            raise OptionError("the scenario set is empty; give --scenarios KEY=V1,V2,... with at least one value")
        labels = [s.label for s in self.scenarios]
        twice = sorted({label for label in labels if labels.count(label) > 1})
        if twice:
            raise OptionError(f"scenario {twice[0]} is given twice; give each scenario once")

    def __len__(self) -> int:
        return len(self.scenarios)

    def __iter__(self):
        return iter(self.scenarios)

    @property
    def keys(self) -> tuple[str, ...]:
        """Every option some scenario sets, in order of first mention."""
        return tuple(dict.fromkeys(k for s in self.scenarios for k in s.keys))

    @classmethod
    def parse(cls, specs: Sequence[str]) -> ScenarioSet:
        """``["p=0.005,0.01,0.02"]``, a grid ``["p=0.01,0.02", "move_cost=1,2"]`` (four
        scenarios) or ``["scenarios.csv"]`` (a header of option names, a scenario per row)."""
        if not specs or not all(s.strip() for s in specs):
            raise OptionError("the scenario set is empty; give --scenarios KEY=V1,V2,...")
        files = [s for s in specs if "=" not in s]
        if files:
            if len(specs) > 1:
                raise OptionError(f"--scenarios {files[0]}: give either one CSV file or KEY=V1,V2,... lists, not both")
            return cls.read_csv(Path(files[0]))
        axes: dict[str, list[str]] = {}
        for spec in specs:
            key, _, text = spec.partition("=")
            key = key.strip()
            values = [v.strip() for v in text.split(",")]
            if not key.isidentifier():
                raise OptionError(f"malformed --scenarios {spec!r}; write KEY=V1,V2,..., e.g. p=0.005,0.01,0.02")
            if not text.strip() or not all(values):
                raise OptionError(f"--scenarios {spec!r} has an empty value; write KEY=V1,V2,..., e.g. p=0.01,0.02")
            if key in axes:
                raise OptionError(f"--scenarios names {key!r} twice; give all its values in one KEY=V1,V2,...")
            twice = sorted({v for v in values if values.count(v) > 1})
            if twice:
                raise OptionError(f"--scenarios {spec!r} gives {key}={twice[0]} twice; give each value once")
            axes[key] = values
        keys = list(axes)
        return cls([Scenario(list(zip(keys, combo))) for combo in itertools.product(*axes.values())])

    @classmethod
    def read_csv(cls, path: Path) -> ScenarioSet:
        text = read_text(path, "scenario file", "give a CSV file with a header of option names", OptionError)
        rows = [row for row in csv.reader(text.splitlines()) if any(cell.strip() for cell in row)]
        if not rows:
            raise OptionError(f"scenario file {path} is empty; give a header of option names and a row per scenario")
        header = [h.strip() for h in rows[0]]
        if not all(h.isidentifier() for h in header):
            raise OptionError(
                f"scenario file {path}: the header {','.join(header)} must name options, e.g. p,move_cost"
            )
        scenarios = []
        for number, row in enumerate(rows[1:], start=2):
            if len(row) != len(header) or not all(cell.strip() for cell in row):
                raise OptionError(f"scenario file {path}, line {number}: give a value for each of {', '.join(header)}")
            scenarios.append(Scenario(list(zip(header, (cell.strip() for cell in row)))))
        if not scenarios:
            raise OptionError(f"scenario file {path} has a header and no scenario; add a row per scenario")
        return cls(scenarios)


@frozen(kw_only=True)
class ScenarioModel:
    """One scenario of a robust run: its options, its system model and its family."""

    scenario: Scenario
    options: Any
    system: SystemModel
    family: Family = field(eq=False, repr=False)

    @property
    def label(self) -> str:
        return self.scenario.label


def scenario_options(case, base: dict[str, str], scenarios: ScenarioSet) -> list[tuple[Scenario, Any]]:
    """Each scenario's options: the run's ``--set`` values, then the scenario's over them. A
    scenario may not set an option ``--set`` gives too (which would win is not obvious)."""
    clash = sorted(set(base) & set(scenarios.keys))
    if clash:
        raise OptionError(f"option {clash[0]!r} is given by --set and by --scenarios; give it in --scenarios only")
    return [(scenario, case.options_from({**base, **scenario.values})) for scenario in scenarios]
