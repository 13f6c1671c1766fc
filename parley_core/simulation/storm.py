"""Simulating a policy with Storm's simulator, next to its model-checked values.

The policy's DTMC (the augmented model with its decision constants set) is built by Storm
and simulated with Storm's sparse simulator from its initial state. Objectives a simulation
can estimate:

- ``P=? [F phi]`` and ``P=? [F<=k phi]``: the share of episodes that reach a phi state (within
  k steps); an episode stops at a sink state or after ``max_steps`` (then it counts as not
  reaching phi, and the number of such cut episodes is reported);
- ``R{"r"}=? [C<=k]``: the mean reward of the first k steps.

Each estimate comes with a 99 % confidence interval (normal approximation; Wilson's for
proportions) and the model-checked value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import numpy as np
import stormpy
import stormpy.simulator as storm_simulator

from parley_core.errors import ModelError
from parley_core.evaluate.storm import StormChecker, StormTask
from parley_core.model import Family
from parley_core.plugin.simulator import Z99, Estimate, wilson
from parley_core.prism import program as prism
from parley_core.prism.properties import Shape, shape
from parley_core.urc.controller import URC

_Reach = tuple[Literal["reach"], str, np.ndarray, int | None, float]
"""A probability to estimate: objective, phi states, step bound (None: none), checked value."""
_Reward = tuple[Literal["reward"], str, int, int, float]
"""A mean reward to estimate: objective, reward model index, steps, checked value."""


def family_for_controller(model: Path, controller: URC, props: Path) -> Family:
    """A user's model augmented with a controller's services and observation (as `parley
    synthesize` augmented it), for simulating the controller on it."""
    from parley_core.family.prepare import make_family
    from parley_core.family.usermodel import system_from_file

    system = system_from_file(model, controller.services, [",".join(controller.observation)], props)
    return make_family(system, prune=True)


def simulation_plans(family: Family, instance, model, properties, checked) -> list[str | _Reach | _Reward]:
    """Per objective, what a simulation of ``model`` (a policy's DTMC built from
    ``instance``) estimates and Storm's value (``checked``), or a sentence saying why it cannot."""
    plans: list[str | _Reach | _Reward] = []
    for objective, prop, value in zip(family.objectives, properties, checked):
        found = shape(prop, instance)
        if found.kind in (Shape.UNTIL, Shape.BOUNDED_UNTIL):
            if found.left is not None:
                plans.append(f"{objective.name}: only F and F<=k probabilities can be simulated")
                continue
            mask = np.zeros(model.nr_states, dtype=bool)
            mask[np.asarray(stormpy.model_checking(model, found.right).get_truth_values_vector(), dtype=np.int64)] = (
                True
            )
            plans.append(("reach", objective.name, mask, found.steps, value))
        elif found.kind is Shape.CUMULATIVE:
            assert found.steps is not None  # shape() gives C<=k its bound k
            rewards = list(model.reward_models)
            name = found.reward if found.reward is not None else rewards[0]
            plans.append(("reward", objective.name, rewards.index(name), found.steps, value))
        else:
            plans.append(f"{objective.name}: {objective.formula} cannot be simulated (F, F<=k and C<=k can)")
    return plans


def simulate(
    family: Family, values: Sequence[int], episodes: int, seed: int, max_steps: int = 10_000
) -> list[Estimate | str]:
    """Estimates per objective (or a sentence saying why one cannot be simulated)."""
    program = prism.parse_program(family.prism, origin="the augmented model")
    instance = prism.define_constants(program, dict(zip(family.names, values)))
    properties = prism.parse_properties([o.formula for o in family.objectives], instance, origin="objective")
    options = stormpy.BuilderOptions(properties)
    try:
        model = stormpy.build_model(instance, options=options)
    except RuntimeError as exc:
        raise ModelError(f"Storm cannot build the policy's model: {prism.storm_message(exc)}") from None
    checked = StormChecker(StormTask.of(family)).check(values)

    plans = simulation_plans(family, instance, model, properties, checked)

    engine = storm_simulator.developer.DiscreteTimeSparseModelSimulator(model)
    engine.set_seed(seed)
    sinks: dict[int, bool] = {}
    plan: str | _Reach | _Reward
    active = [p for p in plans if not isinstance(p, str)]
    horizon = max([max_steps if p[3] is None else p[3] for p in active] or [0])
    hits = np.zeros(len(active), dtype=np.int64)
    sums = np.zeros(len(active))
    squares = np.zeros(len(active))
    cut = np.zeros(len(active), dtype=np.int64)
    for _ in range(episodes):
        engine.reset_to_initial()
        reached = [False] * len(active)
        total = [0.0] * len(active)
        state = engine.get_current_state()
        step = 0
        while True:
            for i, plan in enumerate(active):
                if plan[0] == "reach" and not reached[i] and plan[2][state] and (plan[3] is None or step <= plan[3]):
                    reached[i] = True
            if step == horizon:
                for i, plan in enumerate(active):
                    if plan[0] == "reach" and plan[3] is None and not reached[i]:
                        cut[i] += 1
                break
            sink = sinks.get(state)
            if sink is None:
                sink = sinks[state] = model.is_sink_state(state)
            engine.step(0)
            rewards = engine.get_last_rewards()
            for i, plan in enumerate(active):
                if plan[0] == "reward" and step < plan[3]:
                    # a sink earns the same reward at every remaining step
                    total[i] += rewards[plan[2]] * (plan[3] - step if sink else 1)
            if sink:  # nothing changes any more
                break
            state = engine.get_current_state()
            step += 1
        for i, plan in enumerate(active):
            if plan[0] == "reach":
                hits[i] += reached[i]
            else:
                sums[i] += total[i]
                squares[i] += total[i] * total[i]

    results: list[Estimate | str] = []
    for plan in plans:
        if isinstance(plan, str):
            results.append(plan)
            continue
        i = active.index(plan)
        if plan[0] == "reach":
            low, high = wilson(int(hits[i]), episodes)
            results.append(
                Estimate(
                    objective=plan[1],
                    kind="probability",
                    mean=hits[i] / episodes,
                    low=low,
                    high=high,
                    checked=plan[4],
                    episodes=episodes,
                    cut=int(cut[i]),
                )
            )
        else:
            mean = sums[i] / episodes
            deviation = math.sqrt(max(squares[i] / episodes - mean * mean, 0.0) * episodes / max(episodes - 1, 1))
            half = Z99 * deviation / math.sqrt(episodes)
            results.append(
                Estimate(
                    objective=plan[1],
                    kind="mean reward",
                    mean=mean,
                    low=mean - half,
                    high=mean + half,
                    checked=plan[4],
                    episodes=episodes,
                )
            )
    return results
