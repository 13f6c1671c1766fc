"""Parley: synthesis of uncertainty reduction controllers with formal guarantees.

Plugins import what they need from here: ``hookimpl`` to mark their hook functions, the
value objects of :mod:`parley_core.model`, :class:`CaseStudy`, the PRISM writer and the
error types.
"""

from parley_core.casestudy import CaseStudy, PolicyTable
from parley_core.errors import ModelError, OptionError, ParleyError, PolicyError
from parley_core.hookspecs import hookimpl
from parley_core.model import (
    Baseline,
    Decision,
    DecisionKind,
    Direction,
    Family,
    Front,
    Objective,
    Policy,
    Service,
    SystemModel,
)

__version__ = "0.1.0"

__all__ = [
    "Baseline",
    "CaseStudy",
    "Decision",
    "DecisionKind",
    "Direction",
    "Family",
    "Front",
    "ModelError",
    "Objective",
    "OptionError",
    "ParleyError",
    "Policy",
    "PolicyError",
    "PolicyTable",
    "Service",
    "SystemModel",
    "hookimpl",
]
