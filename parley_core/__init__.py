"""Parley: synthesis of uncertainty reduction controllers with formal guarantees.

The public API. Plugins import what they need from here: ``hookimpl`` to mark their hook
functions, :class:`CaseStudy`, the value objects of :mod:`parley_core.model`, the plugin
kit (:func:`option`, :func:`positive`, :data:`probability`, :meth:`Baseline.sweep`,
:meth:`PolicyTable.values_of`, :func:`read_text`), the :class:`Reporter` a ``warm_up``
reports to, the :class:`EventModel` of an adaptive URC, the figure helpers :func:`figure`
and :func:`save` for policy plots, and the error types. PRISM text is written with
:mod:`parley_core.prism.writer`, and plugin tests use :mod:`parley_core.testing`. These
names stay where they are when the modules behind them move. Importing this package
imports neither stormpy nor matplotlib (``figure`` and ``save`` load matplotlib when first
used).
"""

from importlib import metadata
from typing import TYPE_CHECKING, Any

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
from parley_core.progress import Reporter
from parley_core.urc.controller import URC
from parley_core.urc.events import EventModel

if TYPE_CHECKING:
    from parley_core.views.plotting import figure, save

try:
    __version__ = metadata.version("parley")
except metadata.PackageNotFoundError:  # run from a source tree that was never installed
    __version__ = "0+unknown"


def __getattr__(name: str) -> Any:
    """``figure`` and ``save`` (:mod:`parley_core.views.plotting`), imported when first used:
    they need matplotlib, which ``import parley_core`` does not load."""
    if name in ("figure", "save"):
        from parley_core.views import plotting

        return getattr(plotting, name)
    raise AttributeError(f"module 'parley_core' has no attribute {name!r}")


__all__ = [
    "URC",
    "Baseline",
    "CaseStudy",
    "Constraint",
    "Decision",
    "DecisionKind",
    "Direction",
    "Episodes",
    "EventModel",
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
    "Reporter",
    "Service",
    "Simulator",
    "SystemModel",
    "Valued",
    "figure",
    "hookimpl",
    "option",
    "positive",
    "probability",
    "read_text",
    "save",
]
