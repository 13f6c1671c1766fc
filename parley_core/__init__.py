"""Parley: synthesis of uncertainty reduction controllers with formal guarantees.

The public API. Plugins import what they need from here: ``hookimpl`` to mark their hook
functions, :class:`CaseStudy`, the value objects of :mod:`parley_core.model`, the plugin
kit (:func:`option`, :func:`positive`, :data:`probability`, :meth:`Baseline.sweep`,
:meth:`PolicyTable.values_of`, :func:`read_text`) and the error types. PRISM text is
written with :mod:`parley_core.prism.writer`, policy plots with :mod:`parley_core.views.plotting`,
and plugin tests use :mod:`parley_core.testing`. Importing this package imports neither
stormpy nor matplotlib.
"""

from parley_core.constraints import Constraint
from parley_core.errors import ModelError, ObservationError, OptionError, ParleyError, PolicyError
from parley_core.files import read_text
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
    Valued,
)
from parley_core.plugin.casestudy import CaseStudy, PolicyTable
from parley_core.plugin.hookspecs import hookimpl
from parley_core.plugin.options import option, positive, probability
from parley_core.plugin.policymap import PolicyMap
from parley_core.plugin.simulator import Episodes, Simulator
from parley_core.urc.controller import URC

__version__ = "0.1.0"

__all__ = [
    "URC",
    "Baseline",
    "CaseStudy",
    "Constraint",
    "Decision",
    "DecisionKind",
    "Direction",
    "Episodes",
    "Family",
    "Front",
    "ModelError",
    "ObservationError",
    "Objective",
    "OptionError",
    "ParleyError",
    "Policy",
    "PolicyError",
    "PolicyMap",
    "PolicyTable",
    "Service",
    "Simulator",
    "SystemModel",
    "Valued",
    "hookimpl",
    "option",
    "positive",
    "probability",
    "read_text",
]
