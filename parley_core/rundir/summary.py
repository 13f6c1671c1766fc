"""``summary.json``, the run directory's record of a run, as one typed value: written by
:mod:`parley_core.rundir.write` and read back by :mod:`parley_core.rundir.read`, the
``parley`` command and the library, all through :class:`RunSummary` (no string keys).

The document is versioned (``schema``, :data:`SCHEMA`); a document written before the field
existed reads as schema 1. Optional parts (a robust run's scenarios, a bound, a guided or
polished search) are ``None`` when absent. ``options`` (a case study's own) and
``evaluator_details`` (an evaluator's own counters) stay mappings: their keys belong to the
plugin and the evaluator, not to the format.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from attrs import field, frozen

from parley_core.constraints import Constraint
from parley_core.model import Objective, Service
from parley_core.optimality.records import BeliefValue, SearchCounts
from parley_core.search.settings import Stop
from parley_core.verify import Verification

SCHEMA = 1
"""The version of ``summary.json`` this module writes."""


def _mapping(value: Mapping[str, Any]) -> Mapping[str, Any]:
    return MappingProxyType(dict(value))


def _floats(values) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


def _maybe_float(value: Any) -> float | None:
    return None if value is None else float(value)


@frozen(kw_only=True)
class Guided:
    """The policy-improvement walks a ``guided`` search started from."""

    walked_policies: int
    seconds: float
    skipped: str
    """Why there were none ("" when there were)."""


@frozen(kw_only=True)
class Polished:
    """What polishing the front did in a ``polished`` search."""

    evaluations: int
    expanded_policies: int
    seconds: float
    skipped: str


@frozen(kw_only=True)
class SearchRecord:
    algorithm: str
    population: int
    generations: int | None
    """The generations asked for (None: no limit)."""
    generations_done: int
    evaluations: int
    max_evaluations: int | None
    time_limit_seconds: float | None
    stopped_by: Stop
    interrupted: bool
    warm_start_policies: int = 0
    guided: Guided | None = None
    polished: Polished | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "algorithm": self.algorithm,
            "population": self.population,
            "generations": self.generations,
            "generations_done": self.generations_done,
            "evaluations": self.evaluations,
            "max_evaluations": self.max_evaluations,
            "time_limit_seconds": self.time_limit_seconds,
            "stopped_by": self.stopped_by.value,
            "interrupted": self.interrupted,
            "warm_start_policies": self.warm_start_policies,
        }
        if self.guided is not None:
            g = self.guided
            out["guided"] = {"walked_policies": g.walked_policies, "seconds": g.seconds, "skipped": g.skipped}
        if self.polished is not None:
            p = self.polished
            out["polished"] = {
                "evaluations": p.evaluations,
                "expanded_policies": p.expanded_policies,
                "seconds": p.seconds,
                "skipped": p.skipped,
            }
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> SearchRecord:
        guided, polished = data.get("guided"), data.get("polished")
        return cls(
            algorithm=str(data["algorithm"]),
            population=int(data["population"]),
            generations=None if data.get("generations") is None else int(data["generations"]),
            generations_done=int(data["generations_done"]),
            evaluations=int(data["evaluations"]),
            max_evaluations=None if data.get("max_evaluations") is None else int(data["max_evaluations"]),
            time_limit_seconds=_maybe_float(data.get("time_limit_seconds")),
            stopped_by=Stop(data["stopped_by"]),
            interrupted=bool(data.get("interrupted", False)),
            warm_start_policies=int(data.get("warm_start_policies", 0)),
            guided=None if guided is None else Guided(**guided),
            polished=None if polished is None else Polished(**polished),
        )


@frozen(kw_only=True)
class ModelRecord:
    """The family searched: what the URC observes, its services, its decisions."""

    observation: tuple[str, ...] = field(converter=tuple[str, ...])
    services: tuple[Service, ...] = field(converter=tuple[Service, ...])
    decisions: int
    valuations: int
    valuations_left_out: int
    left_out: tuple[tuple[int, ...], ...] = field(converter=lambda rows: tuple(tuple(int(x) for x in r) for r in rows))

    def to_json(self) -> dict[str, Any]:
        return {
            "observation": list(self.observation),
            "services": [s.to_json() for s in self.services],
            "decisions": self.decisions,
            "valuations": self.valuations,
            "valuations_left_out": self.valuations_left_out,
            "left_out": [list(v) for v in self.left_out],
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ModelRecord:
        left_out = data.get("left_out", [])
        return cls(
            observation=data["observation"],
            services=[Service.from_json(s) for s in data["services"]],
            decisions=int(data["decisions"]),
            valuations=int(data["valuations"]),
            valuations_left_out=int(data.get("valuations_left_out", len(left_out))),
            left_out=left_out,
        )


@frozen(kw_only=True)
class OptimalityRecord:
    """The certified bound's hypervolume against the front's (same reference point)."""

    bound_hypervolume: float
    front_hypervolume: float
    gap: float | None
    """(bound - front) / bound (None: no finite bound)."""
    bound_method: str
    exact: bool
    bound_points: int
    seconds: float
    search: SearchCounts | None = None
    """Branch and bound's counts, where it made the bound."""
    belief: Mapping[str, BeliefValue] | None = None
    """The belief bound's values per objective, where it was asked for."""

    @property
    def method_name(self) -> str:
        """The method's short name (what precedes its explanation)."""
        return self.bound_method.split(":")[0]

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "bound_hypervolume": self.bound_hypervolume,
            "front_hypervolume": self.front_hypervolume,
            "gap": self.gap,
            "bound_method": self.bound_method,
            "exact": self.exact,
            "bound_points": self.bound_points,
            "seconds": self.seconds,
        }
        if self.search is not None:
            out["search"] = self.search.to_json()
        if self.belief is not None:
            out["belief"] = {name: value.to_json() for name, value in self.belief.items()}
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> OptimalityRecord:
        search, belief = data.get("search"), data.get("belief")
        return cls(
            bound_hypervolume=float(data["bound_hypervolume"]),
            front_hypervolume=float(data["front_hypervolume"]),
            gap=_maybe_float(data.get("gap")),
            bound_method=str(data["bound_method"]),
            exact=bool(data["exact"]),
            bound_points=int(data.get("bound_points", 0)),
            seconds=float(data.get("seconds", 0.0)),
            search=None if not search else SearchCounts.from_json(search),
            belief=None if belief is None else {k: BeliefValue.from_json(v) for k, v in belief.items()},
        )


@frozen(kw_only=True)
class ScenarioRecord:
    label: str
    values: Mapping[str, Any] = field(converter=_mapping)
    """The scenario's option values (``set`` in the document)."""
    front_hypervolume: float
    baseline_hypervolume: float


@frozen(kw_only=True)
class RobustRecord:
    """A robust run: what its values are, and the front's and baseline's hypervolume per scenario."""

    objective: str
    scenarios: tuple[ScenarioRecord, ...] = field(converter=tuple[ScenarioRecord, ...])

    def to_json(self) -> dict[str, Any]:
        return {
            "objective": self.objective,
            "scenarios": [
                {
                    "label": s.label,
                    "set": dict(s.values),
                    "front_hypervolume": s.front_hypervolume,
                    "baseline_hypervolume": s.baseline_hypervolume,
                }
                for s in self.scenarios
            ],
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> RobustRecord:
        return cls(
            objective=str(data["objective"]),
            scenarios=[
                ScenarioRecord(
                    label=s["label"],
                    values=s["set"],
                    front_hypervolume=float(s["front_hypervolume"]),
                    baseline_hypervolume=float(s["baseline_hypervolume"]),
                )
                for s in data["scenarios"]
            ],
        )


@frozen(kw_only=True)
class SetRecord:
    """A set of valued policies (the front, the baseline): its size, hypervolume and spread."""

    size: int
    hypervolume: float
    spread: float | None
    points: int | None = None
    """The front's distinct points: policies whose values are ties within the verification
    tolerance share one (None: not recorded, a file from before)."""

    def to_json(self) -> dict[str, Any]:
        document: dict[str, Any] = {"size": self.size, "hypervolume": self.hypervolume, "spread": self.spread}
        if self.points is not None:
            document["points"] = self.points
        return document

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> SetRecord:
        return cls(
            size=int(data["size"]),
            hypervolume=float(data["hypervolume"]),
            spread=_maybe_float(data.get("spread")),
            points=None if data.get("points") is None else int(data["points"]),
        )


KNEE = "knee (closest to the ideal point, normalized)"
"""The rule that chose the selected policy."""


@frozen(kw_only=True)
class RunSummary:
    """A run as ``summary.json`` records it (see the module docstring)."""

    case_study: str
    description: str
    options: Mapping[str, Any] = field(converter=_mapping, hash=False)
    seed: int
    search: SearchRecord
    evaluator: str
    """The evaluator that searched (an :class:`~parley_core.evaluate.EvaluatorKind` value)."""
    evaluator_details: Mapping[str, Any] = field(converter=_mapping, hash=False)
    storm_solver: str
    workers: int
    model: ModelRecord
    objectives: tuple[Objective, ...] = field(converter=tuple[Objective, ...])
    constraints: tuple[Constraint, ...] = field(converter=tuple[Constraint, ...])
    optimality: OptimalityRecord | None
    robust: RobustRecord | None
    infinite_values: Mapping[str, int] = field(converter=_mapping, hash=False)
    """Per objective, how many evaluated policies had an infinite value."""
    front: SetRecord
    baseline: SetRecord
    hypervolume_reference: tuple[float, ...] = field(converter=_floats)
    hypervolume_gain: float
    hypervolume_gain_percent: float | None
    verification: Verification
    selected: str
    """The knee policy, drawn on ``front.png`` and ``policy.png``."""
    selection_rule: str = KNEE
    timings_seconds: Mapping[str, float] = field(converter=_mapping, hash=False)
    versions: Mapping[str, str] = field(converter=_mapping, hash=False)
    schema: int = SCHEMA

    def to_json(self) -> dict[str, Any]:
        return {
            "schema": self.schema,
            "case_study": self.case_study,
            "description": self.description,
            "options": dict(self.options),
            "seed": self.seed,
            "search": self.search.to_json(),
            "evaluator": self.evaluator,
            "evaluator_details": dict(self.evaluator_details),
            "storm_solver": self.storm_solver,
            "workers": self.workers,
            "model": self.model.to_json(),
            "objectives": [o.to_json() for o in self.objectives],
            "constraints": [str(c) for c in self.constraints],
            "optimality": None if self.optimality is None else self.optimality.to_json(),
            "robust": None if self.robust is None else self.robust.to_json(),
            "infinite_values": dict(self.infinite_values),
            "front": self.front.to_json(),
            "baseline": self.baseline.to_json(),
            "hypervolume_reference": list(self.hypervolume_reference),
            "hypervolume_gain": self.hypervolume_gain,
            "hypervolume_gain_percent": self.hypervolume_gain_percent,
            "verification": self.verification.to_json(),
            "selected": {"policy": self.selected, "rule": self.selection_rule},
            "timings_seconds": dict(self.timings_seconds),
            "versions": dict(self.versions),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> RunSummary:
        optimality, robust = data.get("optimality"), data.get("robust")
        selected = data["selected"]
        return cls(
            schema=int(data.get("schema", 1)),
            case_study=str(data["case_study"]),
            description=str(data.get("description", "")),
            options=data.get("options", {}),
            seed=int(data["seed"]),
            search=SearchRecord.from_json(data["search"]),
            evaluator=str(data["evaluator"]),
            evaluator_details=data.get("evaluator_details", {}),
            storm_solver=str(data.get("storm_solver", "")),
            workers=int(data.get("workers", 1)),
            model=ModelRecord.from_json(data["model"]),
            objectives=[Objective.from_json(o) for o in data["objectives"]],
            constraints=[Constraint.parse(c) for c in data.get("constraints", [])],
            optimality=None if not optimality else OptimalityRecord.from_json(optimality),
            robust=None if not robust else RobustRecord.from_json(robust),
            infinite_values=data.get("infinite_values", {}),
            front=SetRecord.from_json(data["front"]),
            baseline=SetRecord.from_json(data["baseline"]),
            hypervolume_reference=data["hypervolume_reference"],
            hypervolume_gain=float(data.get("hypervolume_gain", float("nan"))),
            hypervolume_gain_percent=_maybe_float(data.get("hypervolume_gain_percent")),
            verification=Verification.from_json(data["verification"]),
            selected=str(selected["policy"]),
            selection_rule=str(selected.get("rule", KNEE)),
            timings_seconds=data.get("timings_seconds", {}),
            versions=data.get("versions", {}),
        )
