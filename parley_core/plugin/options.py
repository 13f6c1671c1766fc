"""Case-study options: typed fields, and their values from ``KEY=VALUE`` strings.

A case study's options are a frozen attrs class whose fields all have defaults and a help
text. :func:`option`, :func:`positive` and :func:`probability` are the plugin kit's field
helpers; ``--set KEY=VALUE`` strings are converted by the fields' type annotations (int,
float, str, bool, Path, and ``X | None``).
"""

from __future__ import annotations

import types
import typing
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import attrs
from attrs import validators

from parley_core.errors import OptionError

Validator = Callable[[Any, attrs.Attribute, Any], None]


def option(default: Any, help: str, *checks: Validator | list[Validator]) -> Any:
    """An option field: its default, its help text (shown by ``parley options``) and
    validators (each given alone or in a list)."""
    flat = [v for check in checks for v in (check if isinstance(check, list) else [check])]
    return attrs.field(default=default, validator=flat or None, metadata={"help": help})


def positive(_instance: Any, attribute: attrs.Attribute, value: Any) -> None:
    """A validator: the option must be greater than zero."""
    if value <= 0:
        raise ValueError(f"option {attribute.name} must be positive, got {value}")


probability: Validator = validators.and_(validators.ge(0.0), validators.le(1.0))
"""A validator: the option must lie in [0, 1]."""


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
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in attrs.asdict(options, recurse=False).items()}


def convert(case: str, key: str, text: str, annotation: Any) -> Any:
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
