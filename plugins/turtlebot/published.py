"""Read the paper's turtlebot model (``models/turtlebot/model.prism`` of its package).

Its motion table was sampled in Gazebo and is published only inside that PRISM file: one
command per true cell, true heading, estimated heading and move, e.g.::

    [north] (ready=1) & (x=0) & (y=0) & (direction=2) & (directionhat=0) ->
      0.022:(x'=x)&(y'=y)&(direction'=0) + ... + 0.2:(out'=1);

and its movement controller is the module ``Adaptation_MAPE_controller``, one move per
estimated cell. This module reads both into a :class:`World`. The published distributions
do not depend on the estimated heading (checked here: a file where they do is refused).

The published file sends every ``[south]`` move that goes down a row to the top row:
``(y'=max(N,y-1))`` where ``max(0,y-1)`` is meant (1,204 updates). With ``repair`` (the
default) it is read as meant; ``repair=False`` keeps the published semantics, to reproduce
the published file's values exactly.
"""

from __future__ import annotations

import re
from pathlib import Path

from parley_core import OptionError, read_text
from parley_plugins.turtlebot.world import CRASH, OUT, Outcome, World

_CONSTANT = re.compile(r"const\s+int\s+(\w+)\s*=\s*(\d+)\s*;")
_MOTION = re.compile(
    r"\[(north|east|south|west)\]\s*\(ready=1\)\s*&\s*\(x=(\d+)\)\s*&\s*\(y=(\d+)\)\s*&\s*"
    r"\(direction=(\d)\)\s*&\s*\(directionhat=(\d)\)\s*->(.*?);",
    re.S,
)
_PLAN = re.compile(
    r"\[(north|east|south|west)\]\s*\(xhat=(\d+)\)\s*&\s*\(yhat=(\d+)\)\s*&\s*\(crashed=0\)\s*&\s*\(out=0\)\s*->\s*true\s*;"
)
_UPDATE_SPLIT = re.compile(r"\+(?=\s*[0-9.eE-]+\s*:)")
_ASSIGNMENT = re.compile(r"\((\w+)'=([^()]*(?:\([^()]*\))?)\)")
_CLAMP = re.compile(r"(min|max)\((\w+),\s*([xy])\s*([+-])\s*1\)")


def load(path: Path, *, repair: bool = True) -> World:
    """The world of the published model file at ``path``; a file it cannot read is an OptionError."""
    text = read_text(path, "turtlebot model", "give the paper's models/turtlebot/model.prism (model=FILE)", OptionError)
    return parse(text, source=str(path), repair=repair)


def parse(text: str, *, source: str = "published model", repair: bool = True) -> World:
    constants = {name: int(value) for name, value in _CONSTANT.findall(text)}
    missing = [c for c in ("N", "startX", "startY", "targetX", "targetY") if c not in constants]
    if missing:
        raise OptionError(
            f"{source} declares no {', '.join(missing)}; give the paper's turtlebot model (models/turtlebot/model.prism)"
        )
    n = constants["N"]
    by_key: dict = {}
    for move, x, y, heading, estimate, body in _MOTION.findall(text):
        key = (int(x), int(y), int(heading), move)
        outcomes = _outcomes(body, int(x), int(y), n, repair, source)
        previous = by_key.setdefault(key, outcomes)
        if previous != outcomes:
            raise OptionError(
                f"{source}: the move {move} from cell ({x},{y}) heading {heading} depends on the estimated heading "
                f"(directionhat={estimate} differs); parley's turtlebot reads only tables that do not"
            )
    if not by_key:
        raise OptionError(
            f"{source} has no motion commands like `[north] (ready=1) & (x=..) & (y=..) & (direction=..) & (directionhat=..) -> ...`"
        )
    plan = {(int(x), int(y)): move for move, x, y in _PLAN.findall(text)}
    if not plan:
        raise OptionError(
            f"{source} has no movement controller commands like `[east] (xhat=..) & (yhat=..) & (crashed=0) & (out=0) -> true;`"
        )
    size = n + 1
    target = (constants["targetX"], constants["targetY"])
    known = {(x, y) for x, y, _, _ in by_key}
    return World(
        size=size,
        start=(constants["startX"], constants["startY"]),
        target=target,
        obstacles={(x, y) for x in range(size) for y in range(size) if (x, y) not in known and (x, y) != target},
        motions=by_key,
        plan=plan,
        source=source,
    )


def _outcomes(body: str, x: int, y: int, n: int, repair: bool, source: str) -> tuple[tuple[Outcome, float], ...]:
    result = []
    for part in _UPDATE_SPLIT.split(body):
        probability, sep, assignments = part.partition(":")
        if not sep:
            raise OptionError(
                f"{source}: cannot read the update {part.strip()!r} of cell ({x},{y}); expected P:(v'=e)&..."
            )
        values = dict(_ASSIGNMENT.findall(assignments))
        if values.get("crashed") == "1":
            outcome = CRASH
        elif values.get("out") == "1":
            outcome = OUT
        else:
            try:
                nx = _value(values["x"], x, y, n, repair)
                ny = _value(values["y"], x, y, n, repair)
                heading = int(values["direction"])
            except (KeyError, ValueError):
                raise OptionError(f"{source}: cannot read the update {part.strip()!r} of cell ({x},{y})") from None
            outcome = Outcome("move", nx - x, ny - y, heading)
        result.append((outcome, float(probability)))
    return tuple(result)


def _value(expression: str, x: int, y: int, n: int, repair: bool) -> int:
    expression = expression.replace(" ", "")
    variables = {"x": x, "y": y}
    if expression in variables:
        return variables[expression]
    match = _CLAMP.fullmatch(expression)
    if not match:
        return int(expression)
    function, bound, variable, sign = match.groups()
    moved = variables[variable] + (1 if sign == "+" else -1)
    limit = n if bound == "N" else int(bound)
    if repair and function == "max" and bound == "N":
        limit = 0  # the published generator's slip: max(N, y-1) where max(0, y-1) is meant
    return min(limit, moved) if function == "min" else max(limit, moved)
