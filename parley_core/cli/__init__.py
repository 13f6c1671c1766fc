"""The ``parley`` command: the only place that prints, colors or chooses exit codes.

User errors (any :class:`~parley_core.errors.ParleyError`) end as one line on stderr,
``error: ...``, with exit status 2. Progress goes to stderr, so ``--json`` output on stdout
is one JSON document and nothing else.

- :mod:`.app`: the typer applications; :mod:`.common`: errors, case studies, limits;
  :mod:`.options`: the option types; :mod:`.console`: progress bars and tables;
- command groups: :mod:`.case_studies` (list, options), :mod:`.synthesis` (run,
  synthesize, augment), :mod:`.requirements` (check, check-model, recheck), :mod:`.controllers` (select, simulate, validate), :mod:`.adaptation` (adapt, and
  simulate's drift mode), :mod:`.evaluation`
  (evaluate, baseline), :mod:`.experiment` (experiment run, verify, report, scalability).
"""

from __future__ import annotations

import os
import sys
import warnings

from parley_core.cli import adaptation, case_studies, controllers, evaluation, experiment, requirements, synthesis  # noqa: F401, I001  (they register commands, in this order)
from parley_core.cli.app import app
from parley_core.errors import PluginWarning


def main() -> None:
    """The command, with each broken plugin's warning printed once as ``warning: ...``."""
    shown: set[str] = set()
    original = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if not issubclass(category, PluginWarning):
            original(message, category, filename, lineno, file, line)
        elif str(message) not in shown:
            shown.add(str(message))
            print(f"warning: {message}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.simplefilter("always", PluginWarning)
        warnings.showwarning = show
        app(prog_name=os.environ.get("PARLEY_PROGRAM", "parley"))


__all__ = ["app", "main"]
