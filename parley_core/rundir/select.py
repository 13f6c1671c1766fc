"""Choosing one policy from a front, and making it a controller."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from parley_core import metrics
from parley_core.constraints import Constraint, meets
from parley_core.errors import OptionError
from parley_core.rundir.read import RunDirectory
from parley_core.urc.controller import URC


def select(run: RunDirectory, constraints: Sequence[Constraint] = (), prefer: str | None = None) -> str:
    """The name of the chosen front policy: among those meeting the constraints, the best
    on ``prefer`` (ties: the knee of those), or else the knee point."""
    names = [o.name for o in run.objectives]
    values = np.array(run.front.values, dtype=float).reshape(-1, len(names))
    feasible = meets(values, names, constraints)
    if not feasible.any():
        raise OptionError(f"no policy of the front meets {' and '.join(map(str, constraints))}; relax the constraints")
    candidates = np.flatnonzero(feasible)
    if prefer is not None:
        if prefer not in names:
            raise OptionError(f"--prefer {prefer}: no objective of that name; objectives: {', '.join(names)}")
        column = values[candidates, names.index(prefer)] * run.directions[names.index(prefer)].sign
        candidates = candidates[column == column.min()]
    chosen = candidates[metrics.knee(values[candidates], run.directions)] if len(candidates) > 1 else candidates[0]
    return run.front.policies[int(chosen)].name


def controller(run: RunDirectory, policy: str) -> URC:
    """The URC of one front policy of a run directory."""
    chosen = run.policy(policy)
    table: dict[tuple[int, ...], dict[str, int]] = {}
    for decision, value in zip(run.decisions, chosen.values):
        table.setdefault(decision.valuation, {})[decision.service.constant] = value
    return URC(
        observation=run.observation,
        services=run.services,
        table=table,
        left_out=run.left_out,
        policy=policy,
        values={o.name: v for o, v in zip(run.objectives, run.values_of(policy))},
        source=str(run.path),
    )
