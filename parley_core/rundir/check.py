"""The files of a check (``parley check``): ``check.json``, the answer as one document; where
it is feasible, the run directory of the policies inside the box (as ``parley run`` writes
one) with the chosen policy's ``controller.json``; where it is infeasible,
``certificate.json``, every sub-family closed and how (see
:mod:`parley_core.optimality.requirement`), which ``parley check --recheck`` checks again.

The directory is written next to its destination and moved into place, as a run's is.
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path
from typing import Any

from parley_core.optimality.requirement import Verdict, certificate_json
from parley_core.pipeline import CheckResult
from parley_core.plugin.options import options_as_dict
from parley_core.rundir.write import check_output, move_into_place, write_run

FORMAT = "parley-check/1"
CHECK = "check.json"
CERTIFICATE = "certificate.json"
CONTROLLER = "controller.json"


def _number(value: float) -> float | str | None:
    value = float(value)
    if math.isnan(value):
        return None
    return value if math.isfinite(value) else ("inf" if value > 0 else "-inf")


def check_document(
    result: CheckResult, out: Path, command: str | None = None, model: dict[str, Any] | None = None
) -> dict[str, Any]:
    """What ``check.json`` holds (and ``parley check --json`` prints)."""
    found, family = result.answer, result.family
    names = [o.name for o in family.objectives]
    document: dict[str, Any] = {
        "format": FORMAT,
        "answer": found.verdict.value,
        "requirement": [str(c) for c in found.requirement.constraints],
        "case_study": result.prepared.case.name,
        "options": options_as_dict(result.prepared.options),
        "objectives": names,
        "directory": str(out),
    }
    if model is not None:
        document["model"] = model  # a user's model: what `parley recheck` builds the family from
    if result.run is not None:
        run = result.run
        chosen = run.front.policies[run.selected]
        document["policy"] = {
            "name": chosen.name,
            "values": {n: _number(v) for n, v in zip(names, run.front.values[run.selected])},
            "verified_by": run.verification.by.value,
            "max_relative_difference": _number(run.verification.max_relative_difference),
            "controller": str(out / CONTROLLER),
        }
        document["policies_inside"] = len(run.front.policies)
    if found.verdict is Verdict.INFEASIBLE:
        document["certificate"] = str(out / CERTIFICATE)
        document["sub_families"] = len(found.closed)
    if found.verdict is Verdict.UNKNOWN:
        document["open_share"] = found.open_share
        document["open_best"] = {n: _number(v) for n, v in zip(names, found.open_best)}
    document["branch_and_bound"] = found.counts.to_json()
    document["timings"] = {k: round(v, 3) for k, v in result.timings.items()}
    if command is not None:
        document["command"] = command
    return document


def write_check(
    result: CheckResult,
    out: Path,
    *,
    force: bool = False,
    command: str | None = None,
    model: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Write the check's directory; returns ``check.json``'s document."""
    from parley_core.rundir import read
    from parley_core.rundir.select import controller

    check_output(out, force)
    document = check_document(result, out.resolve(), command, model)
    if result.run is not None:
        write_run(result.run, out, force=force)
        run = read.load(out)
        controller(run, result.run.front.policies[result.run.selected].name).save(out / CONTROLLER)
        (out / CHECK).write_text(json.dumps(document, indent=2) + "\n")
        return document
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    staging.chmod(0o755)
    try:
        (staging / "model.prism").write_text(result.family.prism)
        (staging / "properties.pctl").write_text(result.family.properties_text())
        if result.answer.verdict is Verdict.INFEASIBLE:
            (staging / CERTIFICATE).write_text(json.dumps(certificate_json(result.family, result.answer)) + "\n")
        (staging / CHECK).write_text(json.dumps(document, indent=2) + "\n")
        move_into_place(staging, out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return document
