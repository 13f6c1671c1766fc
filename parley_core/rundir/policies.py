"""Policies files.

Two CSV layouts, both with a first column ``policy`` naming the policy:

- long form (the input format): then the observation variables, then one column per service
  constant; one row per (policy, observation valuation)::

      policy,xhat,yhat,c
      mine,0,0,3
      mine,0,1,10
      ...

- wide form (what a run writes as ``policies.csv``): then one column per decision constant
  of the augmented model (``c_0_0, c_0_1, ...``); one row per policy.

:func:`read_policies` accepts either and tells them apart by the header.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable
from pathlib import Path

from parley_core.errors import PolicyError
from parley_core.files import read_text
from parley_core.model import Family, Policy
from parley_core.plugin.casestudy import PolicyTable
from parley_core.urc.controller import URC


def read_policies(path: Path, family: Family) -> list[Policy]:
    """The policies in a long- or wide-form CSV file, checked against the family."""
    text = read_text(path, "policies file", "give a CSV text file (see `parley evaluate --help`)", PolicyError)
    rows = [row for row in csv.reader(io.StringIO(text)) if any(cell.strip() for cell in row)]
    if not rows:
        raise PolicyError(f"policies file {path} is empty; give a header line and one line per policy or valuation")
    header = [cell.strip() for cell in rows[0]]
    body = rows[1:]
    if not header or header[0] != "policy":
        raise PolicyError(
            f"policies file {path}: the first column must be 'policy', found {header[0] if header else 'nothing'!r}"
        )
    observation = list(family.observation)
    constants = [s.constant for s in family.services]
    if header[1:] == observation + constants:
        policies = _read_long(path, body, family)
    elif set(header[1:]) == set(family.names) and len(header) == len(family.names) + 1:
        policies = _read_wide(path, header, body, family)
    else:
        raise PolicyError(
            f"policies file {path}: header {','.join(header)!r} fits neither layout; expected "
            f"'policy,{','.join(observation + constants)}' (one row per valuation) or "
            f"'policy,{family.names[0]},...' (one column per decision constant)"
        )
    if not policies:
        raise PolicyError(f"policies file {path} has a header but no policies")
    for policy in policies:
        family.check(policy)
    return policies


def _integer(path: Path, line: int, column: str, text: str) -> int:
    try:
        return int(text.strip())
    except ValueError:
        raise PolicyError(f"policies file {path}, line {line}: {column}={text!r} is not an integer") from None


def _read_long(path: Path, body: list[list[str]], family: Family) -> list[Policy]:
    observation = family.observation
    services = family.services
    width = 1 + len(observation) + len(services)
    tables: dict[str, dict[tuple[int, ...], list[int]]] = {}
    for line, row in enumerate(body, start=2):
        if len(row) != width:
            raise PolicyError(f"policies file {path}, line {line}: expected {width} cells, found {len(row)}")
        name = row[0].strip()
        if not name:
            raise PolicyError(f"policies file {path}, line {line}: the policy name is empty")
        valuation = tuple(_integer(path, line, v, row[1 + i]) for i, v in enumerate(observation))
        values = [_integer(path, line, s.constant, row[1 + len(observation) + i]) for i, s in enumerate(services)]
        table = tables.setdefault(name, {})
        if valuation in table:
            raise PolicyError(
                f"policies file {path}, line {line}: policy {name!r} gives {_show(observation, valuation)} twice"
            )
        table[valuation] = values
    known = set(family.valuations)
    ignored = set(family.left_out)  # valuations at which no service is ever consulted
    policies = []
    for name, table in tables.items():
        unknown = [v for v in table if v not in known and v not in ignored]
        if unknown:
            raise PolicyError(
                f"policies file {path}: policy {name!r} gives {_show(observation, unknown[0])}, "
                "which is not an observation valuation of the model (outside the variables' ranges)"
            )
        missing = [v for v in family.valuations if v not in table]
        if missing:
            raise PolicyError(
                f"policies file {path}: policy {name!r} lacks {_show(observation, missing[0])}"
                f"{f' and {len(missing) - 1} more valuations' if len(missing) > 1 else ''}; give one row per valuation"
            )
        position = {s.constant: i for i, s in enumerate(services)}
        values = [table[d.valuation][position[d.service.constant]] for d in family.decisions]
        policies.append(Policy(name=name, values=values))
    return policies


def _read_wide(path: Path, header: list[str], body: list[list[str]], family: Family) -> list[Policy]:
    column = {name: i for i, name in enumerate(header)}
    policies = []
    seen = set()
    for line, row in enumerate(body, start=2):
        if len(row) != len(header):
            raise PolicyError(f"policies file {path}, line {line}: expected {len(header)} cells, found {len(row)}")
        name = row[0].strip()
        if not name or name in seen:
            raise PolicyError(f"policies file {path}, line {line}: policy name {name!r} is empty or repeated")
        seen.add(name)
        values = [_integer(path, line, n, row[column[n]]) for n in family.names]
        policies.append(Policy(name=name, values=values))
    return policies


def _show(names: Iterable[str], valuation: tuple[int, ...]) -> str:
    return ", ".join(f"{n}={v}" for n, v in zip(names, valuation))


def wide_csv(family: Family, policies: Iterable[Policy]) -> str:
    """Policies as wide-form CSV: ``policy`` then one column per decision constant."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["policy", *family.names])
    for policy in policies:
        writer.writerow([policy.name, *policy.values])
    return out.getvalue()


def long_csv(family: Family, policies: Iterable[Policy]) -> str:
    """Policies as long-form CSV: ``policy``, the observation variables, one column per service."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    constants = [s.constant for s in family.services]
    writer.writerow(["policy", *family.observation, *constants])
    for policy in policies:
        for valuation, values in table(family, policy).items():
            writer.writerow([policy.name, *valuation, *(values[c] for c in constants)])
    return out.getvalue()


def table(family: Family, policy: Policy) -> PolicyTable:
    """A policy as observation valuation -> {service constant: value}."""
    result: dict[tuple[int, ...], dict[str, int]] = {}
    for decision, value in zip(family.decisions, policy.values):
        result.setdefault(decision.valuation, {})[decision.service.constant] = value
    return PolicyTable(result)


def policy_from_file(path: Path, family: Family) -> Policy:
    """The one policy of a controller file (``parley select``) or of a policies file holding one."""
    if path.suffix == ".json":
        urc = URC.load(path)
        if tuple(urc.observation) != tuple(family.observation):
            raise PolicyError(
                f"controller {path} reads {', '.join(urc.observation)}, the model {', '.join(family.observation)}"
            )
        values = [urc.decide(d.valuation)[d.service.constant] for d in family.decisions]
        return Policy(name=urc.policy or path.stem, values=values)
    policies = read_policies(path, family)
    if len(policies) != 1:
        raise PolicyError(
            f"policies file {path} holds {len(policies)} policies; give a file with one (or a controller file)"
        )
    return policies[0]


def policies_or_constant(family: Family, path: Path | None, constant: int | None) -> list[Policy]:
    """The policies of ``path``, or the one policy that uses ``constant`` everywhere (exactly one must be given)."""
    if (path is None) == (constant is None):
        raise PolicyError("give exactly one of --policies FILE and --constant K")
    if path is not None:
        return read_policies(path, family)
    assert constant is not None  # exactly one of the two is given
    policy = family.uniform(f"constant-{constant}", {s.constant: constant for s in family.services})
    family.check(policy)
    return [policy]
