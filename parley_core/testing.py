"""Helpers for tests of the core and of plugins (``from parley_core.testing import storm_values``).

They use plain stormpy calls and nothing of parley's evaluators, so a test can compare
parley's values with Storm's on the same PRISM text.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence

import stormpy

from parley_core.prism.program import quiet_storm


def storm_values(
    prism_text: str, formulas: Sequence[str], constants: Mapping[str, int] | None = None, exact: bool = False
) -> list[float]:
    """Each formula's value at the initial state of the DTMC ``prism_text`` with the given
    undefined constants defined. ``exact`` builds and checks with rational numbers (for
    nested thresholds such as ``P<1`` that rounding must not decide)."""
    quiet_storm()
    fd, path = tempfile.mkstemp(suffix=".prism")
    with os.fdopen(fd, "w") as handle:
        handle.write(prism_text)
    try:
        program = stormpy.parse_prism_program(path)
    finally:
        os.unlink(path)
    if constants:
        manager = program.expression_manager
        by_name = {c.name: c.expression_variable for c in program.constants}
        program = program.define_undefined_constants({by_name[k]: manager.integer(v) for k, v in constants.items()})
    properties = stormpy.parse_properties(";".join(formulas), program)
    model = stormpy.build_model[stormpy.Rational](program, properties) if exact else stormpy.build_model(program, properties)
    state = model.initial_states[0]
    return [float(stormpy.model_checking(model, p).get_value(state)) for p in properties]
