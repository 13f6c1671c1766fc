"""Certified bounds and exact fronts: the ideal point and the Pareto outer approximation of
the quotient's relaxation (:mod:`.bound`), its belief tightening (:mod:`.belief`), branch and
bound (:mod:`.branch_and_bound`) with its archive (:mod:`.archive`), the bounds a run computes
after its search (:mod:`.after_search`), what they report (:mod:`.records`), and Storm's own
Pareto query, which tests and benchmarks hold the bound against (:mod:`.storm_pareto`)."""
