"""What a plugin imports: the one public surface for case-study plugins.

``from parley.plugin import CaseStudy, hookimpl, ...``:

- the hook marker ``hookimpl`` and :class:`CaseStudy`;
- the value objects (``SystemModel``, ``Service``, ``Objective``, ``Baseline``,
  ``Direction``, ``DecisionKind``);
- the option kit (``option``, ``positive``, ``probability``);
- the PRISM writer classes (``Program``, ``Module``, ``Command``, ``Update``,
  ``Variable``, ``Constant``, ``Formula``, ``Label``, ``Rewards``, ``RewardItem``);
- the optional parts of a case study (``PolicyMap``, ``PolicyTable``, ``Simulator``,
  ``Episodes``, ``EventModel``, ``Reporter``);
- the figure helpers ``figure`` and ``save``, which load matplotlib when first used;
- ``read_text`` and the error types.

Importing this module imports neither stormpy nor matplotlib. The same names stay
importable from :mod:`parley_core`, where they are defined. A plugin's tests use
:mod:`parley_core.testing`.
"""

from typing import TYPE_CHECKING, Any

from parley_core import (
    Baseline,
    CaseStudy,
    DecisionKind,
    Direction,
    Episodes,
    EventModel,
    ModelError,
    Objective,
    OptionError,
    ParleyError,
    PolicyMap,
    PolicyTable,
    Reporter,
    Service,
    Simulator,
    SystemModel,
    hookimpl,
    option,
    positive,
    probability,
    read_text,
)
from parley_core.errors import PluginError
from parley_core.prism.writer import (
    Command,
    Constant,
    Formula,
    Label,
    Module,
    Program,
    RewardItem,
    Rewards,
    Update,
    Variable,
)

if TYPE_CHECKING:
    from parley_core.views.plotting import figure, save


def __getattr__(name: str) -> Any:
    """``figure`` and ``save``, imported when first used (they need matplotlib), as
    :mod:`parley_core` gives them."""
    if name in ("figure", "save"):
        import parley_core

        return getattr(parley_core, name)
    raise AttributeError(f"module 'parley.plugin' has no attribute {name!r}")


__all__ = [
    "Baseline",
    "CaseStudy",
    "Command",
    "Constant",
    "DecisionKind",
    "Direction",
    "Episodes",
    "EventModel",
    "Formula",
    "Label",
    "ModelError",
    "Module",
    "Objective",
    "OptionError",
    "ParleyError",
    "PluginError",
    "PolicyMap",
    "PolicyTable",
    "Program",
    "Reporter",
    "RewardItem",
    "Rewards",
    "Service",
    "Simulator",
    "SystemModel",
    "Update",
    "Variable",
    "figure",
    "hookimpl",
    "option",
    "positive",
    "probability",
    "read_text",
    "save",
]
