"""An MDP whose schedulers include every policy's DTMC: the quotient's sound relaxation.

A policy's DTMC is not one scheduler of the quotient MDP: where several consistent choices
overlap, Storm's DTMC mixes them uniformly, and where none is consistent the state deadlocks
(a self-loop the MDP may not have). The relaxation has, in every state, one action per
assignment of the decisions the state's choices consult: the uniform mix of the choices
consistent with it, or, if there is none, a move to a fresh absorbing state that earns
nothing (the deadlock, which Storm's DTMC makes a self-loop earning nothing). A policy picks
the same assignment in every state of an observation valuation; the relaxation's schedulers
may pick any, so the best value over them bounds every policy's from outside.

The MDP is handed to Storm in its explicit DRN format.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
from attrs import field, frozen
from numba import njit

from parley_core.model import Family
from parley_core.quotient.coloring import Quotient


@frozen(kw_only=True)
class Relaxation:
    """The relaxed MDP as arrays: ``state_actions`` (CSR over actions, one extra state at the
    end: the deadlock sink), ``action_entries`` (CSR over merged branches), per action its
    rewards [r, actions] and whether it is a deadlock (no consistent choice)."""

    states: int
    initial: int
    state_actions: np.ndarray = field(eq=False, repr=False)
    action_entries: np.ndarray = field(eq=False, repr=False)
    targets: np.ndarray = field(eq=False, repr=False)
    probabilities: np.ndarray = field(eq=False, repr=False)
    rewards: np.ndarray = field(eq=False, repr=False)
    stuck: np.ndarray = field(eq=False, repr=False)
    state_decisions: np.ndarray = field(eq=False, repr=False)
    """CSR over states into ``decisions``: the decisions a state's choices consult; a state's
    actions are their assignments in mixed radix, the first decision's digit fastest."""
    decisions: np.ndarray = field(eq=False, repr=False)
    domain_sizes: np.ndarray = field(eq=False, repr=False)

    @property
    def sink(self) -> int:
        return self.states - 1

    @property
    def actions(self) -> int:
        return len(self.stuck)


@njit(cache=True)
def _state_decisions(choice_dec, first, last, buffer):
    """The distinct decisions the choices first..last-1 consult, into ``buffer``; their count."""
    n = 0
    for c in range(first, last):
        for j in range(choice_dec.shape[1]):
            d = choice_dec[c, j]
            if d < 0:
                break
            seen = False
            for i in range(n):
                if buffer[i] == d:
                    seen = True
                    break
            if not seen:
                buffer[n] = d
                n += 1
    return n


@njit(cache=True)
def _widest(state_choices, choice_dec):
    """An upper bound on the distinct decisions one state's choices consult."""
    most = 0
    for s in range(state_choices.shape[0] - 1):
        most = max(most, state_choices[s + 1] - state_choices[s])
    return max(1, most * choice_dec.shape[1])


@njit(cache=True)
def decision_lists(state_choices, choice_dec):
    """Per state the decisions its choices consult (CSR: pointers, flat list)."""
    states = state_choices.shape[0] - 1
    buffer = np.empty(_widest(state_choices, choice_dec), dtype=np.int64)
    pointers = np.zeros(states + 2, dtype=np.int64)
    flat = np.empty(max(1, state_choices[-1] * max(1, choice_dec.shape[1])), dtype=np.int64)
    total = 0
    for s in range(states):
        n = _state_decisions(choice_dec, state_choices[s], state_choices[s + 1], buffer)
        for i in range(n):
            flat[total + i] = buffer[i]
        total += n
        pointers[s + 1] = total
    pointers[states + 1] = total  # the sink consults nothing
    return pointers, flat[:total].copy()


@njit(cache=True)
def _consistent(choice_dec, choice_val, c, decisions, n, digits, dom_ptr, dom_vals):
    for j in range(choice_dec.shape[1]):
        d = choice_dec[c, j]
        if d < 0:
            return True
        for i in range(n):
            if decisions[i] == d:
                if dom_vals[dom_ptr[d] + digits[i]] != choice_val[c, j]:
                    return False
                break
    return True


@njit(cache=True)
def _relax(state_choices, choice_branches, targets, probabilities, choice_dec, choice_val, state_rewards,
           choice_rewards, dom_ptr, dom_vals, count_only, state_actions, entry_ptr, out_targets, out_probs,
           out_rewards, out_stuck):  # fmt: skip
    """Count (``count_only``) or write the relaxation's actions and (unmerged) entries."""
    states = state_choices.shape[0] - 1
    sink = states
    n_rewards = state_rewards.shape[0]
    decisions = np.empty(_widest(state_choices, choice_dec), dtype=np.int64)
    digits = np.zeros(decisions.shape[0], dtype=np.int64)
    actions = 0
    entries = 0
    for s in range(states):
        first, last = state_choices[s], state_choices[s + 1]
        n = _state_decisions(choice_dec, first, last, decisions)
        combinations = 1
        for i in range(n):
            combinations *= dom_ptr[decisions[i] + 1] - dom_ptr[decisions[i]]
        if not count_only:
            state_actions[s] = actions
        for i in range(n):
            digits[i] = 0
        for _ in range(combinations):
            k = 0
            for c in range(first, last):
                if _consistent(choice_dec, choice_val, c, decisions, n, digits, dom_ptr, dom_vals):
                    k += 1
            if not count_only:
                entry_ptr[actions] = entries
                out_stuck[actions] = k == 0
                for r in range(n_rewards):
                    out_rewards[r, actions] = 0.0
            if k == 0:
                if not count_only:
                    out_targets[entries] = sink
                    out_probs[entries] = 1.0
                entries += 1
            else:
                w = 1.0 / k
                for c in range(first, last):
                    if not _consistent(choice_dec, choice_val, c, decisions, n, digits, dom_ptr, dom_vals):
                        continue
                    if not count_only:
                        for r in range(n_rewards):
                            out_rewards[r, actions] += w * choice_rewards[r, c]
                    for b in range(choice_branches[c], choice_branches[c + 1]):
                        if not count_only:
                            out_targets[entries] = targets[b]
                            out_probs[entries] = w * probabilities[b]
                        entries += 1
                if not count_only:
                    for r in range(n_rewards):
                        out_rewards[r, actions] += state_rewards[r, s]
            actions += 1
            # next assignment (mixed radix over the decisions' domains)
            for i in range(n):
                digits[i] += 1
                if digits[i] < dom_ptr[decisions[i] + 1] - dom_ptr[decisions[i]]:
                    break
                digits[i] = 0
    if not count_only:
        state_actions[states] = actions
        entry_ptr[actions] = entries
    return actions, entries


def relax(quotient: Quotient, family: Family) -> Relaxation:
    """The relaxation of a family's quotient (see the module docstring)."""
    domains = [np.array(d.service.values, dtype=np.int64) for d in family.decisions]
    dom_ptr = np.zeros(len(domains) + 1, dtype=np.int64)
    dom_ptr[1:] = np.cumsum([len(d) for d in domains])
    dom_vals = np.concatenate(domains) if domains else np.zeros(0, dtype=np.int64)
    q = quotient
    n_rewards = q.state_rewards.shape[0]
    empty_i, empty_f = np.zeros(1, dtype=np.int64), np.zeros(1)
    args = (q.state_choices, q.choice_branches, q.targets, q.probabilities, q.choice_dec, q.choice_val,
            q.state_rewards, q.choice_rewards, dom_ptr, dom_vals)  # fmt: skip
    actions, entries = _relax(*args, True, empty_i, empty_i, empty_i, empty_f, np.zeros((n_rewards, 1)),
                              np.zeros(1, dtype=np.bool_))  # fmt: skip
    state_actions = np.zeros(q.states + 2, dtype=np.int64)
    entry_ptr = np.zeros(actions + 2, dtype=np.int64)
    raw_targets = np.zeros(entries, dtype=np.int64)
    raw_probs = np.zeros(entries)
    rewards = np.zeros((n_rewards, actions + 1))
    stuck = np.zeros(actions + 1, dtype=np.bool_)
    _relax(*args, False, state_actions, entry_ptr, raw_targets, raw_probs, rewards, stuck)
    # the sink: one action, a self-loop that earns nothing
    state_actions[q.states + 1] = actions + 1
    entry_ptr[actions + 1] = entries + 1
    raw_targets = np.append(raw_targets, q.states)
    raw_probs = np.append(raw_probs, 1.0)
    # merge the branches of an action that go to the same state
    action_of = np.repeat(np.arange(actions + 1), np.diff(entry_ptr))
    order = np.lexsort((raw_targets, action_of))
    action_of, raw_targets, raw_probs = action_of[order], raw_targets[order], raw_probs[order]
    starts = np.flatnonzero(np.r_[True, (np.diff(action_of) != 0) | (np.diff(raw_targets) != 0)])
    merged_probs = np.add.reduceat(raw_probs, starts)
    merged_targets = raw_targets[starts]
    merged_actions = action_of[starts]
    action_entries = np.zeros(actions + 2, dtype=np.int64)
    np.add.at(action_entries, merged_actions + 1, 1)
    state_decisions, decisions = decision_lists(q.state_choices, q.choice_dec)
    return Relaxation(
        state_decisions=state_decisions,
        decisions=decisions,
        domain_sizes=np.diff(dom_ptr),
        states=q.states + 1,
        initial=q.initial,
        state_actions=state_actions,
        action_entries=np.cumsum(action_entries),
        targets=merged_targets,
        probabilities=merged_probs,
        rewards=rewards,
        stuck=stuck,
    )


def observations(relaxation: Relaxation) -> np.ndarray:
    """Each state's observation when the relaxation is read as a POMDP: one per set of
    decisions a state consults (the sink and the states that consult none share one). A
    state's actions are the assignments of its decisions, so a policy, which assigns each
    decision one value, is a memoryless scheduler on these observations, and the POMDP's best
    value over all observation-based schedulers bounds every policy's, often more tightly
    than the MDP's over all schedulers."""
    r = relaxation
    seen: dict[tuple[int, ...], int] = {(): 0}
    out = np.zeros(r.states, dtype=np.int64)
    for s in range(r.states - 1):
        key = tuple(int(d) for d in r.decisions[r.state_decisions[s] : r.state_decisions[s + 1]])
        out[s] = seen.setdefault(key, len(seen))
    return out


def write_drn(relaxation: Relaxation, labels: dict[str, np.ndarray], path: str, pomdp: bool = False) -> None:
    """The relaxation in Storm's explicit DRN format: ``labels`` (name -> state mask over the
    quotient's states; the sink has none), reward structures r0, r1, ... (one per row); with
    ``pomdp``, as a POMDP with :func:`observations` (actions named by their assignment's
    number, which means the same assignment at every state of an observation)."""
    r = relaxation
    seen = observations(r) if pomdp else None
    n_rewards = r.rewards.shape[0]
    names = list(labels)
    masks = np.zeros((len(names), r.states), dtype=bool)
    for i, name in enumerate(names):
        masks[i, : len(labels[name])] = labels[name]
    lines = [
        f"@type: {'POMDP' if pomdp else 'MDP'}",
        "@parameters",
        "",
        "@reward_models",
        " ".join(f"r{i}" for i in range(n_rewards)),
    ]
    lines += ["@nr_states", str(r.states), "@nr_choices", str(r.actions), "@model"]
    probability_text = [repr(float(p)) for p in r.probabilities]
    for s in range(r.states):
        state_labels = [names[i] for i in np.flatnonzero(masks[:, s])]
        if s == r.initial:
            state_labels.insert(0, "init")
        reward_text = "[" + ", ".join("0" for _ in range(n_rewards)) + "]"
        observed = f" {{{seen[s]}}}" if seen is not None else ""
        lines.append(f"state {s}{observed} {reward_text} {' '.join(state_labels)}".rstrip())
        for local, a in enumerate(range(r.state_actions[s], r.state_actions[s + 1])):
            lines.append(f"\taction {local} [{', '.join(repr(float(r.rewards[i, a])) for i in range(n_rewards))}]")
            for e in range(r.action_entries[a], r.action_entries[a + 1]):
                lines.append(f"\t\t{int(r.targets[e])} : {probability_text[e]}")
    with open(path, "w") as handle:
        handle.write("\n".join(lines) + "\n")


def storm_model(relaxation: Relaxation, labels: dict[str, np.ndarray], pomdp: bool = False):
    """The relaxation as a Storm sparse MDP, or POMDP with ``pomdp`` (through a DRN file;
    the POMDP with choice labels, which Storm's belief exploration needs)."""
    import stormpy
    import stormpy.developer as storm_dev

    fd, path = tempfile.mkstemp(suffix=".drn", prefix="parley-relaxation-")
    os.close(fd)
    try:
        write_drn(relaxation, labels, path, pomdp=pomdp)
        if not pomdp:
            return stormpy.build_model_from_drn(path)
        options = storm_dev.DirectEncodingParserOptions()
        options.build_choice_labeling = True
        return stormpy.build_model_from_drn(path, options=options)
    finally:
        os.unlink(path)
