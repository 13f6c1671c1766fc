"""The plugin contract: built-ins, entry points, duplicate and unknown names."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import types
from pathlib import Path

import attrs
import pytest

from parley_core import CaseStudy, hookimpl
from parley_core.errors import PluginError, PluginWarning, UnknownCaseStudyError
from parley_core.plugin.manager import load_registry, plugin_manager

ROOT = Path(__file__).resolve().parents[1]


@attrs.frozen
class _Empty:
    pass


EXAMPLE = ROOT / "docs" / "examples" / "parley-thermostat"


def test_builtins_are_registered():
    registry = load_registry(plugin_manager(entry_points=False))
    assert "robot_grid" in registry.names
    assert registry.providers["robot_grid"] == "parley_plugins.robot_grid"


def test_a_misspelt_hook_is_an_error_naming_the_hooks():
    module = types.ModuleType("misspelt")

    @hookimpl
    def parley_case_study():  # the hook is parley_case_studies
        return []

    module.parley_case_study = parley_case_study
    pm = plugin_manager(entry_points=False)
    pm.register(module, name="misspelt")
    from parley_core.plugin.manager import check_hooks

    with pytest.raises(
        PluginError, match=r"plugin misspelt implements a hook parley does not know .*parley_case_studies"
    ):
        check_hooks(pm)


def test_list_names_each_plugin_with_its_distribution():
    registry = load_registry(plugin_manager(entry_points=False))
    assert registry.provider("robot_grid").startswith("parley_plugins.robot_grid (parley ")


def test_unknown_case_study_lists_the_valid_names():
    registry = load_registry(plugin_manager(entry_points=False))
    with pytest.raises(UnknownCaseStudyError, match=r"unknown case study 'robot'; valid: .*robot_grid"):
        registry.get("robot")


def _plugin(name: str) -> types.ModuleType:
    module = types.ModuleType(f"fake_{name}")

    @hookimpl
    def parley_case_studies():
        return [CaseStudy(name=name, description="fake", options_type=_Empty, build=lambda o: None)]

    module.parley_case_studies = parley_case_studies
    return module


def test_duplicate_names_are_an_error_naming_both_plugins():
    pm = plugin_manager(entry_points=False)
    pm.register(_plugin("robot_grid"), name="impostor")
    with pytest.raises(
        PluginError, match="'robot_grid' is provided twice, by parley_plugins.robot_grid and by impostor"
    ):
        load_registry(pm)


def _odd(returned, name="odd"):
    module = types.ModuleType(name)

    @hookimpl
    def parley_case_studies():
        return returned

    module.parley_case_studies = parley_case_studies
    pm = plugin_manager(entry_points=False)
    pm.register(module, name=name)
    return pm


THERMOSTAT = CaseStudy(name="odd_one", description="one", options_type=_Empty, build=lambda o: None)


@pytest.mark.parametrize(
    ("returned", "message"),
    [
        (["not a case study"], "plugin odd returned str, expected CaseStudy"),
        (THERMOSTAT, r"plugin odd returned one CaseStudy, not a list of them; return \[odd_one\]"),
        ("robot", "plugin odd returned str, expected a list of CaseStudy"),
    ],
)
def test_a_plugin_returning_something_else_is_skipped_with_a_warning_or_an_error_when_strict(returned, message):
    with pytest.warns(PluginWarning, match=message):
        registry = load_registry(_odd(returned))
    assert "robot_grid" in registry.names and "odd_one" not in registry.names  # the others stay usable
    assert len(registry.problems) == 1 and "the other case studies" not in registry.problems[0]
    with pytest.raises(PluginError, match=message):
        load_registry(_odd(returned), strict=True)


def test_a_plugin_that_fails_to_list_its_case_studies_is_skipped():
    module = types.ModuleType("failing")

    @hookimpl
    def parley_case_studies():
        raise RuntimeError("no map here")

    module.parley_case_studies = parley_case_studies
    pm = plugin_manager(entry_points=False)
    pm.register(module, name="failing")
    with pytest.warns(
        PluginWarning, match=r"plugin failing failed to list its case studies \(RuntimeError: no map here\)"
    ):
        assert "robot_grid" in load_registry(pm).names


def _install_example(site: Path) -> dict[str, str]:
    """Put the example plugin and its distribution metadata (with the entry point) on a path."""
    shutil.copy(EXAMPLE / "parley_thermostat.py", site)
    info = site / "parley_thermostat-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: parley-thermostat\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text("[parley]\nthermostat = parley_thermostat\n")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), env.get("PYTHONPATH", "")])
    env["COLUMNS"] = "200"  # rich wraps table cells to the terminal width
    return env


@pytest.mark.slow
def test_an_installed_plugin_is_found_through_its_entry_point_and_runs(tmp_path):
    env = _install_example(tmp_path)
    listed = subprocess.run(
        [sys.executable, "-m", "parley_core", "list"], env=env, capture_output=True, text=True, timeout=120
    )
    assert listed.returncode == 0, listed.stderr
    assert "thermostat" in listed.stdout and "robot_grid" in listed.stdout
    assert "parley-thermostat 0.1.0" in listed.stdout
    baseline = subprocess.run(
        [sys.executable, "-m", "parley_core", "baseline", "thermostat", "--json", "--workers", "1"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert baseline.returncode == 0, baseline.stderr
    document = json.loads(baseline.stdout)
    by_name = {p["policy"]: p["values"] for p in document["policies"]}
    # Calibrating every round keeps the room comfortable: the controller always knows the
    # temperature and corrects one level of drift at a time. 20 rounds -> 20 calibrations.
    assert by_name["every-1"]["discomfort"] == pytest.approx(0.0, abs=1e-12)
    assert by_name["every-1"]["calibrations"] == pytest.approx(20.0, abs=1e-9)
    assert by_name["every-2"]["calibrations"] == pytest.approx(10.0, abs=1e-9)
    assert 0 < by_name["every-2"]["discomfort"] < by_name["every-4"]["discomfort"]


def _parley(env, *arguments: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "parley_core", *arguments], env=env, capture_output=True, text=True, timeout=300
    )


def _strict(env) -> subprocess.CompletedProcess:
    """The conformance suite's view of the installed plugins: strict."""
    code = "from parley_core.plugin.manager import load_registry; load_registry(strict=True)"
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)


BROKEN = [
    ("misspelt hook", lambda s: s.replace("def parley_case_studies(", "def parley_casestudies("),
     "plugin thermostat implements a hook parley does not know"),
    ("no @hookimpl", lambda s: s.replace("@hookimpl\ndef parley_case_studies(", "def parley_case_studies("),
     "plugin thermostat (parley-thermostat 0.1.0) was loaded but provides no case study: mark its "
     "parley_case_studies function with @hookimpl"),
    ("fails to import", lambda s: "raise ImportError('boom')\n",
     "plugin thermostat (parley-thermostat 0.1.0) failed to load (ImportError: boom); "
     "fix or uninstall it (pip uninstall parley-thermostat)"),
    ("one CaseStudy", lambda s: s.replace("    return [\n        CaseStudy(", "    return (\n        CaseStudy(").replace("        )\n    ]", "        )\n    )"),
     "plugin thermostat returned one CaseStudy, not a list of them"),
]  # fmt: skip


@pytest.mark.parametrize(("label", "breaking", "message"), BROKEN, ids=[b[0] for b in BROKEN])
def test_a_broken_installed_plugin_fails_alone(tmp_path, label, breaking, message):
    env = _install_example(tmp_path)
    source = tmp_path / "parley_thermostat.py"
    broken = breaking(source.read_text())
    assert broken != source.read_text(), label  # the example still has what the breaking edits
    source.write_text(broken)
    listed = _parley(env, "list")
    assert listed.returncode == 0, listed.stderr
    assert "robot_grid" in listed.stdout and "thermostat" not in listed.stdout
    (warning,) = [line for line in listed.stderr.splitlines() if line.startswith("warning:")]
    assert message in warning and "Traceback" not in listed.stderr
    strict = _strict(env)
    assert strict.returncode != 0 and message in strict.stderr


@pytest.mark.slow
def test_a_run_beside_a_broken_plugin_works_and_warns_once(tmp_path):
    env = _install_example(tmp_path)
    (tmp_path / "parley_thermostat.py").write_text("raise ImportError('boom')\n")
    out = tmp_path / "run"
    ran = _parley(env, "run", "robot_grid", "--set", "size=3", "--generations", "2", "--population", "6",
                  "--workers", "1", "--out", str(out))  # fmt: skip
    assert ran.returncode == 0, ran.stderr
    assert [line for line in ran.stderr.splitlines() if line.startswith("warning:")] == [
        "warning: plugin thermostat (parley-thermostat 0.1.0) failed to load (ImportError: boom); "
        "fix or uninstall it (pip uninstall parley-thermostat); the other case studies are unaffected"
    ]
    assert (out / "front.csv").is_file() and "Traceback" not in ran.stderr


def test_the_plugin_guide_names_every_case_study_field():
    guide = (ROOT / "docs" / "plugins.md").read_text()
    sentence = guide[guide.index("Their\nfields are documented once") :].split("; a test checks")[0]
    named = {part.strip(" `\n,.") for part in sentence.split(":", 1)[1].replace(" and ", ",").split(",")}
    assert named == {f.name for f in attrs.fields(CaseStudy)}


def test_help_shows_every_field_of_the_plugin_facing_value_objects():
    import pydoc

    import parley.plugin as kit
    from parley_core.model import Decision, Family, Front, Policy, Valued

    classes = [kit.Service, kit.Objective, kit.Baseline, kit.SystemModel, kit.CaseStudy, kit.PolicyMap]
    classes += [kit.Simulator, kit.Episodes, kit.EventModel, Decision, Family, Policy, Valued, Front]
    for cls in classes:
        text = pydoc.render_doc(cls)
        missing = [f.name for f in attrs.fields(cls) if f"{f.name}: " not in text]
        assert not missing, (cls.__name__, missing)
    assert "The model's ``const int`` that decides when the service runs" in pydoc.render_doc(kit.Service)


def test_the_plugin_surface_is_one_module_without_storm_or_matplotlib():
    code = (
        "import sys, parley.plugin as p; print(len(p.__all__), 'stormpy' in sys.modules, 'matplotlib' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60).stdout.split()
    assert out[1:] == ["False", "False"] and int(out[0]) >= 30
    import parley.plugin as kit

    assert all(getattr(kit, name) is not None for name in kit.__all__)
