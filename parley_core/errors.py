"""Exception types for errors a user can cause.

Every message says what is wrong and what to do about it, on one line. The CLI prints
``error: <message>`` and exits with status 2; library users catch :class:`ParleyError`.
Anything else that escapes is a bug in parley.
"""

from __future__ import annotations


class ParleyError(Exception):
    """Base class of every error a user can cause (bad input, unknown names, missing files)."""


class PluginError(ParleyError):
    """A plugin is malformed, or two plugins register the same case study."""


class PluginWarning(UserWarning):
    """An installed plugin is broken and was skipped; the other case studies stay usable
    (the command prints it once as ``warning: ...``)."""


class UnknownCaseStudyError(ParleyError):
    """The requested case study is not registered."""


class OptionError(ParleyError):
    """A ``--set KEY=VALUE`` option is malformed, unknown or out of range."""


class ModelError(ParleyError):
    """A PRISM model or property does not parse, or does not fit what parley needs."""


class PolicyError(ParleyError):
    """A policy or a policies file is malformed or does not match the model's decisions."""


class OutputError(ParleyError):
    """An output location cannot be used."""


class SearchError(ParleyError):
    """A search found nothing to report (no evaluated policy meets the constraints)."""


class ObservationError(ParleyError):
    """An observation the controller was not synthesized for."""


class WorkerError(ParleyError):
    """A worker process ended abnormally (a crash in Storm, the memory killer) or could not
    start; the work stopped cleanly."""


class ParleyDefect(Exception):
    """Something parley got wrong, not the user: the CLI prints it in one line and exits with
    status 3, and asks for a report. Never a subclass of :class:`ParleyError`."""


class EvaluatorDisagreement(ParleyDefect):
    """The search's evaluator and Storm's re-check give different values for a policy."""
