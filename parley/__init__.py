"""Parley as a library: synthesize uncertainty reduction controllers from Python.

One call per command that makes results, value objects out, nothing printed (progress
bars on stderr unless ``progress=False``), errors as parley's exception types::

    import parley

    run = parley.run("robot_grid", map="path/to/map_10.csv", seed=1)   # writes runs/robot_grid-TIME/
    run.front.to_pandas()          # the Storm-verified front (pandas: pip install 'parley[notebook]')
    run.baseline, run.summary, run.optimality
    run.plot()                     # a matplotlib Figure: front, baseline, bound
    run.report                     # the interactive report.html, inline in Jupyter
    urc = run.select(["success>=0.8"], prefer="cost").controller()
    urc.decide({"xhat": 3, "yhat": 4})   # the runtime URC
    parley.load(run.directory) == run

    parley.synthesize("pump.prism", props="pump.pctl", decisions={"c": (1, 8)}, observe=["est"])
    parley.exact("web_ids", time_limit=60)
    parley.experiment("robot_grid", store="campaign.sqlite", reps=2, generations=5)
    parley.evaluate("robot_grid", constant=3), parley.baseline("tas"), parley.case_studies()
    run.simulate(episodes=1000), parley.run("turtlebot").validate()

The implementation is ``parley_core`` (plugins import it); importing ``parley`` imports
neither stormpy nor matplotlib, and changes no global state.
"""

from parley_core import __version__
from parley_core.api import *  # noqa: F403  (the library API: every name of parley_core.api.__all__)
from parley_core.api import __all__ as _api
from parley_core.constraints import Constraint
from parley_core.errors import (
    ModelError,
    OptionError,
    OutputError,
    ParleyDefect,
    ParleyError,
    PolicyError,
    SearchError,
    WorkerError,
)
from parley_core.model import Front, Objective, Policy, Valued
from parley_core.urc.controller import URC

__all__ = [
    *_api,
    "URC",
    "Constraint",
    "Front",
    "ModelError",
    "Objective",
    "OptionError",
    "OutputError",
    "ParleyDefect",
    "ParleyError",
    "Policy",
    "PolicyError",
    "SearchError",
    "Valued",
    "WorkerError",
    "__version__",
]
