"""Run as a script by test_imports.py: import every module of parley, parley_core and the
built-in plugins (plus any modules named on the command line) and print, as JSON, which
pieces of process-wide state changed.

The third-party libraries parley imports are imported first: some of them set warnings
filters of their own at import (scipy, numpy's testing helpers), which is theirs to do and
the same with or without parley. What is measured is what parley's own modules change."""

from __future__ import annotations

import importlib
import json
import logging
import os
import pkgutil
import signal
import sys
import warnings

import matplotlib
import numpy as np
import stormpy.developer as storm_dev

storm_calls: list[str] = []
_real_set_log_level = storm_dev.set_log_level


def _recording(level):  # Storm's log level has no getter: record who sets it
    storm_calls.append(str(level))
    _real_set_log_level(level)


storm_dev.set_log_level = _recording


def state() -> dict[str, str]:
    return {
        "warnings filters": repr(warnings.filters),
        "matplotlib backend": repr(matplotlib.rcParams._get_backend_or_none()),
        # read without rcParams' own __getitem__, which would resolve the backend
        "matplotlib rcParams": repr(sorted((k, repr(v)) for k, v in dict.items(matplotlib.rcParams) if k != "backend")),
        "logging": repr((logging.root.level, logging.root.handlers)),
        "numpy errors": repr(np.geterr()),
        "numpy print options": repr(np.get_printoptions()),
        "environment": repr(sorted(os.environ.items())),
        "excepthook": repr(sys.excepthook),
        "SIGINT handler": repr(signal.getsignal(signal.SIGINT)),
        "recursion limit": repr(sys.getrecursionlimit()),
        "working directory": os.getcwd(),
        "Storm's log level": repr(storm_calls),
    }


def modules() -> list[str]:
    import parley_core
    import parley_plugins

    names = ["parley"]
    for package in (parley_core, parley_plugins):
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            if ".tests" not in info.name:
                names.append(info.name)
    return names


THIRD_PARTY = (
    "attrs",
    "moocore",
    "mujoco",
    "numba",
    "pluggy",
    "pymoo",
    "pytest",
    "rich",
    "scipy",
    "stormpy",
    "typer",
    "matplotlib.figure",
    "matplotlib.backends.backend_agg",
    "pymoo.algorithms.moo.nsga2",
    "scipy.optimize",
    "scipy.sparse",
    "scipy.stats",
    "typer.testing",
    "hypothesis",
    "pandas",
)
for name in THIRD_PARTY:
    importlib.import_module(name)
before = state()
names = modules()
for name in names + sys.argv[1:]:
    importlib.import_module(name)
after = state()
changed = sorted(k for k in before if before[k] != after[k])
print(json.dumps({"modules": len(names), "changed": changed, "before": before, "after": after}))
