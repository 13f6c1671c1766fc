"""Field documentation for ``help()``: attrs keeps no docstring of a field, so the one
written under it in the class body (which the reference pages show) would be invisible
in the interpreter. :func:`fields_in_help` gives a class a docstring that ends with a
*Fields* section, made when it is first read (nothing is parsed at import)."""

from __future__ import annotations

import ast
import inspect
import textwrap
from typing import Any, TypeVar

import attrs

_C = TypeVar("_C", bound=type)


def _written(cls: type) -> dict[str, str]:
    """The docstrings written under the fields of ``cls``'s own body, by field name."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError, SyntaxError):
        return {}
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    found = {}
    for statement, following in zip(body, body[1:]):
        if (
            isinstance(statement, ast.AnnAssign)
            and isinstance(statement.target, ast.Name)
            and isinstance(following, ast.Expr)
            and isinstance(following.value, ast.Constant)
            and isinstance(following.value.value, str)
        ):
            found[statement.target.id] = inspect.cleandoc(following.value.value)
    return found


def fields_section(cls: type) -> str:
    """``Fields:`` then each attrs field of ``cls`` with its type, its default and its docstring."""
    docs: dict[str, str] = {}
    for base in reversed(cls.__mro__):
        if attrs.has(base):
            docs.update(_written(base))
    lines = ["Fields:"]
    for field in attrs.fields(cls):
        kind = field.type if isinstance(field.type, str) else getattr(field.type, "__name__", str(field.type))
        default = "" if field.default is attrs.NOTHING else " (optional)"
        lines.append(f"    {field.name}: {kind}{default}")
        for line in docs.get(field.name, "").splitlines():
            lines.append(f"        {line}")
    return "\n".join(lines)


class _Doc:
    """A class's ``__doc__``: its own text, then :func:`fields_section`, made on first read."""

    def __init__(self, text: str | None) -> None:
        self.text = inspect.cleandoc(text or "")
        self.made: dict[type, str] = {}

    def __get__(self, instance: Any, owner: type) -> str:
        if owner not in self.made:
            self.made[owner] = f"{self.text}\n\n{fields_section(owner)}".strip()
        return self.made[owner]


def fields_in_help(cls: _C) -> _C:
    """A class decorator (below attrs'): ``help(cls)`` lists its fields with their docstrings."""
    cls.__doc__ = _Doc(cls.__dict__.get("__doc__"))  # type: ignore[assignment]
    return cls
