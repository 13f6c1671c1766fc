"""Reading a run directory back (for `parley select` and `parley simulate`), as value objects."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

from attrs import field, frozen

from parley_core.errors import OptionError
from parley_core.files import read_text
from parley_core.model import Direction, Objective, Policy, Service, Valued

FILES = ("summary.json", "front.csv", "policies.csv", "decisions.csv", "model.prism", "properties.pctl")


@frozen(kw_only=True)
class RunDirectory:
    path: Path
    summary: dict[str, Any] = field(eq=False)
    """summary.json as written (settings, timings, versions...)."""
    objectives: tuple[Objective, ...] = field(converter=tuple[Objective, ...])
    services: tuple[Service, ...] = field(converter=tuple[Service, ...])
    observation: tuple[str, ...] = field(converter=tuple[str, ...])
    left_out: tuple[tuple[int, ...], ...] = field(converter=tuple[tuple[int, ...], ...])
    front: Valued
    """The front's policies (their decision values in the order of ``decisions``) and values."""
    decisions: tuple[tuple[str, str, tuple[int, ...]], ...] = field(
        converter=tuple[tuple[str, str, tuple[int, ...]], ...]
    )
    """(decision constant, service constant, observation valuation)."""
    model: str

    @property
    def directions(self) -> list[Direction]:
        return [o.direction for o in self.objectives]

    def policy(self, name: str) -> Policy:
        for policy in self.front.policies:
            if policy.name == name:
                return policy
        raise OptionError(f"policy {name!r} is not in {self.path}/policies.csv")

    def values_of(self, name: str) -> tuple[float, ...]:
        return self.front.values[self.front.policies.index(self.policy(name))]


def load(path: Path) -> RunDirectory:
    if not path.is_dir():
        raise OptionError(
            f"run directory {path} does not exist; give a directory written by `parley run` or `parley synthesize`"
        )
    missing = [f for f in FILES if not (path / f).is_file()]
    if missing:
        raise OptionError(
            f"{path} is not a complete run directory (missing {', '.join(missing)}); give one written by `parley run`"
        )
    summary = json.loads(read_text(path / "summary.json", "summary", "rerun `parley run`", OptionError))
    objectives = tuple(Objective.from_json(o) for o in summary["objectives"])
    model = summary["model"]
    names = [o.name for o in objectives]
    with open(path / "front.csv") as handle:
        front = [(row["policy"], tuple(float(row[n]) for n in names)) for row in csv.DictReader(handle)]
    with open(path / "decisions.csv") as handle:
        reader = csv.reader(handle)
        next(reader)  # decision, constant, observation variables
        decisions = [(row[0], row[1], tuple(int(v) for v in row[2:])) for row in reader]
    order = [d[0] for d in decisions]
    with open(path / "policies.csv") as handle:
        policies = {row["policy"]: tuple(int(row[n]) for n in order) for row in csv.DictReader(handle)}
    missing_policies = [name for name, _ in front if name not in policies]
    if missing_policies:
        raise OptionError(f"{path}/policies.csv lacks front policy {missing_policies[0]!r}; rerun `parley run`")
    return RunDirectory(
        path=path,
        summary=summary,
        objectives=objectives,
        services=tuple(Service.from_json(s) for s in model["services"]),
        observation=tuple(model["observation"]),
        left_out=tuple(tuple(int(x) for x in v) for v in model.get("left_out", [])),
        front=Valued(
            objectives=objectives,
            policies=[Policy(name=name, values=policies[name]) for name, _ in front],
            values=[values for _, values in front],
        ),
        decisions=decisions,
        model=(path / "model.prism").read_text(),
    )
