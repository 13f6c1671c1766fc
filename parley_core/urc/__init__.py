"""Controllers a system runs: the URC of one policy (:mod:`.controller`, its controller file
and ``decide(observation)``), the adaptive URC that switches between policies
(:mod:`.adaptive`) and the events it weighs (:mod:`.events`). Nothing here imports Storm."""

from parley_core.urc.controller import URC

__all__ = ["URC"]
