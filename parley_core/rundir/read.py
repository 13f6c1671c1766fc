"""Reading a run directory back as value objects: :class:`RunDirectory` (for ``parley select``,
``parley simulate``, ``report.html`` and the library's :class:`~parley_core.api.runs.Run`),
with its typed :class:`~parley_core.rundir.summary.RunSummary`, its baseline and its bound.

Everything here is read from the files alone, so a run made in this process and one loaded
from disk read the same; nothing here imports the pipeline.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

from attrs import field, frozen

from parley_core.errors import OptionError
from parley_core.files import read_text
from parley_core.model import Decision, Direction, Family, Front, Objective, Policy, Service, Valued, identifier
from parley_core.rundir.summary import RunSummary

FILES = ("summary.json", "front.csv", "policies.csv", "decisions.csv", "model.prism", "properties.pctl")


@frozen(kw_only=True)
class Optimality:
    """How close the front is to a certified outer bound of the family (``bound.csv``): no
    policy of the family is better than every point of :attr:`points`."""

    method: str
    exact: bool
    """True when the front is proven to be the family's whole Pareto front."""
    bound_hypervolume: float
    front_hypervolume: float
    gap: float | None
    """(bound - front) / bound, of the hypervolumes (None: no finite bound)."""
    points: tuple[tuple[float, ...], ...] = field(converter=lambda rows: tuple(tuple(map(float, r)) for r in rows))
    seconds: float = field(eq=False)


@frozen(kw_only=True)
class RunDirectory:
    path: Path
    summary: RunSummary = field(eq=False)
    """summary.json, typed."""
    document: Mapping[str, Any] = field(eq=False, repr=False, converter=lambda d: MappingProxyType(dict(d)))
    """summary.json as written."""
    objectives: tuple[Objective, ...] = field(converter=tuple[Objective, ...])
    services: tuple[Service, ...] = field(converter=tuple[Service, ...])
    observation: tuple[str, ...] = field(converter=tuple[str, ...])
    left_out: tuple[tuple[int, ...], ...] = field(converter=tuple[tuple[int, ...], ...])
    front: Front
    """The front's policies (their decision values in the order of ``decisions``) and values."""
    baseline: Valued
    """The case study's baseline policies and their values (baseline.csv)."""
    optimality: Optimality | None
    """The certified bound (bound.csv) and the front's gap to it; None when the run made none."""
    decisions: tuple[Decision, ...] = field(converter=tuple[Decision, ...])
    """The decision constants of model.prism, in the order of every policy's values."""
    model: str

    @property
    def case_study(self) -> str:
        return self.summary.case_study

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

    def family(self) -> Family:
        """The run's family, rebuilt from its model.prism and decisions.csv (no plugin needed).
        It has no original model: Storm can check and simulate its policies, the quotient
        cannot be built from it."""
        return Family(
            name=identifier(self.case_study or "run"),
            prism=self.model,
            services=self.services,
            observation=self.observation,
            objectives=self.objectives,
            decisions=self.decisions,
            valuations=tuple(dict.fromkeys(d.valuation for d in self.decisions)),
            left_out=self.left_out,
        )


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
    document = json.loads(read_text(path / "summary.json", "summary", "rerun `parley run`", OptionError))
    try:
        summary = RunSummary.from_json(document)
    except (KeyError, TypeError, ValueError) as exc:
        raise OptionError(
            f"{path}/summary.json is not a summary parley can read ({type(exc).__name__}: {exc}); rerun `parley run`"
        ) from None
    objectives = summary.objectives
    model = summary.model
    names = [o.name for o in objectives]
    with open(path / "front.csv") as handle:
        front = [(row["policy"], tuple(float(row[n]) for n in names)) for row in csv.DictReader(handle)]
    services = {s.constant: s for s in model.services}
    with open(path / "decisions.csv") as handle:
        reader = csv.reader(handle)
        next(reader)  # decision, constant, observation variables
        decisions = [
            Decision(name=row[0], service=services[row[1]], valuation=tuple(int(v) for v in row[2:])) for row in reader
        ]
    order = [d.name for d in decisions]
    with open(path / "policies.csv") as handle:
        policies = {row["policy"]: tuple(int(row[n]) for n in order) for row in csv.DictReader(handle)}
    missing_policies = [name for name, _ in front if name not in policies]
    if missing_policies:
        raise OptionError(f"{path}/policies.csv lacks front policy {missing_policies[0]!r}; rerun `parley run`")
    return RunDirectory(
        path=path,
        summary=summary,
        document=document,
        objectives=objectives,
        services=model.services,
        observation=model.observation,
        left_out=model.left_out,
        front=Front(
            objectives=objectives,
            policies=[Policy(name=name, values=policies[name]) for name, _ in front],
            values=[values for _, values in front],
        ),
        baseline=_baseline(path, objectives, decisions),
        optimality=_optimality(path, summary),
        decisions=decisions,
        model=(path / "model.prism").read_text(),
    )


def _baseline(path: Path, objectives: tuple[Objective, ...], decisions: list[Decision]) -> Valued:
    """baseline.csv: each baseline sets each service's constant to one value everywhere."""
    names = [o.name for o in objectives]
    policies: list[Policy] = []
    values: list[list[float]] = []
    if (path / "baseline.csv").is_file():
        with open(path / "baseline.csv") as handle:
            for row in csv.DictReader(handle):
                policies.append(Policy(name=row["policy"], values=[int(row[d.service.constant]) for d in decisions]))
                values.append([float(row[n]) for n in names])
    return Valued(objectives=objectives, policies=policies, values=values)


def _optimality(path: Path, summary: RunSummary) -> Optimality | None:
    record = summary.optimality
    if record is None:
        return None
    names = [o.name for o in summary.objectives]
    with open(path / "bound.csv") as handle:
        points = [[float(row[n]) for n in names] for row in csv.DictReader(handle)]
    return Optimality(
        method=record.bound_method,
        exact=record.exact,
        bound_hypervolume=record.bound_hypervolume,
        front_hypervolume=record.front_hypervolume,
        gap=record.gap,
        points=points,
        seconds=record.seconds,
    )
