"""A run directory as value objects: :class:`Run` (what ``parley.run`` returns and
``parley.load`` reads back), its :class:`Summary` and :class:`Optimality`, and the
:class:`Selection` of one policy, which becomes the runtime controller.

Everything here is read from the files of the run directory, so a run made in this
process and one loaded from disk are the same object (``==``); the in-memory pipeline
result rides along only as :attr:`Run.result` (not compared).
"""

from __future__ import annotations

import csv
from collections.abc import Iterable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from attrs import field, frozen

from parley_core.constraints import Constraint
from parley_core.model import Front, Objective, Policy, Valued
from parley_core.rundir import read as rundir
from parley_core.urc.controller import URC
from parley_core.verify import Verification

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from parley_core.pipeline import RunResult
    from parley_core.plugin.simulator import Estimate
    from parley_core.progress import Reporter
    from parley_core.simulation.validate import Validation


def _mapping(value: Mapping[str, Any]) -> Mapping[str, Any]:
    return MappingProxyType(dict(value))


@frozen(kw_only=True)
class Summary:
    """The headline of ``summary.json``; the whole document is :attr:`document`."""

    case_study: str
    options: Mapping[str, Any] = field(converter=_mapping, hash=False)
    seed: int
    algorithm: str
    evaluations: int
    generations: int
    stopped_by: str
    front_hypervolume: float
    baseline_hypervolume: float
    hypervolume_gain_percent: float | None
    reference: tuple[float, ...] = field(converter=tuple[float, ...])
    selected: str
    """The knee policy, drawn on ``front.png`` and ``policy.png``."""
    verified_by: str
    """Who computed the reported values: "storm" (re-checked), "search" (Storm searched) or "none"."""
    verification: Verification = field(eq=False)
    """Its details (path, largest difference, seconds)."""
    timings: Mapping[str, float] = field(converter=_mapping, eq=False)
    document: Mapping[str, Any] = field(converter=_mapping, eq=False, repr=False)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Summary:
        search = data["search"]
        return cls(
            case_study=data["case_study"],
            options=data["options"],
            seed=int(data["seed"]),
            algorithm=search["algorithm"],
            evaluations=int(search["evaluations"]),
            generations=int(search["generations_done"]),
            stopped_by=search["stopped_by"],
            front_hypervolume=float(data["front"]["hypervolume"]),
            baseline_hypervolume=float(data["baseline"]["hypervolume"]),
            hypervolume_gain_percent=data["hypervolume_gain_percent"],
            reference=data["hypervolume_reference"],
            selected=data["selected"]["policy"],
            verified_by=data["verification"]["by"],
            verification=Verification.from_json(data["verification"]),
            timings=data["timings_seconds"],
            document=data,
        )


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
class Selection:
    """One policy of a front, chosen by :meth:`Run.select`."""

    policy: Policy
    values: Mapping[str, float] = field(converter=_mapping, hash=False)
    run: Run = field(eq=False, repr=False)

    @property
    def name(self) -> str:
        return self.policy.name

    def controller(self) -> URC:
        """The runtime URC of this policy (what ``parley select`` writes; ``.save(path)``)."""
        from parley_core.rundir.select import controller

        return controller(self.run.files, self.policy.name)


@frozen(kw_only=True)
class Page:
    """An interactive page of a run; Jupyter shows it inline (an iframe holding the page)."""

    path: Path
    run: Run = field(eq=False, repr=False)
    height: int = 860

    def html(self) -> str:
        """The page (made now from the run directory if it has no report.html)."""
        if self.path.is_file():
            return self.path.read_text(encoding="utf-8")
        from parley_core.rundir.page import render

        return render(self.run)

    def _repr_html_(self) -> str:
        from parley_core.views import inline

        return inline(self.html(), self.height)


@frozen(kw_only=True)
class Run:
    """A run directory of ``parley run`` / ``parley synthesize`` / ``parley exact``."""

    directory: Path
    case_study: str
    objectives: tuple[Objective, ...] = field(converter=tuple[Objective, ...])
    front: Front
    """Storm-verified Pareto front, in lexicographic order of the values."""
    baseline: Valued
    """The case study's baseline policies, Storm's values."""
    summary: Summary
    optimality: Optimality | None
    files: rundir.RunDirectory = field(eq=False, repr=False)
    result: RunResult | None = field(default=None, eq=False, repr=False)
    """The pipeline's in-memory result when the run was made in this process."""

    def policy(self, name: str) -> Policy:
        return self.files.policy(name)

    def select(self, constraints: Iterable[str | Constraint] = (), prefer: str | None = None) -> Selection:
        """The best front policy on ``prefer`` among those meeting ``constraints`` (ties and
        no ``prefer``: the knee of those), as ``parley select`` picks it."""
        from parley_core.rundir.select import select

        parsed = tuple(c if isinstance(c, Constraint) else Constraint.parse(c) for c in constraints)
        return self._selection(select(self.files, parsed, prefer))

    def knee(self) -> Selection:
        """The policy the run marked (``summary.selected``)."""
        return self._selection(self.summary.selected)

    def _selection(self, name: str) -> Selection:
        values = self.files.values_of(name)
        return Selection(
            policy=self.policy(name), values=dict(zip((o.name for o in self.objectives), values)), run=self
        )

    def simulate(
        self, policy: str | Selection | None = None, *, episodes: int = 10_000, seed: int = 1, max_steps: int = 10_000
    ) -> list[Estimate | str]:
        """``parley simulate``: a front policy (its name, a :class:`Selection`, or the knee)
        in Storm's simulator; per objective an estimate with its 99 % interval next to the
        model-checked value (or a sentence saying why it cannot be simulated)."""
        from parley_core.family.usermodel import family_of_run
        from parley_core.simulation.storm import simulate

        name = self.summary.selected if policy is None else policy.name if isinstance(policy, Selection) else policy
        return simulate(family_of_run(self.files), self.policy(name).values, episodes, seed, max_steps)

    def validate(
        self,
        policy: str = "knee",
        *,
        episodes: int = 1000,
        seed: int = 1,
        baselines: bool = True,
        progress: bool | Reporter = True,
    ) -> Validation:
        """``parley validate``: the policy (and the baselines) in closed loop on the case
        study's simulator (turtlebot: MuJoCo), against Storm's values."""
        from parley_core.simulation.validate import validate
        from parley_core.views.richprogress import reporting

        with reporting(progress) as reporter:
            return validate(self.directory, policy, episodes, seed, baselines, reporter)

    def plot(self) -> Figure:
        """The front against the baseline and the bound, as ``front.png`` (a matplotlib Figure)."""
        from parley_core.views.frontplot import front_figure

        names = [p.name for p in self.front.policies]
        return front_figure(
            title=f"{self.case_study}: front vs baseline",
            objectives=self.objectives,
            front=np.array(self.front.values),
            baseline=np.array(self.baseline.values),
            baseline_names=[p.name for p in self.baseline.policies],
            selected=names.index(self.summary.selected),
            selected_name=self.summary.selected,
            reference=self.summary.reference,
            bound=np.array(self.optimality.points) if self.optimality else None,
        )

    @property
    def report(self) -> Page:
        """The interactive report.html (in Jupyter, shown inline)."""
        return Page(path=self.directory / "report.html", run=self)

    def _repr_html_(self) -> str:
        s = self.summary
        gain = "" if s.hypervolume_gain_percent is None else f" ({s.hypervolume_gain_percent:+.1f} % over the baseline)"
        gap = ""
        if self.optimality is not None and self.optimality.gap is not None:
            gap = f"; gap to the bound {100 * self.optimality.gap:.1f} %"
        return (
            f"<p><b>{self.case_study}</b> run in <code>{self.directory}</code>: {len(self.front)} policies, "
            f"hypervolume {s.front_hypervolume:.6g}{gain}{gap}; verified by {s.verification.by.value}</p>"
            + self.front._repr_html_()
        )


def load(directory: str | Path, *, result: RunResult | None = None) -> Run:
    """The :class:`Run` of a run directory written by parley."""
    path = Path(directory)
    files = rundir.load(path)
    summary = Summary.from_json(files.summary)
    front = Front(objectives=files.objectives, policies=files.front.policies, values=files.front.values)
    return Run(
        directory=path,
        case_study=summary.case_study,
        objectives=files.objectives,
        front=front,
        baseline=_baseline(files),
        summary=summary,
        optimality=_optimality(path, files),
        files=files,
        result=result,
    )


def _baseline(files: rundir.RunDirectory) -> Valued:
    """baseline.csv: each baseline sets each service's constant to one value everywhere."""
    names = [o.name for o in files.objectives]
    policies: list[Policy] = []
    values: list[list[float]] = []
    if not (files.path / "baseline.csv").is_file():
        return Valued(objectives=files.objectives, policies=policies, values=values)
    with open(files.path / "baseline.csv") as handle:
        for row in csv.DictReader(handle):
            policies.append(Policy(name=row["policy"], values=[int(row[c]) for _, c, _ in files.decisions]))
            values.append([float(row[n]) for n in names])
    return Valued(objectives=files.objectives, policies=policies, values=values)


def _optimality(path: Path, files: rundir.RunDirectory) -> Optimality | None:
    data = files.summary.get("optimality")
    if not data:
        return None
    names = [o.name for o in files.objectives]
    with open(path / "bound.csv") as handle:
        points = [[float(row[n]) for n in names] for row in csv.DictReader(handle)]
    return Optimality(
        method=data["bound_method"],
        exact=bool(data["exact"]),
        bound_hypervolume=float(data["bound_hypervolume"]),
        front_hypervolume=float(data["front_hypervolume"]),
        gap=data["gap"],
        points=points,
        seconds=float(data.get("seconds", 0.0)),
    )
