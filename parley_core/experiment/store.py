"""The results store of campaigns: one SQLite file, one row per finished run.

Each run is written in one transaction, under a unique (campaign, instance, repetition) key,
so a campaign killed at any moment keeps every finished run exactly once and a restart
skips them. A campaign's settings are recorded when it starts; resuming it with other
settings is refused.
"""

from __future__ import annotations

import contextlib
import json
import sqlite3
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from attrs import field, frozen

from parley_core.errors import OptionError, OutputError
from parley_core.model import Objective, Policy, Valued
from parley_core.verify import Verification

SCHEMA = """
CREATE TABLE IF NOT EXISTS campaigns (
    name TEXT PRIMARY KEY,
    case_study TEXT NOT NULL,
    settings TEXT NOT NULL,
    created REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS runs (
    campaign TEXT NOT NULL REFERENCES campaigns(name),
    instance TEXT NOT NULL,
    repetition INTEGER NOT NULL,
    seed INTEGER NOT NULL,
    options TEXT NOT NULL,
    objectives TEXT NOT NULL,
    front TEXT NOT NULL,
    baseline TEXT NOT NULL,
    summary TEXT NOT NULL,
    finished REAL NOT NULL,
    PRIMARY KEY (campaign, instance, repetition)
);
CREATE TABLE IF NOT EXISTS bounds (
    campaign TEXT NOT NULL REFERENCES campaigns(name),
    instance TEXT NOT NULL,
    method TEXT NOT NULL,
    points TEXT NOT NULL,
    seconds REAL NOT NULL,
    PRIMARY KEY (campaign, instance)
);
CREATE TABLE IF NOT EXISTS answers (
    campaign TEXT NOT NULL REFERENCES campaigns(name),
    instance TEXT NOT NULL,
    setting TEXT NOT NULL,
    answer TEXT NOT NULL,
    detail TEXT NOT NULL,
    PRIMARY KEY (campaign, instance, setting)
);
"""


@frozen(kw_only=True)
class RunRecord:
    """One finished run: its front and baseline values, and what produced them."""

    campaign: str
    instance: str
    repetition: int
    seed: int
    options: dict[str, Any]
    """The case study's options in JSON form (:func:`parley_core.plugin.options.options_as_dict`)."""
    objectives: tuple[Objective, ...] = field(converter=tuple[Objective, ...])
    front: Valued
    """The front's policies (decision values; named p1, p2, ... in stored order) and values."""
    baseline: Valued
    """The baselines by name with their values (their decision values are not stored)."""
    summary: dict[str, Any]
    """evaluations, timings, verification, quotient size... (JSON-friendly)"""

    @property
    def verification(self) -> Verification | None:
        data = self.summary.get("verification")
        return Verification.from_json(data) if data else None

    @property
    def verified(self) -> bool:
        """Whether Storm vouches for the front's values."""
        verification = self.verification
        return verification is not None and verification.by.by_storm

    def values(self) -> tuple[np.ndarray, np.ndarray]:
        """The front's and the baseline's values as arrays [points, objectives]."""
        n = len(self.objectives)
        return (
            np.array(self.front.values, dtype=float).reshape(-1, n),
            np.array(self.baseline.values, dtype=float).reshape(-1, n),
        )

    def front_json(self) -> dict[str, Any]:
        return {
            "policies": [list(p.values) for p in self.front.policies],
            "values": [list(v) for v in self.front.values],
        }

    def baseline_json(self) -> dict[str, Any]:
        return {"names": [p.name for p in self.baseline.policies], "values": [list(v) for v in self.baseline.values]}


def front_from_json(objectives: tuple[Objective, ...], data: dict[str, Any]) -> Valued:
    return Valued(
        objectives=objectives,
        policies=[Policy(name=f"p{i + 1}", values=p) for i, p in enumerate(data["policies"])],
        values=data["values"],
    )


def baseline_from_json(objectives: tuple[Objective, ...], data: dict[str, Any]) -> Valued:
    return Valued(
        objectives=objectives, policies=[Policy(name=n, values=()) for n in data["names"]], values=data["values"]
    )


class Store:
    """A campaign results file. Use as a context manager, or call close()."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        if self.path.exists() and not self.path.is_file():
            raise OutputError(f"store {self.path} is not a file; give a path for the SQLite results file")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self.connection = sqlite3.connect(self.path, timeout=60, isolation_level=None)
            self.connection.execute("PRAGMA journal_mode=WAL")
            self.connection.execute("PRAGMA synchronous=FULL")
            self.connection.executescript(SCHEMA)
        except sqlite3.DatabaseError as exc:
            raise OutputError(f"store {self.path} cannot be used as a SQLite results file ({exc})") from None

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.connection.close()

    @contextlib.contextmanager
    def _transaction(self) -> Iterator[None]:
        """One immediate transaction: committed whole, or rolled back (also on KeyboardInterrupt)."""
        self.connection.execute("BEGIN IMMEDIATE")
        try:
            yield
        except BaseException:
            if self.connection.in_transaction:
                self.connection.execute("ROLLBACK")
            raise
        self.connection.execute("COMMIT")

    def begin_campaign(self, name: str, case_study: str, settings: dict[str, Any]) -> None:
        """Record a campaign, or check that a recorded one has the same case study and settings."""
        row = self.connection.execute("SELECT case_study, settings FROM campaigns WHERE name = ?", (name,)).fetchone()
        text = json.dumps(settings, sort_keys=True)
        if row is None:
            self.connection.execute(
                "INSERT INTO campaigns (name, case_study, settings, created) VALUES (?, ?, ?, ?)",
                (name, case_study, text, time.time()),
            )
            return
        if row[0] != case_study or row[1] != text:
            raise OutputError(
                f"store {self.path} already holds campaign {name!r} with other settings ({row[0]}: {row[1]}); "
                "rerun with the same settings to resume it, or give another --name or --store"
            )

    def campaigns(self) -> list[tuple[str, str, dict[str, Any]]]:
        rows = self.connection.execute("SELECT name, case_study, settings FROM campaigns ORDER BY created").fetchall()
        return [(name, case, json.loads(settings)) for name, case, settings in rows]

    def campaign(self, name: str | None = None) -> tuple[str, str, dict[str, Any]]:
        """(name, case study, settings) of the named campaign, or of the store's only one."""
        campaigns = self.campaigns()
        if not campaigns:
            raise OptionError(f"store {self.path} holds no campaign")
        names = [c[0] for c in campaigns]
        chosen = name or (names[0] if len(names) == 1 else None)
        if chosen not in names:
            raise OptionError(f"give --name: store {self.path} holds campaigns {', '.join(names)}")
        return next(c for c in campaigns if c[0] == chosen)

    def done(self, campaign: str) -> set[tuple[str, int]]:
        rows = self.connection.execute("SELECT instance, repetition FROM runs WHERE campaign = ?", (campaign,))
        return {(instance, repetition) for instance, repetition in rows}

    def add(self, record: RunRecord) -> bool:
        """Store a finished run in one transaction; False if that run was stored already."""
        with self._transaction():
            cursor = self.connection.execute(
                "INSERT OR IGNORE INTO runs "
                "(campaign, instance, repetition, seed, options, objectives, front, baseline, summary, finished) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    record.campaign,
                    record.instance,
                    record.repetition,
                    record.seed,
                    json.dumps(record.options),
                    json.dumps([o.to_json() for o in record.objectives]),
                    json.dumps(record.front_json()),
                    json.dumps(record.baseline_json()),
                    json.dumps(record.summary),
                    time.time(),
                ),
            )
        return cursor.rowcount == 1

    def runs(self, campaign: str | None = None) -> Iterator[RunRecord]:
        query = "SELECT campaign, instance, repetition, seed, options, objectives, front, baseline, summary FROM runs"
        args: tuple = ()
        if campaign is not None:
            query += " WHERE campaign = ?"
            args = (campaign,)
        for row in self.connection.execute(query + " ORDER BY campaign, instance, repetition", args):
            objectives = tuple(Objective.from_json(o) for o in json.loads(row[5]))
            yield RunRecord(
                campaign=row[0],
                instance=row[1],
                repetition=row[2],
                seed=row[3],
                options=json.loads(row[4]),
                objectives=objectives,
                front=front_from_json(objectives, json.loads(row[6])),
                baseline=baseline_from_json(objectives, json.loads(row[7])),
                summary=json.loads(row[8]),
            )

    def add_bound(self, campaign: str, instance: str, method: str, points: np.ndarray, seconds: float) -> None:
        """Store an instance's certified outer bound (every policy of its family is weakly
        dominated by one of ``points``), replacing an earlier one."""
        rows = [[float(v) for v in row] for row in np.asarray(points, dtype=float)]
        with self._transaction():
            self.connection.execute(
                "INSERT OR REPLACE INTO bounds (campaign, instance, method, points, seconds) VALUES (?, ?, ?, ?, ?)",
                (campaign, instance, method, json.dumps(rows), seconds),
            )

    def add_answer(self, campaign: str, instance: str, setting, detail: dict[str, Any]) -> None:
        """Store a cell's requirement answer (:mod:`parley_core.experiment.answers`): ``detail``
        holds ``answer`` ("feasible", "infeasible" or "unknown") and how it was reached."""
        with self._transaction():
            self.connection.execute(
                "INSERT OR REPLACE INTO answers (campaign, instance, setting, answer, detail) VALUES (?, ?, ?, ?, ?)",
                (campaign, instance, json.dumps([float(b) for b in setting]), detail["answer"], json.dumps(detail)),
            )

    def answers(self, campaign: str) -> dict[tuple[str, tuple[float, ...]], dict[str, Any]]:
        """The stored answers of a campaign's cells, by (instance, setting)."""
        rows = self.connection.execute("SELECT instance, setting, detail FROM answers WHERE campaign = ?", (campaign,))
        return {(i, tuple(float(b) for b in json.loads(s))): json.loads(d) for i, s, d in rows}

    def bounds(self, campaign: str) -> dict[str, np.ndarray]:
        """The stored bounds of a campaign's instances (points, one row per point)."""
        rows = self.connection.execute("SELECT instance, points FROM bounds WHERE campaign = ?", (campaign,))
        return {instance: np.array(json.loads(points), dtype=float) for instance, points in rows}

    def replace_front(self, record: RunRecord) -> None:
        """Replace a stored run's front and summary (after verification), in one transaction."""
        with self._transaction():
            self.connection.execute(
                "UPDATE runs SET front = ?, summary = ? WHERE campaign = ? AND instance = ? AND repetition = ?",
                (
                    json.dumps(record.front_json()),
                    json.dumps(record.summary),
                    record.campaign,
                    record.instance,
                    record.repetition,
                ),
            )
