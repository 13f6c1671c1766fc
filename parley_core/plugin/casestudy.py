"""The case-study value object that plugins return: the one reference for its fields."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

import attrs
from attrs import field, frozen, validators

from parley_core.docstrings import fields_in_help
from parley_core.errors import OptionError
from parley_core.model import SystemModel
from parley_core.plugin.options import as_text, convert, parse_assignments
from parley_core.plugin.policymap import PolicyMap
from parley_core.plugin.simulator import Simulator
from parley_core.progress import Reporter
from parley_core.urc.events import EventModel


class PolicyTable(Mapping[tuple[int, ...], Mapping[str, int]]):
    """A policy seen from a plugin: observation valuation -> {service constant: value}."""

    def __init__(self, table: Mapping[tuple[int, ...], Mapping[str, int]]) -> None:
        self._table = {tuple(v): dict(d) for v, d in table.items()}

    def __getitem__(self, valuation: tuple[int, ...]) -> Mapping[str, int]:
        return self._table[valuation]

    def __iter__(self) -> Iterator[tuple[int, ...]]:
        return iter(self._table)

    def __len__(self) -> int:
        return len(self._table)

    def values_of(self, constant: str) -> dict[tuple[int, ...], int]:
        """Valuation -> the value of one service constant (what a one-service plot draws)."""
        return {valuation: decision[constant] for valuation, decision in self._table.items()}


@fields_in_help
@frozen(kw_only=True)
class CaseStudy:
    """A case study: a name, typed options and a builder of system models.

    This docstring and the field docstrings below are the reference for plugin authors; the
    hook specification and docs/plugins.md point here.
    """

    name: str = field(validator=validators.matches_re(r"[a-z][a-z0-9_]*"))
    """What ``parley run NAME`` takes: lower case, digits and underscores, unique among the
    installed plugins."""
    description: str = field(validator=validators.min_len(1))
    """One line, shown by ``parley list``."""
    options_type: type = field()
    """A frozen attrs class whose fields all have defaults and a ``metadata["help"]`` text
    (use :func:`parley_core.option`); ``--set KEY=VALUE`` strings are converted by the
    fields' type annotations (int, float, str, bool, Path, and ``X | None``)."""
    build: Callable[[Any], SystemModel] = field()
    """``build(options) -> SystemModel``, called once per run; it raises
    :class:`~parley_core.ParleyError` subclasses for bad input (a missing map file, a map
    without a path...)."""
    warm_up: Callable[[Any, Reporter], None] | None = None
    """Optionally, ``warm_up(options, reporter)`` does a build's slow one-off work before
    ``build`` runs (turtlebot samples its motions from MuJoCo here, once, and caches them),
    announcing it as a stage of ``reporter`` so the CLI draws a progress bar. ``build``
    must not depend on it having run: library callers may call ``build`` alone."""
    simulator: Simulator | None = None
    """Optionally, a closed-loop simulator of the system (:class:`parley_core.plugin.simulator.Simulator`):
    ``parley validate RUN_DIR`` runs a run's policies on it against Storm's values."""
    events: Mapping[str, EventModel] = field(factory=dict, converter=dict)
    """Optionally, by option name, what the system observes about a drifting parameter
    (:class:`parley_core.urc.adaptive.EventModel`: which transitions are trials, how likely
    their outcomes are under each value): an adaptive URC (``parley adapt``) switches policy
    by it, and ``parley simulate --drift`` runs it (robot_grid: localisations that find the
    estimate wrong tell about the slip probability ``p``)."""
    plot_policy: Callable[[SystemModel, PolicyTable, Path], None] | None = None
    """Optionally draws one policy as a PNG for the run report: ``plot_policy(system, table,
    path)``. A failing plot costs only the plot (the run says why in policy-plot-error.txt)."""
    policy_map: Callable[[SystemModel], PolicyMap] | None = None
    """Optionally, the map the interactive report draws a policy on
    (:class:`parley_core.plugin.policymap.PolicyMap`: axes, obstacles, start and target), from the
    built system; without one, the report's grid shows the first two observation variables."""
    quick: Mapping[str, str] = field(factory=dict, converter=dict)
    """Option values (``--set`` strings) for a small instance that builds and searches in
    seconds; the conformance suite runs every case study with them."""
    requirement_settings: tuple[tuple[float, ...], ...] = field(
        default=(), converter=lambda rows: tuple(tuple(float(v) for v in row) for row in rows)
    )
    """Campaign reports' default requirement settings: one worst acceptable value per
    objective each (robot_grid: the paper's nine, e.g. success >= 0.7 and cost <= 80)."""
    figure_setting: tuple[float, ...] | None = field(
        default=None, converter=lambda row: None if row is None else tuple(float(v) for v in row)
    )
    """The requirement setting of a campaign report's box plots (default: the first of
    ``requirement_settings``)."""
    prune: bool = False
    """Decide only at the observation valuations where a service is consulted in some
    reachable state (found on the quotient MDP), as ``parley synthesize`` does. Off by
    default, so that a policy has one value per valuation in the variables' ranges (as the
    paper's published policies have); worth it where most valuations are never consulted."""

    @options_type.validator
    def _check_options_type(self, _attribute: attrs.Attribute, value: type) -> None:
        if not attrs.has(value):
            raise TypeError(f"case study {self.name!r}: options_type must be an attrs class")
        for f in attrs.fields(value):
            if f.default is attrs.NOTHING:
                raise TypeError(f"case study {self.name!r}: option {f.name!r} needs a default")

    def option_fields(self) -> tuple[attrs.Attribute, ...]:
        attrs.resolve_types(self.options_type)
        return attrs.fields(self.options_type)

    def options(self, assignments: Iterable[str] = (), **overrides: Any) -> Any:
        """Options from ``KEY=VALUE`` strings (as given to ``--set``), over the defaults."""
        values = parse_assignments(assignments)
        values.update({k: as_text(v) for k, v in overrides.items()})
        return self.options_from(values)

    def options_from(self, values: Mapping[str, str]) -> Any:
        """Options from ``{KEY: VALUE}`` strings, over the defaults."""
        fields = {f.name: f for f in self.option_fields()}
        kwargs: dict[str, Any] = {}
        for key, text in values.items():
            if key not in fields:
                raise OptionError(
                    f"unknown option {key!r} for {self.name}; valid options: {', '.join(fields) or 'none'}"
                )
            kwargs[key] = convert(self.name, key, text, fields[key].type)
        try:
            return self.options_type(**kwargs)
        except OptionError:
            raise
        except (TypeError, ValueError) as exc:
            raise OptionError(f"{self.name}: {exc}") from None

    def options_from_json(self, values: Mapping[str, Any]) -> Any:
        """Options from the JSON form :func:`parley_core.plugin.options.options_as_dict` writes
        (a run's summary.json, a campaign store)."""
        return self.options_from({k: as_text(v) for k, v in values.items()})
