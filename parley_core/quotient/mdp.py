"""The quotient MDP of a system: built once by Storm, read into numpy arrays.

The quotient program (:func:`parley_core.prism.rewrite.quotient_program`) is the system's
DTMC with every command that consults a service constant copied once per value, declared
an ``mdp``. Storm builds it with choice origins and exports it in its binary UMB format,
which numpy reads without a Python loop per entry. Each choice gets the (service, value)
pairs of the commands it came from and its state's observation valuation (from the state
reward :data:`~parley_core.prism.rewrite.OBSERVATION_REWARD`).
"""

from __future__ import annotations

import json
import os
import tarfile
import tempfile
from collections.abc import Sequence
from typing import Any

import numpy as np
import stormpy
import stormpy.io as storm_io
from attrs import field, frozen
from stormpy.exceptions import StormError

from parley_core.errors import ModelError
from parley_core.model import SystemModel
from parley_core.prism import program as prism
from parley_core.prism import rewrite


@frozen(kw_only=True)
class QuotientMDP:
    """The quotient MDP as Storm built it, its UMB arrays, and per choice its state, its
    (service position, value) pairs (-1: none; one column per service) and its observation
    valuation (an index into ``valuations``, every valuation of the observation domains)."""

    system: SystemModel = field(eq=False, repr=False)
    model: Any = field(eq=False, repr=False)
    program: Any = field(eq=False, repr=False)
    properties: list = field(eq=False, repr=False)
    """The objectives' properties parsed against the quotient program (empty when built without)."""
    arrays: dict = field(eq=False, repr=False)
    reward_names: frozenset[str]
    """The reward structures Storm built (by their names in the model)."""
    state_choices: np.ndarray = field(eq=False, repr=False)
    state_of_choice: np.ndarray = field(eq=False, repr=False)
    service_of_choice: np.ndarray = field(eq=False, repr=False)
    value_of_choice: np.ndarray = field(eq=False, repr=False)
    obs_of_choice: np.ndarray = field(eq=False, repr=False)
    valuations: tuple[tuple[int, ...], ...]

    @property
    def states(self) -> int:
        return int(self.model.nr_states)

    @property
    def initial(self) -> int:
        return int(self.model.initial_states[0])


def build_mdp(system: SystemModel, formulas: Sequence[str] = (), objective_names: Sequence[str] = ()) -> QuotientMDP:
    """Build the quotient MDP of ``system`` with Storm (with choice origins), keeping what
    ``formulas`` need (their labels; every reward structure is built)."""
    text, tags = rewrite.quotient_program(system)
    program = prism.parse_program(text, origin="the quotient model")
    properties = prism.parse_properties(formulas, program, origin="objective")
    names = list(objective_names) or [str(f) for f in formulas]
    for prop, name in zip(properties, names):
        prism.check_property_references(
            prop, program, origin=f"objective {name!r}", ignore=(rewrite.OBSERVATION_REWARD,)
        )
    options = stormpy.BuilderOptions(properties) if properties else stormpy.BuilderOptions()
    options.set_build_choice_origins()
    options.set_build_all_reward_models()
    try:
        model = stormpy.build_model(program, options=options)
    except (RuntimeError, StormError) as exc:
        raise ModelError(f"Storm cannot build the quotient model: {prism.storm_message(exc)}") from None
    if len(model.initial_states) != 1:
        raise ModelError(f"the model has {len(model.initial_states)} initial states; parley needs exactly one")
    arrays, reward_names = read_umb(model)
    n = model.nr_states
    state_choices = arrays["state-to-choices.bin"].astype(np.int64)
    state_of_choice = np.repeat(np.arange(n), np.diff(state_choices))

    # (service, value) tags per distinct choice origin, then per choice
    identifiers = arrays["actions/choices/values.bin"].astype(np.int64)
    unique, first = np.unique(identifiers, return_index=True)
    origins = model.choice_origins
    # A choice may come from synchronising commands of several modules that read the same
    # constant: each copy carries its value, so one choice can hold a service twice. With
    # the same value that is one pair; with two values no policy keeps the choice (both
    # pairs must match the policy's decision), which is what Storm builds too.
    pairs_of = {
        int(identifier): sorted({tag for index in origins.get_command_set(int(choice)) for tag in tags.get(index, ())})
        for identifier, choice in zip(unique, first)
    }
    width = max([len(system.services), *(len(p) for p in pairs_of.values())])
    id_service = np.full((int(unique.max()) + 1, width), -1, dtype=np.int64)
    id_value = np.zeros_like(id_service)
    for identifier, pairs in pairs_of.items():
        for j, (service, value) in enumerate(pairs):
            id_service[identifier, j] = service
            id_value[identifier, j] = value

    observation = arrays[f"annotations/rewards/{rewrite.OBSERVATION_REWARD}/states/values.bin"].astype(np.int64)
    return QuotientMDP(
        system=system,
        model=model,
        program=program,
        properties=properties,
        arrays=arrays,
        reward_names=reward_names,
        state_choices=state_choices,
        state_of_choice=state_of_choice,
        service_of_choice=id_service[identifiers],
        value_of_choice=id_value[identifiers],
        obs_of_choice=observation[state_of_choice],
        valuations=tuple(rewrite.observation_valuations(program, system)),
    )


def consulted_valuations(mdp: QuotientMDP) -> set[tuple[int, ...]]:
    """Observation valuations at which some reachable state of some policy consults a service."""
    tagged = (mdp.service_of_choice >= 0).any(axis=1)
    return {mdp.valuations[i] for i in np.unique(mdp.obs_of_choice[tagged])}


def read_umb(model) -> tuple[dict[str, np.ndarray], frozenset[str]]:
    """The arrays of Storm's binary UMB export of ``model`` that the quotient uses, by file
    name, and the names of the reward structures it holds. UMB escapes names in its file
    names (``lostH`` is stored as ``lost0x48``); its index gives each one's real name
    (``alias``), and the reward arrays are returned under the real names."""
    options = storm_io.UmbExportOptions()
    options.compression = storm_io.CompressionMode.NO_COMPRESSION
    options.allow_choice_origins_as_actions = True
    options.allow_choice_labeling_as_actions = False
    umb = storm_io.sparse_model_to_umb(model, options=options)
    fd, path = tempfile.mkstemp(suffix=".umb", prefix="parley-quotient-")
    os.close(fd)
    try:
        storm_io.umb_to_archive(umb, path, options)
        arrays = {}
        with tarfile.open(path) as archive:
            index = archive.extractfile("index.json")
            if index is None:
                raise RuntimeError("Storm's UMB export has no index.json")
            rewards = json.loads(index.read()).get("annotations", {}).get("rewards", {})
            alias = {key: str(entry.get("alias", key)) for key, entry in rewards.items()}
            built = set(model.reward_models)
            for key, name in alias.items():  # UMB calls an unnamed structure "default"
                if name not in built and "" in built:
                    alias[key] = ""
            if set(alias.values()) != built:
                raise RuntimeError(
                    f"Storm's UMB export names rewards {sorted(alias.values())}, the model has {sorted(built)}"
                )
            for member in archive.getmembers():
                if not member.isfile() or not member.name.endswith(".bin"):
                    continue
                handle = archive.extractfile(member)
                if handle is None:
                    continue
                data = handle.read()
                name = member.name
                if name in ("state-to-choices.bin", "choice-to-branches.bin", "branch-to-target.bin"):
                    arrays[name] = np.frombuffer(data, dtype=np.uint64)
                elif name == "actions/choices/values.bin":
                    arrays[name] = np.frombuffer(data, dtype=np.uint32)
                elif name == "branch-to-probability.bin":
                    arrays[name] = np.frombuffer(data, dtype=np.float64)
                elif name.startswith("annotations/rewards/") and name.endswith("/values.bin"):
                    _, _, key, rest = name.split("/", 3)
                    if key not in alias:
                        raise RuntimeError(f"Storm's UMB export holds reward {key!r}, which its index does not name")
                    arrays[f"annotations/rewards/{alias[key]}/{rest}"] = np.frombuffer(data, dtype=np.float64)
        return arrays, frozenset(alias.values())
    finally:
        os.unlink(path)
