"""One quotient per scenario, or one parametric quotient instantiated per scenario?

A robust run (``--scenarios``) builds the quotient MDP once per scenario. For scenarios over
a constant of the model (robot_grid's ``p``), Storm could instead build the quotient once
with the constant as a parameter and instantiate it per value. This script measures both on
the paper's map_10: the concrete build (with choice origins, as parley builds it), the
parametric build, and an instantiation, and says whether the instantiated model keeps the
choice origins parley reads the decisions from.

    .venv/bin/python benchmarks/parametric_quotient.py
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import stormpy
import stormpy.pars

from parley_core.family.prepare import prepare
from parley_core.plugin.manager import load_registry
from parley_core.prism import program as prism
from parley_core.prism import rewrite

MAP = Path(__file__).resolve().parents[2] / "shared" / "reference" / "parley2024" / "maps" / "map_10.csv"


def options() -> stormpy.BuilderOptions:
    built = stormpy.BuilderOptions()
    built.set_build_choice_origins()
    built.set_build_all_reward_models()
    return built


def main() -> None:
    case = load_registry().get("robot_grid")
    system = prepare(case, case.options_from({"map": str(MAP)})).system
    text, _ = rewrite.quotient_program(system)
    concrete = []
    for value in (0.005, 0.01, 0.02):
        start = time.perf_counter()
        program = prism.parse_program(re.sub(r"const double p = [^;]*;", f"const double p = {value};", text))
        model = stormpy.build_model(program, options=options())
        concrete.append(time.perf_counter() - start)
    start = time.perf_counter()
    program = prism.parse_program(re.sub(r"const double p = [^;]*;", "const double p;", text))
    parametric = stormpy.build_model[stormpy.RationalFunction](program, options=options())
    once = time.perf_counter() - start
    instantiator = stormpy.pars.ModelInstantiator(parametric)
    (parameter,) = parametric.collect_probability_parameters()
    start = time.perf_counter()
    instance = instantiator.instantiate({parameter: stormpy.pars.RationalFunctionCoefficient(0.02)})
    each = time.perf_counter() - start
    print(f"map_10 quotient: {model.nr_states} states, {model.nr_choices} choices")
    print(f"concrete build per scenario: {', '.join(f'{t:.2f}' for t in concrete)} s")
    print(f"parametric build once: {once:.2f} s; instantiation per scenario: {1000 * each:.1f} ms")
    print(f"the instantiated model keeps choice origins: {instance.has_choice_origins()}")
    scenarios = once / max(1e-9, min(concrete) - each)
    print(f"the parametric route pays from about {scenarios:.1f} scenarios (with choice origins carried over)")


if __name__ == "__main__":
    main()
