"""Controllers in a drifting environment: fixed, robust and adaptive URCs, mission after mission.

A system runs ``missions`` missions one after the other (a robot crossing its map again and
again), while a parameter of its model drifts: ``p=0.01:0.03@40`` jumps from 0.01 to 0.03 at
mission 40, ``p=0.01:0.03@20-60`` ramps linearly from mission 20 to 60 (in at most
:data:`RAMP_LEVELS` steps). Each mission is an episode of the policy's DTMC for the
parameter's value at that mission, built by Storm from the run's model.prism with the
parameter's constant set (so the drift needs the parameter to be a constant of the model)
and sampled here from Storm's transition matrix, ``episodes`` independent systems at once.
A fixed URC keeps its policy; an adaptive one (:mod:`parley_core.urc.adaptive`) observes the
events its case study's :class:`~parley_core.urc.adaptive.EventModel` reads off each transition
and may switch policy between missions. Per mission and controller, the result holds each
objective's mean over the systems with a 99 % interval, and Storm's value of every
(policy, parameter value) pair, which the missions at a constant value must agree with.
The missions are sampled by :mod:`parley_core.simulation.missions`; :mod:`parley_core.simulation.drift_report`
writes drift.json and drift.png.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np
from attrs import field, frozen

from parley_core.errors import OptionError
from parley_core.model import Family
from parley_core.plugin.simulator import Z99, wilson
from parley_core.progress import NullReporter, Reporter
from parley_core.simulation.missions import Chain, Observer, build_chain, policy_values, run_mission
from parley_core.urc.adaptive import AdaptiveController, Beliefs, Calibration
from parley_core.urc.controller import URC
from parley_core.urc.events import EventModel

RAMP_LEVELS = 9
"""A ramp takes at most this many distinct values (one DTMC per policy and value)."""


@frozen(kw_only=True)
class Drift:
    """A parameter's value per mission: ``low`` before mission ``begin``, ``high`` from
    ``end`` on, linear in between (a jump when ``begin == end``)."""

    parameter: str
    low: float
    high: float
    begin: int
    end: int

    @classmethod
    def parse(cls, text: str) -> Drift:
        match = re.fullmatch(r"\s*([A-Za-z_]\w*)=([^:@]+):([^:@]+)@(\d+)(?:-(\d+))?\s*", text)
        if match is None:
            raise OptionError(
                f"malformed --drift {text!r}; write NAME=FROM:TO@MISSION (a jump) or NAME=FROM:TO@BEGIN-END (a ramp), "
                "e.g. p=0.01:0.03@40"
            )
        name, low, high, begin, end = match.groups()
        try:
            values = float(low), float(high)
        except ValueError:
            raise OptionError(f"--drift {text!r}: FROM and TO must be numbers, e.g. p=0.01:0.03@40") from None
        first, last = int(begin), int(end) if end is not None else int(begin)
        if last < first:
            raise OptionError(f"--drift {text!r}: the ramp ends before it begins; write BEGIN-END with BEGIN <= END")
        if values[0] == values[1]:
            raise OptionError(f"--drift {text!r}: FROM and TO are equal; that is no drift")
        return cls(parameter=name, low=values[0], high=values[1], begin=first, end=last)

    def levels(self, missions: int) -> tuple[tuple[float, ...], np.ndarray]:
        """The distinct values and, per mission, the index of its value."""
        steps = min(RAMP_LEVELS, self.end - self.begin + 1) if self.end > self.begin else 2
        values = tuple(float(v) for v in np.linspace(self.low, self.high, max(2, steps)))
        m = np.arange(missions)
        exact = np.where(
            m < self.begin,
            self.low,
            np.where(
                m >= self.end,
                self.high,
                self.low + (self.high - self.low) * (m - self.begin) / max(1, self.end - self.begin),
            ),
        )
        index = np.abs(exact[:, None] - np.array(values)[None, :]).argmin(axis=1)
        return values, index

    def __str__(self) -> str:
        at = f"{self.begin}" if self.begin == self.end else f"{self.begin}-{self.end}"
        return f"{self.parameter}={self.low:g}:{self.high:g}@{at}"


@frozen(kw_only=True)
class Series:
    """One controller's missions: per objective and mission, the mean over the systems and
    its 99 % interval; per mission, how many systems run each parameter value's policy."""

    name: str
    means: dict[str, np.ndarray] = field(eq=False)
    lows: dict[str, np.ndarray] = field(eq=False)
    highs: dict[str, np.ndarray] = field(eq=False)
    squares: dict[str, np.ndarray] = field(eq=False)
    """Per objective and mission, the mean of the squared outcomes (for a phase's interval)."""
    in_force: np.ndarray = field(eq=False)
    """[missions, policies]: systems per policy of the controller."""
    policies: tuple[str, ...]
    """The controller's policies (one for a fixed URC; one per value for an adaptive one)."""
    checked: dict[tuple[str, float], tuple[float, ...]] = field(eq=False)
    """Storm's values of (policy, parameter value)."""
    cut: int = 0
    """Episodes cut at max_steps before reaching an unbounded reach objective or a sink."""


@frozen(kw_only=True)
class DriftResult:
    drift: Drift
    missions: int
    episodes: int
    seed: int
    objectives: tuple[str, ...]
    kinds: tuple[str, ...]
    """Per objective, ``probability`` or ``mean reward``."""
    levels: tuple[float, ...]
    level_of_mission: np.ndarray = field(eq=False)
    series: tuple[Series, ...]

    def phase(self, series: Series, objective: str, first: int, last: int) -> tuple[float, float, float]:
        """The mean of an objective over missions ``first..last-1`` and all systems, with its
        99 % interval (as if the missions were independent: an adaptive controller's are not
        quite, its estimator carries over)."""
        mean = float(series.means[objective][first:last].mean())
        n = self.episodes * (last - first)
        kind = self.kinds[self.objectives.index(objective)]
        if kind == "probability":
            low, high = wilson(round(mean * n), n)
            return mean, low, high
        variance = max(0.0, float(series.squares[objective][first:last].mean()) - mean * mean) * n / max(1, n - 1)
        half = Z99 * math.sqrt(variance / n)
        return mean, mean - half, mean + half


Controller = URC | AdaptiveController


def simulate_drift(
    family: Family,
    drift: Drift,
    controllers: Sequence[tuple[str, Controller]],
    events: EventModel | None,
    *,
    missions: int,
    episodes: int,
    seed: int,
    max_steps: int = 10_000,
    reporter: Reporter | None = None,
) -> DriftResult:
    """Every controller on ``episodes`` systems for ``missions`` missions each (module docstring)."""
    reporter = reporter or NullReporter()
    levels, level_of = drift.levels(missions)
    adaptive = [c for _, c in controllers if isinstance(c, AdaptiveController)]
    for one in adaptive:
        if one.parameter != drift.parameter:
            raise OptionError(
                f"an adaptive controller switches on {one.parameter}, the drift changes {drift.parameter}"
            )
        if events is None:
            raise OptionError(
                f"the adaptive controller needs an event model for {drift.parameter} from the case study's plugin, "
                "which has none; simulate fixed controllers only"
            )
    variables = tuple(events.variables) if events is not None and adaptive else ()
    chains: dict[tuple[tuple[int, ...], int], Chain] = {}
    policies: dict[str, list[tuple[int, ...]]] = {}
    for name, given in controllers:
        policies[name] = [policy_values(family, urc) for urc in _urcs(given)]
    needed = {(values, k) for rows in policies.values() for values in rows for k in range(len(levels))}
    reporter.stage("build the policies' models", len(needed))
    for values, k in sorted(needed):
        chains[values, k] = build_chain(family, values, drift.parameter, levels[k], variables)
        reporter.advance(1)
    first = next(iter(chains.values()))
    plans = [p for p in first.plans if not isinstance(p, str)]
    objectives = tuple(p[1] for p in plans)
    kinds = tuple("probability" if p[0] == "reach" else "mean reward" for p in plans)
    horizon = max(max_steps if p[3] is None else p[3] for p in plans)
    reporter.stage("missions", missions * len(controllers))
    series = []
    for c, (name, controller) in enumerate(controllers):
        rng = np.random.default_rng([seed, c])
        rows = policies[name]
        beliefs = (
            Beliefs(
                controller.values,
                controller.estimator,
                controller.likelihood(events.probability),
                episodes,
                controller.start,
            )
            if isinstance(controller, AdaptiveController) and events is not None
            else None
        )
        means = {o: np.empty(missions) for o in objectives}
        lows = {o: np.empty(missions) for o in objectives}
        highs = {o: np.empty(missions) for o in objectives}
        squares = {o: np.empty(missions) for o in objectives}
        in_force = np.zeros((missions, len(rows)), dtype=np.int64)
        cut = 0
        for m in range(missions):
            current = beliefs.current if beliefs is not None else np.zeros(episodes, dtype=np.int64)
            in_force[m] = np.bincount(current, minlength=len(rows))
            outcome = {o: np.zeros(episodes) for o in objectives}
            for j in np.unique(current):
                systems = np.flatnonzero(current == j)
                chain = chains[rows[j], int(level_of[m])]
                seen = None if beliefs is None else _observer(beliefs, systems)
                found, stopped = run_mission(chain, plans, len(systems), horizon, rng, seen, events)
                cut += stopped
                for o in objectives:
                    outcome[o][systems] = found[o]
            if beliefs is not None:
                beliefs.adapt()
            for o, kind in zip(objectives, kinds):
                column = outcome[o]
                means[o][m] = column.mean()
                squares[o][m] = np.mean(column * column)
                if kind == "probability":
                    lows[o][m], highs[o][m] = wilson(int(column.sum()), episodes)
                else:
                    half = Z99 * column.std(ddof=1) / math.sqrt(episodes) if episodes > 1 else 0.0
                    lows[o][m], highs[o][m] = column.mean() - half, column.mean() + half
            reporter.advance(1)
        checked = {}
        names = _names(name, controller)
        for policy, row in zip(names, rows):
            for k, level in enumerate(levels):
                checked[policy, level] = chains[row, k].checked
        series.append(
            Series(
                name=name,
                means=means,
                lows=lows,
                highs=highs,
                squares=squares,
                in_force=in_force,
                policies=names,
                checked=checked,
                cut=cut,
            )
        )
    return DriftResult(
        drift=drift,
        missions=missions,
        episodes=episodes,
        seed=seed,
        objectives=objectives,
        kinds=kinds,
        levels=levels,
        level_of_mission=level_of,
        series=tuple(series),
    )


def _urcs(controller: Controller) -> tuple[URC, ...]:
    return controller.controllers if isinstance(controller, AdaptiveController) else (controller,)


def _names(name: str, controller: Controller) -> tuple[str, ...]:
    """The controller's policies by name (an adaptive one's with their parameter values)."""
    if isinstance(controller, AdaptiveController):
        return tuple(
            f"{urc.policy or name} ({controller.parameter}={value:g})"
            for urc, value in zip(controller.controllers, controller.values)
        )
    return (controller.policy or name,)


def _observer(beliefs: Beliefs, systems: np.ndarray) -> Observer:
    def observe(which: np.ndarray, outcomes: np.ndarray, contexts: np.ndarray) -> None:
        beliefs.observe(systems[which], outcomes, contexts)

    return observe


def calibrate(
    families: Sequence[Family],
    parameter: str,
    values: Sequence[float],
    urcs: Sequence[URC],
    events: EventModel,
    *,
    missions: int = 1000,
    seed: int = 1,
    max_steps: int = 10_000,
    reporter: Reporter | None = None,
) -> Calibration:
    """The model's predictions of the events (:class:`~parley_core.urc.adaptive.Calibration`):
    every policy's DTMC at every value (Storm builds it from ``families[i]``, the run of
    ``values[i]``, with the constant set), ``missions`` missions each, outcomes counted per context."""
    reporter = reporter or NullReporter()
    reporter.stage("calibrate the estimator", len(values) * len(urcs))
    counts: dict[tuple[int, int], dict[int, list[int]]] = {}
    for i, (family, value) in enumerate(zip(families, values)):
        for j, urc in enumerate(urcs):
            chain = build_chain(family, policy_values(family, urc), parameter, value, events.variables)
            plans = [p for p in chain.plans if not isinstance(p, str)]
            horizon = max(max_steps if p[3] is None else p[3] for p in plans)
            seen: dict[int, list[int]] = {}

            def count(_which, outcomes, contexts, seen=seen) -> None:
                for outcome, context in zip(np.asarray(outcomes).tolist(), np.asarray(contexts).tolist()):
                    entry = seen.setdefault(int(context), [0, 0])
                    entry[0] += int(outcome)
                    entry[1] += 1

            rng = np.random.default_rng([seed, i, j])
            run_mission(chain, plans, missions, horizon, rng, count, events)
            counts[i, j] = seen
            reporter.advance(1)
    contexts = sorted({k for seen in counts.values() for k in seen}) or [0]
    rates = np.empty((len(values), len(urcs), len(contexts)))
    for (i, j), seen in counts.items():
        ones = sum(e[0] for e in seen.values())
        trials = sum(e[1] for e in seen.values())
        overall = (ones + 1) / (trials + 2)
        for c, context in enumerate(contexts):
            one, n = seen.get(context, (0, 0))
            rates[i, j, c] = (one + 1) / (n + 2) if n else overall
    return Calibration(contexts=contexts, rates=rates, missions=missions)
