"""A policy's DTMC as Storm builds it, read into arrays, and missions sampled from it.

:func:`build_chain` has Storm build a policy's DTMC from a family's model.prism with one
constant set (the drift simulation's and the calibration's models), its state valuations
included for the events an adaptive URC observes; :func:`run_mission` runs one mission of many
systems at once on it, sampling the successors from Storm's transition matrix.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import stormpy
from attrs import field, frozen

from parley_core.errors import ModelError, OptionError
from parley_core.evaluate.storm import check_values, reference_environment
from parley_core.model import Family
from parley_core.prism import program as prism
from parley_core.prism.rewrite import override_constants
from parley_core.quotient.mdp import read_umb
from parley_core.simulation.storm import simulation_plans
from parley_core.urc.controller import URC
from parley_core.urc.events import EventModel


@frozen(kw_only=True)
class Chain:
    """A policy's DTMC at one parameter value, as arrays to sample from."""

    keys: np.ndarray
    """Per branch, its state's index plus the cumulative probability within the state (sorted)."""
    targets: np.ndarray
    rewards: dict[int, np.ndarray] = field(eq=False)
    """Reward model index -> per state, the state reward plus the reward of its one choice."""
    masks: dict[str, np.ndarray] = field(eq=False)
    """Reach objective -> its phi states."""
    sinks: np.ndarray
    variables: dict[str, np.ndarray] = field(eq=False)
    initial: int
    plans: tuple = field(eq=False)
    checked: tuple[float, ...]
    """Storm's value of each objective."""

    def step(self, states: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return self.targets[np.searchsorted(self.keys, states + rng.random(len(states)), side="right")]


def build_chain(family: Family, values: Sequence[int], parameter: str, value: float, variables: Sequence[str]) -> Chain:
    """Storm builds the policy ``values`` of ``family`` with the parameter's constant set to ``value``."""
    text = override_constants(family.prism, {parameter: repr(value)}, services=list(family.names), option="--drift")
    program = prism.parse_program(text, origin="the run's model")
    instance = prism.define_constants(program, dict(zip(family.names, (int(v) for v in values))))
    properties = prism.parse_properties([o.formula for o in family.objectives], instance, origin="objective")
    options = stormpy.BuilderOptions(properties)
    options.set_build_state_valuations()
    options.set_build_all_reward_models()
    try:
        model = stormpy.build_model(instance, options=options)
    except RuntimeError as exc:
        raise ModelError(f"Storm cannot build the policy's model: {prism.storm_message(exc)}") from None
    environment = reference_environment()
    initial = int(model.initial_states[0])
    checked = tuple(check_values(model, prop, environment, [initial])[0] for prop in properties)
    plans = simulation_plans(family, instance, model, properties, checked)
    arrays, _ = read_umb(model)
    n = int(model.nr_states)
    # a DTMC's export has no state-to-choices (one choice per state)
    choices = arrays.get("state-to-choices.bin", np.arange(n + 1)).astype(np.int64)
    if len(choices) != n + 1 or int(choices[-1]) != n:
        raise ModelError("the policy's model is not a DTMC with one choice per state")
    begins = arrays["choice-to-branches.bin"].astype(np.int64)
    targets = arrays["branch-to-target.bin"].astype(np.int64)
    probabilities = arrays["branch-to-probability.bin"].astype(np.float64)
    state_of_branch = np.repeat(np.arange(n), np.diff(begins))
    cumulative = np.cumsum(probabilities)
    start = np.concatenate([[0.0], cumulative])[begins[:-1]]
    within = cumulative - start[state_of_branch]
    totals = within[begins[1:] - 1]
    keys = state_of_branch + within / totals[state_of_branch]
    keys[begins[1:] - 1] = np.arange(1, n + 1)  # the last branch of each state closes it exactly
    single = np.diff(begins) == 1
    sinks = single & (targets[begins[:-1]] == np.arange(n))
    names = list(model.reward_models)
    rewards = {}
    for plan in plans:
        if not isinstance(plan, str) and plan[0] == "reward":
            structure = model.reward_models[names[plan[2]]]
            each = np.zeros(n)
            if structure.has_state_rewards:
                each += np.asarray(structure.state_rewards, dtype=float)
            if structure.has_state_action_rewards:
                each += np.asarray(structure.state_action_rewards, dtype=float)
            rewards[plan[2]] = each
    masks = {plan[1]: plan[2] for plan in plans if not isinstance(plan, str) and plan[0] == "reach"}
    by_name = {v.name: v for v in prism.all_variables(instance)}
    missing = [v for v in variables if v not in by_name]
    if missing:
        raise ModelError(f"the event model reads {', '.join(missing)}, which the model lacks")
    valuations = model.state_valuations
    read = {}
    for name in variables:
        variable = by_name[name].expression_variable
        read[name] = np.array([valuations.get_int64_value(s, variable) for s in range(n)], dtype=np.int64)
    return Chain(
        keys=keys,
        targets=targets,
        rewards=rewards,
        masks=masks,
        sinks=sinks,
        variables=read,
        initial=initial,
        plans=tuple(plans),
        checked=checked,
    )


def policy_values(family: Family, urc: URC) -> tuple[int, ...]:
    if tuple(urc.observation) != tuple(family.observation):
        raise OptionError(
            f"a controller reads {', '.join(urc.observation)}, the run's model {', '.join(family.observation)}"
        )
    return tuple(urc.decide(d.valuation)[d.service.constant] for d in family.decisions)


Observer = Callable[[np.ndarray, np.ndarray, np.ndarray], None]
"""``observer(systems, outcomes, contexts)``: events of a mission's systems (0..n-1)."""


def run_mission(
    chain: Chain,
    plans: list,
    n: int,
    horizon: int,
    rng: np.random.Generator,
    observer: Observer | None,
    events: EventModel | None,
) -> tuple[dict[str, np.ndarray], int]:
    """One mission of ``n`` systems on ``chain``: each objective's outcome per system (1/0 or
    the reward), and how many were cut at ``horizon`` before reaching an unbounded reach
    objective's states or a sink (counted as not reaching them); the events of ``events``
    go to ``observer``."""
    state = np.full(n, chain.initial, dtype=np.int64)
    reached = {p[1]: np.zeros(n, dtype=bool) for p in plans if p[0] == "reach"}
    totals = {p[1]: np.zeros(n) for p in plans if p[0] == "reward"}
    alive = np.ones(n, dtype=bool)
    step = 0
    while True:
        for p in plans:
            if p[0] == "reach" and (p[3] is None or step <= p[3]):
                reached[p[1]] |= chain.masks[p[1]][state]
        sink = chain.sinks[state]
        for p in plans:
            if p[0] == "reward" and step < p[3]:
                earned = chain.rewards[p[2]][state]
                # a system in a sink earns the same reward at every remaining step
                totals[p[1]] += np.where(sink & alive, earned * (p[3] - step), np.where(alive, earned, 0.0))
        alive &= ~sink
        if step == horizon or not alive.any():
            break
        following = np.where(alive, chain.step(state, rng), state)
        if observer is not None and events is not None:
            moving = np.flatnonzero(alive)
            before = {k: v[state[moving]] for k, v in chain.variables.items()}
            after = {k: v[following[moving]] for k, v in chain.variables.items()}
            trial, outcome, context = events.events(before, after)
            trial = np.asarray(trial, dtype=bool)
            if trial.any():
                observer(moving[trial], np.asarray(outcome)[trial], np.asarray(context)[trial])
        state = following
        step += 1
    values: dict[str, Any] = {name: hit.astype(float) for name, hit in reached.items()}
    values.update(totals)
    unbounded = [reached[p[1]] for p in plans if p[0] == "reach" and p[3] is None]
    cut = alive & ~np.logical_and.reduce(unbounded) if unbounded else np.zeros(n, dtype=bool)
    return values, int(cut.sum())
