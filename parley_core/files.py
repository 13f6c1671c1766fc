"""Reading a user's files with errors that say what to do."""

from __future__ import annotations

from pathlib import Path

from parley_core.errors import ParleyError


def read_text(path: Path, what: str, hint: str, error: type[ParleyError] = ParleyError) -> str:
    """The text of a user's file, or ``error`` saying that ``what`` (e.g. "map file") is missing or unreadable."""
    if not path.is_file():
        raise error(f"{what} {path} does not exist; {hint}")
    try:
        return path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{what} {path} cannot be read ({exc}); {hint}") from None
