"""The fast evaluator: one quotient MDP per family, every policy solved on it.

The family/quotient idea of PAYNT: all policies differ only in which commands the decision
constants enable, so one MDP holds them all.

- The quotient program is the system's original DTMC with every command that consults a
  service constant copied once per value of that constant (the constant replaced by the
  value), declared as an ``mdp``; a state reward ``__parley_obs`` numbers each state's
  observation valuation. Storm builds it once, with choice origins, and exports it in its
  binary UMB format, which numpy reads without a Python loop per entry.
- Each choice carries the (decision, value) pairs that enable it: the decision is the one of
  its state's observation valuation, the value comes from the copied command. A policy
  keeps the consistent choices; a state mixes them uniformly and a state left without one
  loops on itself and earns no reward, exactly as Storm builds the policy's DTMC (see
  :mod:`.kernels`).
- Objectives: ``P=? [F phi]``, ``P=? [phi U psi]``, ``P=? [phi U<=k psi]`` (and ``F<=k``),
  ``R=? [F phi]``, ``R=? [C<=k]`` and ``R=? [C]``, with propositional ``phi`` and ``psi``
  (their states are found by Storm on the quotient). Any other objective is evaluated by
  the Storm evaluator, and :attr:`QuotientEvaluator.fallback` names it.
"""

from __future__ import annotations

import itertools
import multiprocessing
import os
import tarfile
import tempfile
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import scipy.sparse as sp
import stormpy
import stormpy.io as storm_io
from attrs import field, frozen
from scipy.sparse import csgraph

from parley_core.augment import observation_domains, widen_bounds
from parley_core.errors import ModelError
from parley_core.evaluate import Progress, kernels
from parley_core.evaluate.storm import StormEvaluator
from parley_core.model import Family
from parley_core.prism import program as prism
from parley_core.prism.writer import RewardItem, Rewards, command_line

OBSERVATION_REWARD = "__parley_obs"
TOLERANCE = 1e-12
MAX_SWEEPS = 1_000_000


@frozen(kw_only=True)
class Objective:
    """One objective in a form the kernels solve.

    kind: "until" (P, unbounded), "bounded" (P, step-bounded), "reach_reward" (R, F),
    "cumulative" (R, C<=k), "total" (R, C). ``left``/``right`` are state masks (phi, psi).
    """

    kind: str
    left: np.ndarray | None = field(default=None, eq=False)
    right: np.ndarray | None = field(default=None, eq=False)
    steps: int = 0
    reward: int = -1


@frozen(kw_only=True)
class Quotient:
    """The quotient MDP as arrays (picklable): CSR over choices and branches, tags, rewards."""

    states: int
    initial: int
    state_choices: np.ndarray = field(eq=False)
    choice_branches: np.ndarray = field(eq=False)
    targets: np.ndarray = field(eq=False)
    probabilities: np.ndarray = field(eq=False)
    choice_dec: np.ndarray = field(eq=False)
    choice_val: np.ndarray = field(eq=False)
    state_rewards: np.ndarray = field(eq=False)
    choice_rewards: np.ndarray = field(eq=False)
    objectives: tuple[Objective | None, ...]
    """One per family objective; None where Storm must evaluate it."""

    @property
    def choices(self) -> int:
        return int(self.state_choices[-1])

    @property
    def branches(self) -> int:
        return len(self.targets)


def quotient_program(family: Family) -> tuple[str, dict[int, tuple[tuple[int, int], ...]]]:
    """The quotient's PRISM text, and for each of its commands (by global index) the
    (service position, value) pairs it stands for."""
    system = family.system
    program = prism.parse_program(system.prism, origin=f"the {system.name} model")
    manager = program.expression_manager
    positions = {s.constant: i for i, s in enumerate(system.services)}
    constants = {c.name: c.expression_variable for c in program.constants if c.name in positions}
    modules: dict[str, str] = {}
    tags_in_order: dict[str, list[tuple[tuple[int, int], ...]]] = {}
    for module in program.modules:
        replacements: dict[int, list[str]] = {}
        tags: list[tuple[tuple[int, int], ...]] = []
        for command in module.commands:
            used = [name for name, variable in constants.items() if prism.command_uses(command, {variable})]
            if not used:
                tags.append(())
                continue
            lines = []
            services = [system.services[positions[name]] for name in used]
            for values in itertools.product(*(s.values for s in services)):
                mapping = {constants[name]: manager.integer(v) for name, v in zip(used, values)}
                guard = command.guard_expression.substitute(mapping)
                updates = [str(update.substitute(mapping)) for update in command.updates]
                lines.append(command_line(command.action_name, str(guard), updates))
                tags.append(tuple((positions[name], v) for name, v in zip(used, values)))
            replacements[command.global_index] = lines
        widened = widen_bounds(module, constants, system, manager, f"the {system.name} model")
        if replacements or widened:
            modules[module.name] = prism.module_with_commands(module, replacements, widened)
        tags_in_order[module.name] = tags
    text = prism.splice(program, modules=modules, constants={name: "" for name in constants}, model_type="mdp")
    text += "\n" + _observation_rewards(family, program).render() + "\n"
    parsed = prism.parse_program(text, origin="the quotient model")
    by_index: dict[int, tuple[tuple[int, int], ...]] = {}
    for module in parsed.modules:
        tags = tags_in_order[module.name]
        if len(tags) != len(module.commands):
            raise RuntimeError(f"quotient module {module.name}: {len(module.commands)} commands, expected {len(tags)}")
        for command, tag in zip(module.commands, tags):
            by_index[command.global_index] = tag
    return text, by_index


def _observation_rewards(family: Family, program) -> Rewards:
    """A state reward that is each state's observation valuation's position in ``family.valuations`` order."""
    terms = []
    stride = 1
    domains = dict(zip(family.system.observation, observation_domains(program, family.system)))
    for name in reversed(family.system.observation):
        domain = domains[name]
        if prism.is_boolean(program, name):
            value = f"({name} ? 1 : 0)"
        else:
            value = f"({name} - {domain.start})"
        terms.append(f"{value} * {stride}")
        stride *= len(domain)
    return Rewards(name=OBSERVATION_REWARD, items=[RewardItem(guard="true", value=" + ".join(terms))])


@frozen(kw_only=True)
class _Built:
    """The quotient MDP as Storm built it, its UMB arrays, and per choice its state, its
    (decision index, value) tags (-1: no decision), its services and its observation
    valuation (an index into ``full``, every valuation of the observation domains)."""

    mdp: object = field(eq=False)
    program: object = field(eq=False)
    properties: list = field(eq=False)
    arrays: dict = field(eq=False)
    state_choices: np.ndarray = field(eq=False)
    state_of_choice: np.ndarray = field(eq=False)
    choice_dec: np.ndarray = field(eq=False)
    choice_val: np.ndarray = field(eq=False)
    service_of_choice: np.ndarray = field(eq=False)
    obs_of_choice: np.ndarray = field(eq=False)
    full: list = field(eq=False)


def _build_mdp(family: Family, properties_text: list[str]) -> _Built:
    """Build the quotient MDP with Storm (with choice origins) and tag its choices."""
    text, tags = quotient_program(family)
    program = prism.parse_program(text, origin="the quotient model")
    properties = prism.parse_properties(properties_text, program, origin="objective")
    for prop, objective in zip(properties, family.objectives):
        prism.check_property_references(prop, program, origin=f"objective {objective.name!r}")
    options = stormpy.BuilderOptions(properties) if properties else stormpy.BuilderOptions()
    options.set_build_choice_origins()
    options.set_build_all_reward_models()
    try:
        mdp = stormpy.build_model(program, options=options)
    except RuntimeError as exc:
        raise ModelError(f"Storm cannot build the quotient model: {prism.storm_message(exc)}") from None
    if len(mdp.initial_states) != 1:
        raise ModelError(f"the model has {len(mdp.initial_states)} initial states; parley needs exactly one")
    arrays = _read_umb(mdp)
    n = mdp.nr_states
    state_choices = arrays["state-to-choices.bin"].astype(np.int64)
    state_of_choice = np.repeat(np.arange(n), np.diff(state_choices))

    # (service, value) tags per distinct choice origin, then per choice
    identifiers = arrays["actions/choices/values.bin"].astype(np.int64)
    unique, first = np.unique(identifiers, return_index=True)
    origins = mdp.choice_origins
    width = len(family.system.services)  # a choice carries at most one value per service
    id_service = np.full((int(unique.max()) + 1, width), -1, dtype=np.int64)
    id_value = np.zeros_like(id_service)
    for identifier, choice in zip(unique, first):
        pairs = sorted({tag for index in origins.get_command_set(int(choice)) for tag in tags.get(index, ())})
        services = [s for s, _ in pairs]
        if len(set(services)) != len(services):
            raise RuntimeError("a choice combines two values of one service")
        for j, (service, value) in enumerate(pairs):
            id_service[identifier, j] = service
            id_value[identifier, j] = value

    # decision of each (full observation valuation, service); -1 where the family left it out
    observation = arrays[f"annotations/rewards/{OBSERVATION_REWARD}/states/values.bin"].astype(np.int64)
    full = _full_valuations(family, program)
    full_index = {v: i for i, v in enumerate(full)}
    decision_of = np.full((len(full), width), -1, dtype=np.int64)
    services = {s.constant: i for i, s in enumerate(family.system.services)}
    for index, decision in enumerate(family.decisions):
        decision_of[full_index[decision.valuation], services[decision.service.constant]] = index
    service_of_choice = id_service[identifiers]
    choice_val = id_value[identifiers]
    obs_of_choice = observation[state_of_choice]
    choice_dec = np.where(service_of_choice >= 0, decision_of[obs_of_choice[:, None], np.maximum(service_of_choice, 0)], -1)
    return _Built(
        mdp=mdp, program=program, properties=properties, arrays=arrays, state_choices=state_choices,
        state_of_choice=state_of_choice, choice_dec=choice_dec, choice_val=choice_val,
        service_of_choice=service_of_choice, obs_of_choice=obs_of_choice, full=full,
    )


def _full_valuations(family: Family, program) -> list[tuple[int, ...]]:
    return list(itertools.product(*observation_domains(program, family.system)))


def consulted_valuations(family: Family) -> set[tuple[int, ...]]:
    """Observation valuations at which some reachable state of some policy consults a service."""
    built = _build_mdp(family, [])
    tagged = (built.service_of_choice >= 0).any(axis=1)
    return {built.full[i] for i in np.unique(built.obs_of_choice[tagged])}


def build_quotient(family: Family) -> Quotient:
    """Build the quotient MDP with Storm and read it into arrays."""
    formulas = [o.formula for o in family.objectives]
    built = _build_mdp(family, formulas)
    mdp, program, properties, arrays = built.mdp, built.program, built.properties, built.arrays
    n = mdp.nr_states
    if ((built.service_of_choice >= 0) & (built.choice_dec < 0)).any():
        raise RuntimeError("a reachable observation valuation has no decision")

    reward_names = sorted({_reward_name(p, program) for p in properties if p.get_raw_formula().is_reward_operator_formula})
    state_rewards = np.zeros((max(1, len(reward_names)), n))
    choice_rewards = np.zeros((max(1, len(reward_names)), len(built.state_of_choice)))
    for r, name in enumerate(reward_names):
        base = f"annotations/rewards/{name}"
        if f"{base}/states/values.bin" in arrays:
            state_rewards[r] = arrays[f"{base}/states/values.bin"]
        if f"{base}/choices/values.bin" in arrays:
            choice_rewards[r] = arrays[f"{base}/choices/values.bin"]
        if f"{base}/branches/values.bin" in arrays:
            branch_rewards = arrays[f"{base}/branches/values.bin"]
            weighted = branch_rewards * arrays["branch-to-probability.bin"]
            choice_branches = arrays["choice-to-branches.bin"].astype(np.int64)
            choice_rewards[r] += np.add.reduceat(weighted, choice_branches[:-1]) if len(weighted) else 0.0

    objectives = tuple(_objective(mdp, prop, program, reward_names) for prop in properties)
    return Quotient(
        states=n,
        initial=int(mdp.initial_states[0]),
        state_choices=built.state_choices,
        choice_branches=arrays["choice-to-branches.bin"].astype(np.int64),
        targets=arrays["branch-to-target.bin"].astype(np.int64),
        probabilities=arrays["branch-to-probability.bin"].astype(np.float64),
        choice_dec=built.choice_dec.astype(np.int64),
        choice_val=built.choice_val.astype(np.int64),
        state_rewards=state_rewards,
        choice_rewards=choice_rewards,
        objectives=objectives,
    )


def _read_umb(model) -> dict[str, np.ndarray]:
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
            for member in archive.getmembers():
                if not member.isfile() or not member.name.endswith(".bin"):
                    continue
                data = archive.extractfile(member).read()
                name = member.name
                if name in ("state-to-choices.bin", "choice-to-branches.bin", "branch-to-target.bin"):
                    arrays[name] = np.frombuffer(data, dtype=np.uint64)
                elif name == "actions/choices/values.bin":
                    arrays[name] = np.frombuffer(data, dtype=np.uint32)
                elif name == "branch-to-probability.bin" or (
                    name.startswith("annotations/rewards/") and name.endswith("/values.bin")
                ):
                    arrays[name] = np.frombuffer(data, dtype=np.float64)
        return arrays
    finally:
        os.unlink(path)


def _reward_name(prop, program) -> str:
    formula = prop.get_raw_formula()
    if formula.has_reward_model_name():
        return formula.reward_name
    return program.reward_models[0].name


def _states(model, formula) -> np.ndarray | None:
    """The states satisfying a propositional state formula (by Storm), or None if Storm cannot say."""
    try:
        result = stormpy.model_checking(model, formula)
        indices = np.asarray(result.get_truth_values_vector(), dtype=np.int64)
    except (RuntimeError, AttributeError):
        return None
    mask = np.zeros(model.nr_states, dtype=bool)
    mask[indices] = True
    return mask


def _objective(model, prop, program, reward_names: list[str]) -> Objective | None:
    """The kernel form of a property, or None if the quotient evaluator does not support it."""
    formula = prop.get_raw_formula()
    if formula.has_bound or formula.has_optimality_type:
        return None
    sub = formula.subformula
    kind = type(sub).__name__
    if formula.is_probability_operator_formula:
        if kind == "EventuallyFormula":
            right = _states(model, sub.subformula)
            return None if right is None else Objective(kind="until", left=np.ones(model.nr_states, bool), right=right)
        if kind == "UntilFormula":
            left, right = _states(model, sub.left_subformula), _states(model, sub.right_subformula)
            return None if left is None or right is None else Objective(kind="until", left=left, right=right)
        if kind == "BoundedUntilFormula":
            if sub.has_lower_bound or sub.is_multi_dimensional:
                return None
            steps = prism.fixed_int(sub.upper_bound_expression)
            left, right = _states(model, sub.left_subformula), _states(model, sub.right_subformula)
            if steps is None or left is None or right is None:
                return None
            return Objective(kind="bounded", left=left, right=right, steps=steps)
        return None
    if formula.is_reward_operator_formula:
        reward = reward_names.index(_reward_name(prop, program))
        if kind == "EventuallyFormula":
            right = _states(model, sub.subformula)
            return None if right is None else Objective(kind="reach_reward", right=right, reward=reward)
        text = str(sub)
        if kind == "CumulativeRewardFormula" and text.startswith("C<=") and text[3:].isdigit():
            return Objective(kind="cumulative", steps=int(text[3:]), reward=reward)
        if text == "C":
            return Objective(kind="total", reward=reward)
    return None


class QuotientSolver:
    """Evaluates policies on a quotient in this process, with reusable work arrays.

    A policy's values depend on the policy alone (iterations start from zero, never from an
    earlier policy's solution), so results do not depend on which process solved what
    before: runs are reproducible whatever the number of workers. Warm starts were measured
    and saved nothing (about 20 Gauss-Seidel sweeps either way on robot_grid).
    """

    def __init__(self, quotient: Quotient) -> None:
        self.q = quotient
        n, b = quotient.states, quotient.branches
        self.local_of = np.full(n, -1, dtype=np.int64)
        self.order = np.empty(n, dtype=np.int64)
        self.indptr = np.empty(n + 1, dtype=np.int64)
        self.cols = np.empty(max(b, n) + n, dtype=np.int64)
        self.vals = np.empty(max(b, n) + n, dtype=np.float64)
        self.rewards = np.empty((quotient.state_rewards.shape[0], n))
        self.levels = np.empty(n, dtype=np.int64)
        self.chosen = np.empty(max(1, int(np.diff(quotient.state_choices).max(initial=0))), dtype=np.int64)
        self.last_states = 0
        # C<=k objectives with the same k share one forward pass: {k: (objectives, rewards)}
        self.cumulative: dict[int, tuple[list[int], np.ndarray]] = {}
        for i, objective in enumerate(quotient.objectives):
            if objective is not None and objective.kind == "cumulative":
                indices, rewards = self.cumulative.get(objective.steps, ([], np.empty(0, dtype=np.int64)))
                self.cumulative[objective.steps] = ([*indices, i], np.append(rewards, objective.reward))

    def solve(self, policy: np.ndarray) -> list[float | None]:
        q = self.q
        count, nnz = kernels.explore(
            np.asarray(policy, dtype=np.int64), q.initial, q.state_choices, q.choice_branches, q.targets,
            q.probabilities, q.choice_dec, q.choice_val, q.state_rewards, q.choice_rewards,
            self.local_of, self.order, self.indptr, self.cols, self.vals, self.rewards, self.levels, self.chosen,
        )
        self.last_states = count
        indptr, cols, vals = self.indptr[: count + 1], self.cols[:nnz], self.vals[:nnz]
        order = self.order[:count]
        values: list[float | None] = [None] * len(q.objectives)
        for steps, (indices, rewards) in self.cumulative.items():
            totals = kernels.cumulative(count, indptr, cols, vals, steps, self.rewards[rewards, :count], self.levels)
            for i, total in zip(indices, totals):
                values[i] = float(total)
        for i, objective in enumerate(q.objectives):
            if objective is not None and objective.kind != "cumulative":
                values[i] = self._objective(objective, count, indptr, cols, vals, order)
        return values

    def _objective(self, objective, count, indptr, cols, vals, order) -> float:
        if objective.kind == "until":
            left, right = objective.left[order], objective.right[order]
            # Iterating from 0, a state that cannot reach a right state keeps exactly 0 (the
            # value Storm's prob0 analysis gives it), so the full graph analysis is only
            # needed for the direct solve after a sweep limit, where those states make I - P
            # singular. One cheap pass finds most of them and leaves them out of the sweeps.
            free = left & ~right & ~kernels.cannot_reach(count, indptr, cols, right, left)
            x = np.where(right, 1.0, 0.0)
            if self._sweeps(count, indptr, cols, vals, free, x, np.zeros(count)):
                return float(x[0])
            can = kernels.backward_reach(count, indptr, cols, right, left)
            x = np.where(right, 1.0, 0.0)
            return self._gauss_seidel(count, indptr, cols, vals, can & ~right, x, np.zeros(count))
        if objective.kind == "bounded":
            left, right = objective.left[order], objective.right[order]
            x = np.where(right, 1.0, 0.0)
            x = kernels.bounded(count, indptr, cols, vals, objective.steps, x, np.zeros(count), left & ~right, self.levels)
            return float(x[0])
        reward = self.rewards[objective.reward, :count].copy()
        if objective.kind == "reach_reward":
            right = objective.right[order]
            can = kernels.backward_reach(count, indptr, cols, right, np.ones(count, bool))
            # infinite where a state that cannot reach the target is reachable (avoiding it)
            infinite = kernels.backward_reach(count, indptr, cols, ~can, ~right)
            if infinite[0]:
                return float("inf")
            free = ~right & ~infinite
            return self._gauss_seidel(count, indptr, cols, vals, free, np.zeros(count), np.where(free, reward, 0.0))
        if objective.kind == "total":
            matrix = sp.csr_matrix((vals, cols, indptr), shape=(count, count))
            _, labels = csgraph.connected_components(matrix, directed=True, connection="strong")
            # bottom components: no transition with positive probability leaves them
            sources = np.repeat(np.arange(count), np.diff(indptr))
            leaving = (labels[cols] != labels[sources]) & (vals > 0)
            leaves = np.ones(labels.max() + 1, dtype=bool)
            leaves[labels[sources[leaving]]] = False
            bottom = leaves[labels]
            positive = np.zeros(labels.max() + 1, dtype=bool)
            np.logical_or.at(positive, labels, bottom & (reward > 0))
            infinite = kernels.backward_reach(count, indptr, cols, positive[labels], np.ones(count, bool))
            if infinite[0]:
                return float("inf")
            free = ~bottom & ~infinite
            return self._gauss_seidel(count, indptr, cols, vals, free, np.zeros(count), np.where(free, reward, 0.0))
        raise ValueError(objective.kind)

    def _sweeps(self, count, indptr, cols, vals, free, x, constant) -> bool:
        """Gauss-Seidel for x = constant + P x on the ``free`` states, in reverse breadth-first
        order, with the states that only pass probability on (one transition, probability
        1) substituted away; x[0] holds the value when it returns True (converged)."""
        through = kernels.pass_through(count, indptr, cols, vals, ~free, count)
        lumped = kernels.lump(count, indptr, cols, vals, through, constant)
        rows = np.flatnonzero(free & (through < 0))[::-1].copy()
        return kernels.gauss_seidel(*lumped[:3], rows, x, lumped[3], TOLERANCE, MAX_SWEEPS) >= 0

    def _gauss_seidel(self, count, indptr, cols, vals, free, x, constant) -> float:
        if not self._sweeps(count, indptr, cols, vals, free, x, constant):
            # no convergence: a direct solve on the free states
            idx = np.flatnonzero(free)
            matrix = sp.csr_matrix((vals, cols, indptr), shape=(count, count))
            sub = matrix[idx][:, idx]
            rhs = constant[idx] + matrix[idx][:, np.flatnonzero(~free)] @ x[~free]
            x[idx] = sp.linalg.spsolve((sp.identity(len(idx)) - sub).tocsc(), rhs)
        return float(x[0])


_SOLVER: list[QuotientSolver] = []
"""Per worker process: its solver, set once by the pool's initializer."""


def _worker_start(quotient: Quotient) -> None:
    _SOLVER[:] = [QuotientSolver(quotient)]


def _worker_solve(rows: np.ndarray) -> np.ndarray:
    solver = _SOLVER[0]
    return np.array([[np.nan if v is None else v for v in solver.solve(row)] for row in rows])


class QuotientEvaluator:
    """Evaluate policies on the family's quotient MDP; unsupported objectives go to Storm.

    With ``workers`` > 1, batches of 64 policies or more are split over worker processes
    that receive the quotient once, when the pool starts.
    """

    name = "quotient"

    def __init__(self, family: Family, workers: int | None = None, quotient: Quotient | None = None) -> None:
        self.family = family
        self.quotient = quotient if quotient is not None else build_quotient(family)
        self.solver = QuotientSolver(self.quotient)
        self.workers = max(1, workers if workers is not None else (os.cpu_count() or 1))
        self.fallback = tuple(o.name for o, q in zip(family.objectives, self.quotient.objectives) if q is None)
        self._storm: StormEvaluator | None = None
        self._pool: ProcessPoolExecutor | None = None

    def evaluate(self, policies: np.ndarray, progress: Progress | None = None) -> np.ndarray:
        policies = np.asarray(policies, dtype=np.int64).reshape(-1, len(self.family.decisions))
        if self.workers > 1 and len(policies) >= 64:
            pool = self._executor()
            chunks = np.array_split(policies, self.workers * 4)
            futures = [pool.submit(_worker_solve, chunk) for chunk in chunks if len(chunk)]
            parts = []
            for future, chunk in zip(futures, [c for c in chunks if len(c)]):
                parts.append(future.result())
                if progress:
                    progress(len(chunk))
            values = np.vstack(parts)
        else:
            values = np.empty((len(policies), len(self.family.objectives)))
            for i, row in enumerate(policies):
                values[i] = [np.nan if v is None else v for v in self.solver.solve(row)]
                if progress:
                    progress(1)
        if self.fallback:
            missing = [i for i, q in enumerate(self.quotient.objectives) if q is None]
            if self._storm is None:
                self._storm = StormEvaluator(self.family, workers=self.workers)
            values[:, missing] = self._storm.evaluate(policies)[:, missing]
        return values

    def _executor(self) -> ProcessPoolExecutor:
        if self._pool is None:
            self._pool = ProcessPoolExecutor(
                max_workers=self.workers,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_worker_start,
                initargs=(self.quotient,),
            )
        return self._pool

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self._storm is not None:
            self._storm.close()
            self._storm = None

    def __enter__(self) -> QuotientEvaluator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
