"""The plugin manager: built-in case studies plus those installed under the entry-point group ``parley``."""

from __future__ import annotations

import importlib
import pkgutil
import warnings
from collections.abc import Iterable, Mapping
from importlib import metadata
from typing import cast

import pluggy
from attrs import field, frozen

from parley_core.errors import PluginError, PluginWarning, UnknownCaseStudyError
from parley_core.plugin import hookspecs
from parley_core.plugin.casestudy import CaseStudy

BUILTIN_PACKAGE = "parley_plugins"
"""The package of the built-in case studies: each sub-package defining a hook is a plugin."""


def builtin_plugins() -> list[str]:
    """The built-in plugin modules: the sub-packages of ``parley_plugins`` (plugins/), sorted."""
    package = importlib.import_module(BUILTIN_PACKAGE)
    return sorted(f"{BUILTIN_PACKAGE}.{info.name}" for info in pkgutil.iter_modules(package.__path__) if info.ispkg)


def plugin_manager(builtins: Iterable[str] | None = None, entry_points: bool = True) -> pluggy.PluginManager:
    """A fresh plugin manager with the built-in plugins and, unless disabled, installed ones;
    strict: a plugin that fails to load, implements a hook parley does not specify (a misspelt
    name, as pytest's ``check_pending`` refuses), or provides no hook at all is an error."""
    return _manager(builtins, entry_points, strict=True).pm


@frozen
class _Loaded:
    pm: pluggy.PluginManager
    problems: tuple[str, ...]
    """What was wrong with each installed plugin that was skipped (lenient loading)."""
    distributions: Mapping[str, str]
    """Installed plugin -> its distribution and version."""


def _manager(builtins: Iterable[str] | None, entry_points: bool, strict: bool) -> _Loaded:
    """The plugin manager, and with ``strict`` False the installed plugins that are broken left
    out, each with a line saying what is wrong. A broken built-in is always an error."""
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    for module_name in builtin_plugins() if builtins is None else builtins:
        pm.register(importlib.import_module(module_name), name=module_name)
    check_hooks(pm)
    problems: list[str] = []
    distributions: dict[str, str] = {}
    for entry in metadata.entry_points(group=hookspecs.PROJECT) if entry_points else ():
        if pm.get_plugin(entry.name) is not None or pm.is_blocked(entry.name):
            continue
        distribution = f"{entry.dist.name} {entry.dist.version}" if entry.dist is not None else ""
        shown = f"plugin {entry.name}" + (f" ({distribution})" if distribution else "")
        remedy = f"fix or uninstall it (pip uninstall {entry.dist.name})" if entry.dist else "fix or uninstall it"
        try:
            plugin = entry.load()
        except Exception as exc:  # an installed plugin failed to import
            message = f"{shown} failed to load ({type(exc).__name__}: {exc}); {remedy}"
            if strict:
                raise PluginError(message) from exc
            problems.append(message)
            continue
        pm.register(plugin, name=entry.name)
        try:
            check_hooks(pm)
        except PluginError as exc:
            pm.unregister(name=entry.name)
            if strict:
                raise
            problems.append(f"{exc}; {remedy}")
            continue
        if not pm.get_hookcallers(plugin):
            pm.unregister(name=entry.name)
            message = (
                f"{shown} was loaded but provides no case study: mark its parley_case_studies function "
                "with @hookimpl (from parley_core import hookimpl)"
            )
            if strict:
                raise PluginError(message)
            problems.append(message)
            continue
        if distribution:
            distributions[entry.name] = distribution
    return _Loaded(pm=pm, problems=tuple(problems), distributions=distributions)


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


def versions(pm: pluggy.PluginManager, installed: Mapping[str, str] | None = None) -> dict[str, str]:
    """Each registered plugin's distribution and version (``parley-thermostat 0.1.0``): of
    its entry point's distribution (``installed``, by plugin name, or pluggy's own record),
    or parley's own for the built-ins."""
    found = {
        pm.get_name(plugin) or repr(plugin): f"{dist.project_name} {dist.version}"
        for plugin, dist in pm.list_plugin_distinfo()
    }
    found.update(installed or {})
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
    problems: tuple[str, ...] = ()
    """The installed plugins left out, each with what is wrong with it."""

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


def load_registry(pm: pluggy.PluginManager | None = None, *, strict: bool = False) -> Registry:
    """Collect every plugin's case studies. A broken installed plugin (one that fails to load,
    implements an unknown hook, provides none, fails to list its case studies or returns
    something else) is left out with a :class:`~parley_core.errors.PluginWarning` saying what
    is wrong, and the others stay usable; with ``strict`` (the conformance suite, a plugin's
    own tests) it is a :class:`~parley_core.errors.PluginError`, as a broken built-in always is.
    A case study name provided twice is an error."""
    if pm is None:
        loaded = _manager(None, True, strict)
        pm, problems, installed = loaded.pm, list(loaded.problems), dict(loaded.distributions)
    else:
        problems, installed = [], {}
    case_studies: dict[str, CaseStudy] = {}
    providers: dict[str, str] = {}
    # Each implementation is called on its own (not through the hook) so that every case
    # study is attributed to the plugin that provided it; registration order.
    for impl in pm.hook.parley_case_studies.get_hookimpls():
        provider = pm.get_name(impl.plugin) or repr(impl.plugin)
        try:
            provided = _case_studies_of(impl, provider)
        except PluginError as exc:
            if strict or provider.startswith(f"{BUILTIN_PACKAGE}."):
                raise
            problems.append(f"{exc}; fix or uninstall it")
            continue
        for case in provided:
            if case.name in case_studies:
                raise PluginError(
                    f"case study {case.name!r} is provided twice, by {providers[case.name]} and by {provider}; "
                    "uninstall one of them or rename its case study"
                )
            case_studies[case.name] = case
            providers[case.name] = provider
    for problem in problems:
        warnings.warn(f"{problem}; the other case studies are unaffected", PluginWarning, stacklevel=2)
    return Registry(
        case_studies=case_studies,
        providers=providers,
        distributions=versions(pm, installed),
        problems=tuple(problems),
    )


def _case_studies_of(impl, provider: str) -> list[CaseStudy]:
    """One plugin's case studies, as its hook implementation returns them (checked)."""
    try:
        # pluggy types the result object; the hookspec asks for a list of CaseStudy (checked below)
        provided = cast("object", impl.function())
    except Exception as exc:
        raise PluginError(f"plugin {provider} failed to list its case studies ({type(exc).__name__}: {exc})") from exc
    if isinstance(provided, CaseStudy):
        raise PluginError(f"plugin {provider} returned one CaseStudy, not a list of them; return [{provided.name}]")
    if provided is None:
        return []
    if not isinstance(provided, (list, tuple)):
        raise PluginError(f"plugin {provider} returned {type(provided).__name__}, expected a list of CaseStudy")
    for case in provided:
        if not isinstance(case, CaseStudy):
            raise PluginError(f"plugin {provider} returned {type(case).__name__}, expected CaseStudy")
    return list(provided)
