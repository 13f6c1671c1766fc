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
        # and Storm's own log lines here (an error the parent reports in its own words, or
        # "Illegally defining already defined constant" for a decision constant the model
        # defines, whose build the quotient's check below covers) would only confuse
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)  # Storm logs to stdout
        os.dup2(devnull, 2)
        code = 0
        try:
            program = make()
            program.substitute_constants()
            stormpy.build_model(define_constants(program, values))
        except BaseException:
            code = 1
        os._exit(code)
    _, status = os.waitpid(pid, 0)
    return os.WTERMSIG(status) if os.WIFSIGNALED(status) else None
