"""Building a user's program where a crash cannot take parley down.

Storm's builder kills the whole process with SIGFPE on an integer division by zero in a
guard, update or probability, and so does its constant substitution on ``const int k =
c/0`` (found by the fuzz test); a user's model must not take parley down with it.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping

import stormpy
from stormpy.developer.storage import PrismProgram

from parley_core.prism.program import define_constants


def build_crashes(make: Callable[[], PrismProgram], values: Mapping[str, int]) -> int | None:
    """Make a program with ``make``, set its undefined constants to ``values`` and build it,
    all in a forked child; return the signal that killed the child, or None (also when it
    raised: the parent reports errors when it does the same work). Storm's builder kills the
    whole process with SIGFPE on an integer division by zero in a guard, update or
    probability, and so does its constant substitution on ``const int k = c/0`` (found by the
    fuzz test); a user's model must not take parley down with it."""
    if not hasattr(os, "fork"):
        return None
    pid = os.fork()
    if pid == 0:  # the child: build, then leave at once whatever happened
        import faulthandler

        faulthandler.disable()  # a crash here is the expected answer, not worth a dump
        code = 0
        try:
            program = make()
            # a decision constant the model defines (const int c = 4) is built at that value:
            # defining it again is an error that Storm would log on stderr
            undefined = {c.name for c in program.constants if not c.defined}
            stormpy.build_model(define_constants(program, {k: v for k, v in values.items() if k in undefined}))
        except BaseException:
            code = 1
        os._exit(code)
    _, status = os.waitpid(pid, 0)
    return os.WTERMSIG(status) if os.WIFSIGNALED(status) else None
