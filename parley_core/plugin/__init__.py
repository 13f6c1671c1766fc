"""The contract a plugin author reads: the hook (:mod:`.hookspecs`), :class:`~.casestudy.CaseStudy`
(:mod:`.casestudy`), typed options (:mod:`.options`), the map of the report's policy view
(:mod:`.policymap`), a closed-loop simulator (:mod:`.simulator`), and the manager that finds
plugins (:mod:`.manager`). Plugins import these names from :mod:`parley_core`."""
