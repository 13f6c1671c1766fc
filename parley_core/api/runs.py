"""A run directory as value objects: :class:`Run` (what ``parley.run`` returns and
``parley.load`` reads back), its :class:`Summary` and :class:`Optimality`, and the
:class:`Selection` of one policy, which becomes the runtime controller.

Everything here is read from the files of the run directory, so a run made in this
process and one loaded from disk are the same object (``==``); the in-memory pipeline
result rides along only as :attr:`Run.result` (not compared).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from attrs import field, frozen

from parley_core.constraints import Constraint
from parley_core.errors import OptionError, PolicyError
from parley_core.model import Front, Objective, Policy, Valued
from parley_core.rundir import read
from parley_core.rundir.read import Optimality
from parley_core.rundir.summary import RunSummary
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
    def of(cls, record: RunSummary, document: Mapping[str, Any]) -> Summary:
        """The headline of a run's :class:`~parley_core.rundir.summary.RunSummary`."""
        return cls(
            case_study=record.case_study,
            options=record.options,
            seed=record.seed,
            algorithm=record.search.algorithm,
            evaluations=record.search.evaluations,
            generations=record.search.generations_done,
            stopped_by=record.search.stopped_by.value,
            front_hypervolume=record.front.hypervolume,
            baseline_hypervolume=record.baseline.hypervolume,
            hypervolume_gain_percent=record.hypervolume_gain_percent,
            reference=record.hypervolume_reference,
            selected=record.selected,
            verified_by=record.verification.by.value,
            verification=record.verification,
            timings=record.timings_seconds,
            document=document,
        )


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
    height: int = 1500

    def html(self) -> str:
        """The page (made now from the run directory if it has no report.html)."""
        if self.path.is_file():
            return self.path.read_text(encoding="utf-8")
        from parley_core.rundir.page import render

        return render(self.run.files)

    def _repr_html_(self) -> str:
        """Jupyter's view: the page stacked (the policy view below the front), so that it fits
        a notebook's or a documentation page's width instead of being cut off."""
        from parley_core.rundir.page import render
        from parley_core.views import inline

        return inline(render(self.run.files, stacked=True), self.height)


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
    files: read.RunDirectory = field(eq=False, repr=False)
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
        from parley_core.simulation.storm import simulate

        name = self.summary.selected if policy is None else policy.name if isinstance(policy, Selection) else policy
        return simulate(self.files.family(), self.policy(name).values, episodes, seed, max_steps)

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
    files = read.load(path)
    return Run(
        directory=path,
        case_study=files.case_study,
        objectives=files.objectives,
        front=files.front,
        baseline=files.baseline,
        summary=Summary.of(files.summary, files.document),
        optimality=files.optimality,
        files=files,
        result=result,
    )


@frozen(kw_only=True)
class Check:
    """A requirement's answer, as ``parley check`` writes it (``check.json`` in
    :attr:`directory`): ``answer`` is "feasible" (:attr:`policy` meets the requirement, its
    :attr:`values` Storm's; :attr:`run` is the run directory of the policies found inside the
    box), "infeasible" (:attr:`certificate` names the file that proves no policy of the
    family does) or "unknown" (:attr:`open_share` of the family was left open in the time
    limit)."""

    answer: str
    requirement: tuple[str, ...] = field(converter=tuple[str, ...])
    directory: Path
    policy: str | None = None
    values: Mapping[str, float] | None = field(default=None, hash=False)
    certificate: Path | None = None
    open_share: float | None = None
    run: Run | None = field(default=None, eq=False)
    document: Mapping[str, Any] = field(converter=_mapping, eq=False, repr=False, factory=dict)

    @property
    def feasible(self) -> bool:
        return self.answer == "feasible"

    def controller(self) -> URC:
        """The feasible policy's runtime URC (``controller.json``)."""
        if self.run is None or self.policy is None:
            raise PolicyError(f"the check in {self.directory} is {self.answer}: it has no policy to control with")
        from parley_core.rundir.select import controller

        return controller(self.run.files, self.policy)


def load_check(directory: str | Path) -> Check:
    """The :class:`Check` of a directory ``parley check`` wrote."""
    import json

    path = Path(directory)
    try:
        document = json.loads((path / "check.json").read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise OptionError(
            f"{path} holds no readable check.json ({exc}); give a directory `parley check` wrote"
        ) from None
    policy = document.get("policy")
    return Check(
        answer=str(document["answer"]),
        requirement=tuple(document["requirement"]),
        directory=path,
        policy=None if policy is None else str(policy["name"]),
        values=None if policy is None else _mapping(policy["values"]),
        certificate=path / "certificate.json" if document["answer"] == "infeasible" else None,
        open_share=document.get("open_share"),
        run=load(path) if policy is not None else None,
        document=document,
    )
