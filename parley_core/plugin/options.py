"""Case-study options: typed fields, and their values from ``KEY=VALUE`` strings.

A case study's options are a frozen attrs class whose fields all have defaults and a help
text. :func:`option`, :func:`positive` and :func:`probability` are the plugin kit's field
helpers; ``--set KEY=VALUE`` strings are converted by the fields' type annotations: int,
float, str, bool, Path, ``X | None``, and tuples of numbers: ``tuple[int, int]`` from ``1:0``,
``tuple[float, float]`` from ``0.7:1.0``, ``tuple[tuple[int, int], ...]`` from
``0:3,0:4,1:3`` (a cell list), ``tuple[int, ...]`` from ``1:2:3``. A tuple option is written
back (summary.json, a campaign store) in the same text form, so that it reads as it was given.
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


def option(
    default: Any, help: str, *checks: Validator | list[Validator], converter: Callable[[Any], Any] | None = None
) -> Any:
    """An option field: its default, its help text (shown by ``parley options``), validators
    (each given alone or in a list) and an optional ``converter`` applied to the value before
    they run (``converter=float`` lets a float option take an int from Python)."""
    flat = [v for check in checks for v in (check if isinstance(check, list) else [check])]
    return attrs.field(default=default, validator=flat or None, converter=converter, metadata={"help": help})


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
    """Options as JSON-friendly values (paths and tuples as their ``--set`` text)."""
    return {
        k: (as_text(v) if isinstance(v, (Path, tuple)) else v) for k, v in attrs.asdict(options, recurse=False).items()
    }


def as_text(value: Any) -> str:
    """An option value as ``--set`` takes it: ``(1, 0)`` as ``1:0``, ``((0, 3), (0, 4))`` as
    ``0:3,0:4``, ``None`` as ``none``."""
    if value is None:
        return "none"
    if isinstance(value, tuple):
        if value and all(isinstance(v, tuple) for v in value):
            return ",".join(as_text(v) for v in value)
        return ":".join(_number_text(v) for v in value)
    return str(value)


def _number_text(value: Any) -> str:
    return repr(value) if isinstance(value, float) else str(value)


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
    names = " or ".join(_describe(c) for c in choices)
    raise OptionError(f"option {key}={text!r} for {case}: expected {names}")


def _describe(kind: Any) -> str:
    if kind is type(None):
        return "none"
    if typing.get_origin(kind) is tuple:
        args = typing.get_args(kind)
        if len(args) == 2 and args[1] is Ellipsis and typing.get_origin(args[0]) is tuple:
            return f"a list X:Y,X:Y,... of {_describe(args[0])}"
        if len(args) == 2 and args[1] is Ellipsis:
            return f"values A:B:... of {_describe(args[0])}"
        return ":".join(_describe(a) for a in args)
    return getattr(kind, "__name__", str(kind))


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
    if typing.get_origin(kind) is tuple:
        return _convert_tuple(text, typing.get_args(kind))
    raise ValueError(f"unsupported option type {kind!r}")


def _convert_tuple(text: str, args: tuple[Any, ...]) -> tuple[Any, ...]:
    """``1:0`` for ``(int, int)``; ``0:3,0:4`` for ``(tuple[int, int], ...)``; ``1:2:3`` for ``(int, ...)``."""
    if len(args) == 2 and args[1] is Ellipsis:
        inner = args[0]
        if typing.get_origin(inner) is tuple:
            items = [item.strip() for item in text.split(",") if item.strip()]
            return tuple(_convert_one(item, inner) for item in items)
        return tuple(_convert_one(part.strip(), inner) for part in text.split(":") if part.strip())
    parts = [part.strip() for part in text.split(":")]
    if len(parts) != len(args):
        raise ValueError(text)
    return tuple(_convert_one(part, kind) for part, kind in zip(parts, args))
