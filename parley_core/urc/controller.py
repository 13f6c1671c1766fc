"""The runtime URC: a synthesized policy as a controller file, and ``decide(observation)``.

A controller file (JSON, written by ``parley select``) holds the observation variables,
the services, one decision per observation valuation the policy was synthesized for, the
valuations left out because no service is ever consulted there, and the policy's
Storm-checked objective values. ``URC.decide`` refuses observations outside that domain
with a clear error instead of guessing a default.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from attrs import field, frozen

from parley_core.errors import ObservationError, ParleyError, PolicyError
from parley_core.files import read_text
from parley_core.model import Service

FORMAT = "parley-urc/1"


def _table(value: Mapping[tuple[int, ...], Mapping[str, int]]) -> dict[tuple[int, ...], Mapping[str, int]]:
    return dict(value)


def _valuations(value: Iterable[tuple[int, ...]]) -> frozenset[tuple[int, ...]]:
    return frozenset(value)


def _values(value: Mapping[str, float]) -> dict[str, float]:
    return dict(value)


@frozen(kw_only=True)
class URC:
    """An uncertainty reduction controller: observation valuation -> service decisions."""

    observation: tuple[str, ...] = field(converter=tuple[str, ...])
    services: tuple[Service, ...] = field(converter=tuple[Service, ...])
    table: Mapping[tuple[int, ...], Mapping[str, int]] = field(converter=_table)
    left_out: frozenset[tuple[int, ...]] = field(factory=frozenset, converter=_valuations)
    policy: str = ""
    values: Mapping[str, float] = field(factory=dict, converter=_values)
    source: str = ""

    def decide(self, observation: Mapping[str, int] | Sequence[int]) -> dict[str, int]:
        """The decision (value per service constant) for an observation: a mapping of the
        observation variables, or their values in the order of ``self.observation``."""
        valuation = self._valuation(observation)
        if valuation in self.table:
            return dict(self.table[valuation])
        shown = ", ".join(f"{n}={v}" for n, v in zip(self.observation, valuation))
        if valuation in self.left_out:
            raise ObservationError(
                f"observation {shown}: the model says no service is ever consulted there, so the controller has no "
                "decision; check the system against the model"
            )
        raise ObservationError(
            f"observation {shown} is outside the domain the controller was synthesized for; "
            "check the sensor or synthesize for a larger domain"
        )

    def _valuation(self, observation) -> tuple[int, ...]:
        if isinstance(observation, Mapping):
            missing = [n for n in self.observation if n not in observation]
            extra = [n for n in observation if n not in self.observation]
            if missing or extra:
                raise ObservationError(
                    f"observation must give exactly {', '.join(self.observation)}"
                    + (f"; missing {', '.join(missing)}" if missing else "")
                    + (f"; unknown {', '.join(map(str, extra))}" if extra else "")
                )
            values = [observation[n] for n in self.observation]
        else:
            values = list(observation)
            if len(values) != len(self.observation):
                raise ObservationError(
                    f"observation must give {len(self.observation)} values ({', '.join(self.observation)})"
                )
        result = []
        for name, value in zip(self.observation, values):
            if isinstance(value, bool):
                value = int(value)
            if not isinstance(value, int) and not (isinstance(value, float) and value.is_integer()):
                raise ObservationError(f"observation {name}={value!r} is not an integer")
            result.append(int(value))
        return tuple(result)

    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "policy": self.policy,
            "values": dict(self.values),
            "observation": list(self.observation),
            "services": [service.to_json() for service in self.services],
            "decisions": [{"observation": list(v), "decision": dict(d)} for v, d in sorted(self.table.items())],
            "left_out": [list(v) for v in sorted(self.left_out)],
            "source": self.source,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any], source: str = "") -> URC:
        """The URC of :meth:`to_json`'s document; KeyError, TypeError or ValueError if malformed."""
        observation = [str(n) for n in data["observation"]]
        services = [Service.from_json(s) for s in data["services"]]
        constants = [s.constant for s in services]
        table = {}
        for entry in data["decisions"]:
            valuation = tuple(int(v) for v in entry["observation"])
            decision = {str(k): int(v) for k, v in entry["decision"].items()}
            if len(valuation) != len(observation) or sorted(decision) != sorted(constants):
                raise ValueError(f"decision {entry} does not fit the observation and services")
            table[valuation] = decision
        return cls(
            observation=observation,
            services=services,
            table=table,
            left_out=[tuple(int(v) for v in row) for row in data.get("left_out", [])],
            policy=str(data.get("policy", "")),
            values={str(k): float(v) for k, v in data.get("values", {}).items()},
            source=str(data.get("source", "")) or source,
        )

    def save(self, path: Path | str) -> None:
        Path(path).write_text(json.dumps(self.to_json(), indent=2) + "\n")

    @classmethod
    def load(cls, path: Path | str) -> URC:
        path = Path(path)
        return cls.from_document(read_document(path, "give a file written by `parley select`"), path)

    @classmethod
    def from_document(cls, data: Mapping[str, Any], path: Path) -> URC:
        """The URC of a controller file's document (:func:`read_document`), or PolicyError."""
        if data.get("format") != FORMAT:
            raise PolicyError(
                f"controller file {path} is not a parley controller ({FORMAT}); give a file written by `parley select`"
            )
        try:
            return cls.from_json(data, source=str(path))
        except (KeyError, TypeError, ValueError, ParleyError) as exc:
            raise PolicyError(f"controller file {path} is malformed ({exc}); write it with `parley select`") from None


def read_document(path: Path, hint: str) -> dict[str, Any]:
    """A controller file's JSON object, or PolicyError saying what is wrong (``hint``: what to give)."""
    text = read_text(path, "controller file", hint, PolicyError)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise PolicyError(f"controller file {path} is not JSON ({exc.msg}, line {exc.lineno}); {hint}") from None
    if not isinstance(data, dict):
        raise PolicyError(f"controller file {path} holds no JSON object; {hint}")
    return data
