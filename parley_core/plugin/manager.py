"""The plugin manager: built-in case studies plus those installed under the entry-point group ``parley``."""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Iterable, Mapping
from importlib import metadata
from typing import cast

import pluggy
from attrs import field, frozen

from parley_core.errors import PluginError, UnknownCaseStudyError
from parley_core.plugin import hookspecs
from parley_core.plugin.casestudy import CaseStudy

BUILTIN_PACKAGE = "parley_plugins"
"""The package of the built-in case studies: each sub-package defining a hook is a plugin."""


def builtin_plugins() -> list[str]:
    """The built-in plugin modules: the sub-packages of ``parley_plugins`` (plugins/), sorted."""
    package = importlib.import_module(BUILTIN_PACKAGE)
    return sorted(f"{BUILTIN_PACKAGE}.{info.name}" for info in pkgutil.iter_modules(package.__path__) if info.ispkg)


def plugin_manager(builtins: Iterable[str] | None = None, entry_points: bool = True) -> pluggy.PluginManager:
    """A fresh plugin manager with the built-in plugins and, unless disabled, installed ones.

    A plugin implementing a hook that parley does not specify (a misspelt name, say) is an
    error, as in pytest (``check_pending``)."""
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    for module_name in builtin_plugins() if builtins is None else builtins:
        pm.register(importlib.import_module(module_name), name=module_name)
    if entry_points:
        try:
            pm.load_setuptools_entrypoints(hookspecs.PROJECT)
        except Exception as exc:  # an installed plugin failed to import
            raise PluginError(
                f"an installed parley plugin failed to load ({type(exc).__name__}: {exc}); "
                "fix or uninstall it (pip uninstall)"
            ) from exc
    check_hooks(pm)
    return pm


def check_hooks(pm: pluggy.PluginManager) -> None:
    """Refuse hook implementations that match no hook specification."""
    try:
        pm.check_pending()
    except pluggy.PluginValidationError as exc:
        name = pm.get_name(exc.plugin) or repr(exc.plugin)
        known = ", ".join(sorted(n for n in dir(hookspecs) if n.startswith(f"{hookspecs.PROJECT}_")))
        raise PluginError(
            f"plugin {name} implements a hook parley does not know ({exc}); the hooks are: {known}"
        ) from None


def versions(pm: pluggy.PluginManager) -> dict[str, str]:
    """Each registered plugin's distribution and version (``parley-thermostat 0.1.0``): of
    its entry point's distribution, or parley's own for the built-ins."""
    found = {
        pm.get_name(plugin) or repr(plugin): f"{dist.project_name} {dist.version}"
        for plugin, dist in pm.list_plugin_distinfo()
    }
    try:
        own = f"parley {metadata.version('parley')}"
    except metadata.PackageNotFoundError:
        own = "parley (not installed)"
    for plugin in pm.get_plugins():
        name = pm.get_name(plugin) or repr(plugin)
        if name not in found and name.startswith(f"{BUILTIN_PACKAGE}."):
            found[name] = own
    return found


def _case_studies(value: Mapping[str, CaseStudy]) -> dict[str, CaseStudy]:
    return dict(value)


def _names(value: Mapping[str, str]) -> dict[str, str]:
    return dict(value)


@frozen(kw_only=True)
class Registry:
    """The registered case studies by name, with the plugin that provided each."""

    case_studies: Mapping[str, CaseStudy] = field(converter=_case_studies)
    providers: Mapping[str, str] = field(converter=_names)
    """Case study -> the plugin (module or entry point name) that provided it."""
    distributions: Mapping[str, str] = field(factory=dict, converter=_names)
    """Plugin -> its distribution and version, where known."""

    def provider(self, name: str) -> str:
        """The plugin of a case study with its distribution: ``parley_thermostat (parley-thermostat 0.1.0)``."""
        plugin = self.providers[name]
        distribution = self.distributions.get(plugin)
        return f"{plugin} ({distribution})" if distribution else plugin

    @property
    def names(self) -> list[str]:
        return sorted(self.case_studies)

    def get(self, name: str) -> CaseStudy:
        try:
            return self.case_studies[name]
        except KeyError:
            valid = ", ".join(self.names) or "none are registered"
            raise UnknownCaseStudyError(f"unknown case study {name!r}; valid: {valid} (see `parley list`)") from None


def load_registry(pm: pluggy.PluginManager | None = None) -> Registry:
    """Collect every plugin's case studies; duplicate names raise PluginError."""
    pm = pm if pm is not None else plugin_manager()
    case_studies: dict[str, CaseStudy] = {}
    providers: dict[str, str] = {}
    # Each implementation is called on its own (not through the hook) so that every case
    # study is attributed to the plugin that provided it; registration order.
    for impl in pm.hook.parley_case_studies.get_hookimpls():
        provider = pm.get_name(impl.plugin) or repr(impl.plugin)
        try:
            # pluggy types the result object; the hookspec asks for a list of CaseStudy (checked below)
            provided = cast("Iterable[object] | None", impl.function())
        except Exception as exc:
            raise PluginError(
                f"plugin {provider} failed to list its case studies ({type(exc).__name__}: {exc})"
            ) from exc
        for case in provided or ():
            if not isinstance(case, CaseStudy):
                raise PluginError(f"plugin {provider} returned {type(case).__name__}, expected CaseStudy")
            if case.name in case_studies:
                raise PluginError(
                    f"case study {case.name!r} is provided twice, by {providers[case.name]} and by {provider}; "
                    "uninstall one of them or rename its case study"
                )
            case_studies[case.name] = case
            providers[case.name] = provider
    return Registry(case_studies=case_studies, providers=providers, distributions=versions(pm))
