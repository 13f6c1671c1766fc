"""The plugin contract: pluggy hook specifications of the project ``parley``.

A plugin is a module (or any object) with functions marked by :data:`hookimpl` and named
like the specifications below. Built-in case studies live in ``parley_plugins``; a
third-party distribution registers its module under the entry-point group ``parley``::

    [project.entry-points.parley]
    my_case = "my_package.parley_plugin"

and ``parley list`` shows its case studies. Plugins never import stormpy or pymoo: they
describe a system (PRISM text, services, observation, objectives, baselines) and the core
does augmentation, search, verification and reports.
"""

from __future__ import annotations

import pluggy

from parley_core.plugin.casestudy import CaseStudy

PROJECT = "parley"

hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec
def parley_case_studies() -> list[CaseStudy]:  # type: ignore[empty-body]  # a hookspec: only its signature is used
    """Return the case studies this plugin provides.

    Each is a :class:`~parley_core.plugin.casestudy.CaseStudy`; its fields (name, options, build,
    plot, quick options, requirement settings, pruning) are documented once, in that class.

    Two plugins returning the same name is an error naming both. The hook is called once per
    plugin manager; ``build`` is called once per run.

    Example::

        from parley_core import CaseStudy, hookimpl

        @hookimpl
        def parley_case_studies():
            return [CaseStudy(name="coin", description="a coin that lies",
                              options_type=CoinOptions, build=build_coin)]
    """
