"""Reading a run directory back (for `parley select` and `parley simulate`)."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

from attrs import field, frozen

from parley_core.errors import OptionError, read_text
from parley_core.model import Direction

FILES = ("summary.json", "front.csv", "policies.csv", "decisions.csv", "model.prism", "properties.pctl")


@frozen(kw_only=True)
class RunDirectory:
    path: Path
    summary: dict[str, Any]
    objectives: tuple[dict[str, str], ...] = field(converter=tuple)
    front: tuple[tuple[str, tuple[float, ...]], ...] = field(converter=tuple)
    """(policy name, objective values) per front policy."""
    policies: dict[str, tuple[int, ...]]
    """policy name -> decision values, in the order of ``decisions``."""
    decisions: tuple[tuple[str, str, tuple[int, ...]], ...] = field(converter=tuple)
    """(decision constant, service constant, observation valuation)."""
    model: str

    @property
    def directions(self) -> list[Direction]:
        return [Direction(o["direction"]) for o in self.objectives]

    @property
    def formulas(self) -> list[str]:
        return [o["formula"] for o in self.objectives]


def load(path: Path) -> RunDirectory:
    if not path.is_dir():
        raise OptionError(f"run directory {path} does not exist; give a directory written by `parley run` or `parley synthesize`")
    missing = [f for f in FILES if not (path / f).is_file()]
    if missing:
        raise OptionError(f"{path} is not a complete run directory (missing {', '.join(missing)}); give one written by `parley run`")
    summary = json.loads(read_text(path / "summary.json", "summary", "rerun `parley run`", OptionError))
    objectives = summary["objectives"]
    names = [o["name"] for o in objectives]
    with open(path / "front.csv") as handle:
        front = [(row["policy"], tuple(float(row[n]) for n in names)) for row in csv.DictReader(handle)]
    with open(path / "decisions.csv") as handle:
        reader = csv.reader(handle)
        next(reader)  # decision, constant, observation variables
        decisions = [(row[0], row[1], tuple(int(v) for v in row[2:])) for row in reader]
    order = [d[0] for d in decisions]
    with open(path / "policies.csv") as handle:
        policies = {row["policy"]: tuple(int(row[n]) for n in order) for row in csv.DictReader(handle)}
    return RunDirectory(
        path=path, summary=summary, objectives=objectives, front=front, policies=policies,
        decisions=decisions, model=(path / "model.prism").read_text(),
    )
