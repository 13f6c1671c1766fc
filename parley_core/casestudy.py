"""The case-study value object that plugins return, and typed options from ``KEY=VALUE`` strings."""

from __future__ import annotations

import types
import typing
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import attrs
from attrs import field, frozen, validators

from parley_core.errors import OptionError
from parley_core.model import SystemModel

PolicyTable = Mapping[tuple[int, ...], Mapping[str, int]]
"""A policy seen from a plugin: observation valuation -> {service constant: value}."""


@frozen(kw_only=True)
class CaseStudy:
    """A case study: a name, typed options and a builder of system models.

    - ``options_type`` is a frozen attrs class whose fields all have defaults; each field's
      ``metadata["help"]`` documents it. ``--set KEY=VALUE`` strings are converted by the
      fields' type annotations (int, float, str, bool, Path, and ``X | None``).
    - ``build(options)`` returns the :class:`SystemModel`; it raises ``ParleyError`` subclasses
      for bad input (a missing map file, a map without a path...).
    - ``plot_policy(system, table, path)`` optionally draws one policy (PNG) for the run report.
    - ``quick`` are option values for a small instance that builds and searches in seconds; the
      conformance suite runs every case study with them.
    - ``requirement_settings`` are campaign reports' default settings: one worst acceptable
      value per objective each (robot_grid: the paper's nine, e.g. success >= 0.7, cost <= 80).
    - ``prune``: decide only at the observation valuations where a service is consulted in
      some reachable state (found on the quotient MDP), as ``parley synthesize`` does. Off by
      default, so that a policy has one value per valuation in the variables' ranges (as the
      paper's published policies have); worth it where most valuations are never consulted.
    """

    name: str = field(validator=validators.matches_re(r"[a-z][a-z0-9_]*"))
    description: str = field(validator=validators.min_len(1))
    options_type: type = field()
    build: Callable[[Any], SystemModel] = field()
    plot_policy: Callable[[SystemModel, PolicyTable, Path], None] | None = None
    quick: Mapping[str, str] = field(factory=dict, converter=dict)
    requirement_settings: tuple[tuple[float, ...], ...] = field(
        default=(), converter=lambda rows: tuple(tuple(float(v) for v in row) for row in rows)
    )
    prune: bool = False

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
        values.update({k: str(v) for k, v in overrides.items()})
        return self.options_from(values)

    def options_from(self, values: Mapping[str, str]) -> Any:
        fields = {f.name: f for f in self.option_fields()}
        kwargs: dict[str, Any] = {}
        for key, text in values.items():
            if key not in fields:
                raise OptionError(
                    f"unknown option {key!r} for {self.name}; valid options: {', '.join(fields) or 'none'}"
                )
            kwargs[key] = _convert(self.name, key, text, fields[key].type)
        try:
            return self.options_type(**kwargs)
        except OptionError:
            raise
        except (TypeError, ValueError) as exc:
            raise OptionError(f"{self.name}: {exc}") from None


def parse_assignments(assignments: Iterable[str]) -> dict[str, str]:
    """``["a=1", "b=x"]`` -> ``{"a": "1", "b": "x"}``; a malformed item raises OptionError."""
    result: dict[str, str] = {}
    for item in assignments:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise OptionError(f"malformed option {item!r}; write KEY=VALUE, for example --set size=20")
        if key in result:
            raise OptionError(f"option {key!r} is given twice; give it once")
        result[key] = value.strip()
    return result


def options_as_dict(options: Any) -> dict[str, Any]:
    """Options as JSON-friendly values (paths as strings)."""
    return {
        k: (str(v) if isinstance(v, Path) else v)
        for k, v in attrs.asdict(options, recurse=False).items()
    }


def _convert(case: str, key: str, text: str, annotation: Any) -> Any:
    choices = _alternatives(annotation)
    if type(None) in choices and text.lower() in ("", "none"):
        return None
    for kind in choices:
        if kind is type(None):
            continue
        try:
            return _convert_one(text, kind)
        except ValueError:
            continue
    names = " or ".join("none" if c is type(None) else getattr(c, "__name__", str(c)) for c in choices)
    raise OptionError(f"option {key}={text!r} for {case}: expected {names}")


def _alternatives(annotation: Any) -> tuple[Any, ...]:
    if isinstance(annotation, types.UnionType) or typing.get_origin(annotation) is typing.Union:
        return typing.get_args(annotation)
    return (annotation,)


def _convert_one(text: str, kind: Any) -> Any:
    if kind is bool:
        lowered = text.lower()
        if lowered in ("1", "true", "yes", "on"):
            return True
        if lowered in ("0", "false", "no", "off"):
            return False
        raise ValueError(text)
    if kind is int:
        return int(text)
    if kind is float:
        return float(text)
    if kind is Path:
        if not text:
            raise ValueError(text)
        return Path(text).expanduser()
    if kind is str:
        return text
    raise ValueError(f"unsupported option type {kind!r}")
