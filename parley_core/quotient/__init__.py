"""The quotient: one MDP that holds every policy of a family (PAYNT's family/quotient split).

- :mod:`.mdp` builds the quotient MDP of a system with Storm and reads it into arrays, with
  each choice's service values and observation valuation; it also answers which
  observation valuations ever consult a service (the pruning analysis).
- :mod:`.coloring` gives each choice the decision of a family it needs (PAYNT's coloring)
  and packs the arrays the solver needs (:class:`~.coloring.Quotient`, picklable).
- :mod:`.compile` turns objectives into the kernels' form.
- :mod:`.solver` evaluates one policy at a time on a quotient; :mod:`.kernels` are its
  compiled loops, :mod:`.ordering` its sparse LU solves.

The process-pool evaluator built on it is :class:`parley_core.evaluate.quotient.QuotientEvaluator`.
"""
