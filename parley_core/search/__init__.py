"""Pareto search over the integer decisions of a family (pymoo).

The problem is vectorized (the evaluator sees a whole population at once) and memoized: a
:class:`~parley_core.evaluate.cache.CachingEvaluator` keeps every policy evaluated with its
values, so no policy is evaluated twice and the final front is taken from everything seen,
not only from the last population. The initial population holds the baseline policies, so
the front can never be worse than the baseline. One seed fixes the run.

- :mod:`.settings`: what a search is asked (:class:`SearchSettings`) and what it did;
- :mod:`.problem`: genes, pymoo's problem, the terminations;
- :mod:`.operators`: variation for ordinal integer policies;
- :mod:`.algorithms`: the named configurations (``paper``, ``ordinal``, ...);
- :mod:`.run`: :func:`search`.

The search ends by pymoo :class:`~pymoo.core.termination.Termination` objects, whichever
comes first: a number of generations, of evaluated policies (exactly: the generation that
reaches the budget evaluates only what is left of it), or of seconds.
"""

from parley_core.search.algorithms import ALGORITHMS, Configuration, configuration
from parley_core.search.problem import UNEVALUATED, EvaluationBudget, Genes, PolicyProblem, termination
from parley_core.search.run import initial_population, search
from parley_core.search.settings import SearchResult, SearchSettings, Stop, default

__all__ = [
    "ALGORITHMS",
    "UNEVALUATED",
    "Configuration",
    "EvaluationBudget",
    "Genes",
    "PolicyProblem",
    "SearchResult",
    "SearchSettings",
    "Stop",
    "configuration",
    "default",
    "initial_population",
    "search",
    "termination",
]
