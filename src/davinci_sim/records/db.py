"""The trainee records database: a local SQLite file through the standard library.

:class:`RecordsDB` opens (creating it if needed) a records file, brings its schema up to
date (:mod:`davinci_sim.records.schema`), and writes and reads trainees, sessions, attempts,
their metrics and scores.

**Durability.** The file is in WAL mode with ``synchronous=FULL``, and
:meth:`RecordsDB.record_attempt` writes an attempt, its metrics and its score in one
transaction committed before it returns: once it has returned, the attempt survives the
process being killed (and, with FULL, the machine losing power); an attempt being written
when the process dies is either all there or not there at all.

**Where.** :func:`default_path`: ``$DAVINCI_SIM_RECORDS`` if set, else
``$XDG_DATA_HOME/davinci-sim/records.sqlite3``, else
``~/.local/share/davinci-sim/records.sqlite3`` (the XDG base directory specification's
default for per-user data).
"""

from __future__ import annotations

import json
import math
import os
import socket
import sqlite3
import threading
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from davinci_sim.records.schema import SCHEMA_VERSION, SchemaError, migrate, version_of

#: Environment variable naming the records file (overrides the per-user default).
ENV_VAR = "DAVINCI_SIM_RECORDS"
#: How long a write waits for another process's lock before it fails, ms.
BUSY_TIMEOUT_MS = 2000


class RecordsError(ValueError):
    """Bad input to the records (unknown trainee, bad name, unusable file)."""


def default_path(environ: Mapping[str, str] | None = None) -> Path:
    """The records file: ``$DAVINCI_SIM_RECORDS``, else under ``$XDG_DATA_HOME``, else under
    ``~/.local/share`` (see the module docstring)."""
    env = os.environ if environ is None else environ
    if env.get(ENV_VAR):
        return Path(env[ENV_VAR]).expanduser()
    base = env.get("XDG_DATA_HOME")
    root = Path(base) if base and Path(base).is_absolute() else Path.home() / ".local" / "share"
    return root / "davinci-sim" / "records.sqlite3"


def software_version() -> str:
    """This davinci-sim's version (the installed package's metadata, else the module's)."""
    try:
        from importlib.metadata import PackageNotFoundError, version

        return version("davinci-sim")
    except (ImportError, PackageNotFoundError):
        import davinci_sim

        return davinci_sim.__version__


def now() -> str:
    """The wall-clock time now, ISO 8601 in UTC (ms)."""
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def check_name(name: object) -> str:
    """A trainee's name, stripped: 1-100 printable characters.

    Raises:
        RecordsError: an empty, too long or non-printable name.
    """
    if not isinstance(name, str) or not name.strip():
        raise RecordsError("a trainee's name must be a non-empty text")
    name = name.strip()
    if len(name) > 100 or not name.isprintable():
        raise RecordsError(f"a trainee's name must be 1-100 printable characters, got {name!r}")
    return name


@dataclass(frozen=True)
class MetricInfo:
    """What the records keep of a metric's declaration (a task's ``METRICS`` entry)."""

    unit: str | None = None
    better: str | None = None
    """``lower``, ``higher``, ``neither`` or None (not declared)."""


@dataclass(frozen=True)
class Score:
    """An attempt's overall score (each field None when not known)."""

    score: float | None = None
    passed: bool | None = None
    pass_mark: float | None = None


def _number(value: object) -> float | None:
    """A metric's value as stored: a finite float, else None (NULL: not measured)."""
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, int | float):
        v = float(value)
        return v if math.isfinite(v) else None
    try:  # numpy scalars
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


class RecordsDB:
    """One records file, open; see the module docstring.

    Args:
        path: the file (created with its folders if missing); None: :func:`default_path`.
        create: create the file if it does not exist (False: a missing file is an error,
            for the read-only commands).

    Raises:
        RecordsError: the file cannot be opened or created, is not a records database, or
            has a newer schema.

    One connection, usable from any thread (calls are serialized by a lock).
    """

    def __init__(self, path: str | Path | None = None, *, create: bool = True) -> None:
        self.path = Path(path) if path is not None else default_path()
        if not create and not self.path.exists():
            raise RecordsError(f"no records file {self.path}")
        self._lock = threading.Lock()
        try:
            if create:
                self.path.parent.mkdir(parents=True, exist_ok=True)
            conn = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False,
                                   timeout=BUSY_TIMEOUT_MS / 1000)  # fmt: skip
        except (OSError, sqlite3.Error) as e:
            raise RecordsError(f"cannot open the records file {self.path}: {e}") from e
        try:
            conn.execute(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
            if version_of(conn) > SCHEMA_VERSION:  # before anything changes the file
                migrate(conn)  # (raises SchemaError)
            conn.execute("PRAGMA journal_mode = WAL")
            conn.execute("PRAGMA synchronous = FULL")
            conn.execute("PRAGMA foreign_keys = ON")
            migrate(conn)
        except SchemaError as e:
            conn.close()
            raise RecordsError(f"{self.path}: {e}") from e
        except sqlite3.Error as e:
            conn.close()
            raise RecordsError(f"{self.path} is not a usable records file: {e}") from e
        self.conn = conn

    def close(self) -> None:
        with self._lock:
            self.conn.close()

    def __enter__(self) -> RecordsDB:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def version(self) -> int:
        return SCHEMA_VERSION

    # ------------------------------------------------------------ writing
    def _write(self, statements) -> object:
        """Run ``statements(conn)`` in one transaction (BEGIN IMMEDIATE … COMMIT)."""
        with self._lock:
            self.conn.execute("BEGIN IMMEDIATE")
            try:
                result = statements(self.conn)
                self.conn.execute("COMMIT")
            except BaseException:
                self.conn.execute("ROLLBACK")
                raise
            return result

    def trainee_id(self, name: str, *, create: bool = True) -> int:
        """The id of trainee ``name`` (created if ``create`` and new).

        Raises:
            RecordsError: a bad name, or an unknown trainee with ``create`` False.
        """
        name = check_name(name)
        row = self._one("SELECT id FROM trainees WHERE name = ?", (name,))
        if row is not None:
            return int(row[0])
        if not create:
            raise RecordsError(f"no trainee {name!r} in {self.path}")

        def add(conn):
            conn.execute("INSERT OR IGNORE INTO trainees (name, created_at) VALUES (?, ?)",
                         (name, now()))  # fmt: skip
            return conn.execute("SELECT id FROM trainees WHERE name = ?", (name,)).fetchone()[0]

        return int(self._write(add))

    def start_session(
        self,
        trainee: str,
        *,
        source: str = "",
        version: str | None = None,
        host: str | None = None,
        started_at: str | None = None,
    ) -> int:
        """A new session of ``trainee`` (created if new); returns its id."""
        trainee_id = self.trainee_id(trainee)
        values = (trainee_id, started_at or now(), version or software_version(),
                  host or socket.gethostname(), source)  # fmt: skip
        return int(
            self._write(
                lambda conn: (
                    conn.execute(
                        "INSERT INTO sessions (trainee_id, started_at, software_version, host, "
                        "source) VALUES (?, ?, ?, ?, ?)",
                        values,
                    ).lastrowid
                )
            )
        )

    def end_session(self, session_id: int, ended_at: str | None = None) -> None:
        self._write(
            lambda conn: conn.execute(
                "UPDATE sessions SET ended_at = ? WHERE id = ?", (ended_at or now(), session_id)
            )
        )

    def record_attempt(
        self,
        session_id: int,
        *,
        task: str,
        metrics: Mapping[str, object],
        kind: str | None = None,
        condition: str = "",
        settings: Mapping | None = None,
        repetition: int | None = None,
        started_at: str | None = None,
        ended_at: str | None = None,
        finished: bool = True,
        info: Mapping[str, MetricInfo] | None = None,
        score: Score | None = None,
        pass_marks: Mapping[str, float] | None = None,
    ) -> int:
        """Write one attempt with its metrics (name → value; ``info`` gives units and
        directions, ``pass_marks`` the marks they were judged against) and its score, in
        one committed transaction; returns the attempt's id. Non-numeric metric values are
        not metrics and are left out; NaN is stored as NULL.
        """
        info = info or {}
        marks = pass_marks or {}
        settings_text = json.dumps(dict(settings or {}), sort_keys=True, default=str)
        ended = ended_at or now()

        def write(conn) -> int:
            attempt = conn.execute(
                "INSERT INTO attempts (session_id, task, kind, condition, settings, repetition, "
                "started_at, ended_at, finished) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (session_id, task, kind, condition, settings_text, repetition, started_at,
                 ended, int(bool(finished))),
            ).lastrowid  # fmt: skip
            rows = []
            for name, value in metrics.items():
                if isinstance(value, str | bytes) or value is None and name not in info:
                    continue
                meta = info.get(name, MetricInfo())
                mark = _number(marks.get(name))
                rows.append((attempt, str(name), _number(value), meta.unit, meta.better, mark))
            conn.executemany(
                "INSERT INTO metrics (attempt_id, name, value, unit, better, pass_mark) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                rows,
            )
            if score is not None:
                passed = None if score.passed is None else int(bool(score.passed))
                conn.execute(
                    "INSERT INTO scores (attempt_id, score, passed, pass_mark) VALUES (?, ?, ?, ?)",
                    (attempt, _number(score.score), passed, _number(score.pass_mark)),
                )
            return int(attempt)

        return self._write(write)

    # ------------------------------------------------------------ reading
    def _one(self, sql: str, params: Iterable = ()):
        with self._lock:
            return self.conn.execute(sql, tuple(params)).fetchone()

    def _all(self, sql: str, params: Iterable = ()) -> list[sqlite3.Row]:
        with self._lock:
            cursor = self.conn.execute(sql, tuple(params))
            names = [d[0] for d in cursor.description]
            return [dict(zip(names, row, strict=True)) for row in cursor.fetchall()]

    def trainees(self) -> list[dict]:
        """Every trainee: name, created_at, sessions, attempts, last (latest attempt's end)."""
        return self._all(
            "SELECT t.name, t.created_at, COUNT(DISTINCT s.id) AS sessions, "
            "COUNT(a.id) AS attempts, MAX(a.ended_at) AS last FROM trainees t "
            "LEFT JOIN sessions s ON s.trainee_id = t.id "
            "LEFT JOIN attempts a ON a.session_id = s.id GROUP BY t.id ORDER BY t.name"
        )

    def sessions(self, trainee: str) -> list[dict]:
        """``trainee``'s sessions in order, with their number of attempts.

        Raises:
            RecordsError: an unknown trainee.
        """
        tid = self.trainee_id(trainee, create=False)
        return self._all(
            "SELECT s.id, s.started_at, s.ended_at, s.software_version, s.host, s.source, "
            "COUNT(a.id) AS attempts FROM sessions s LEFT JOIN attempts a ON a.session_id = s.id "
            "WHERE s.trainee_id = ? GROUP BY s.id ORDER BY s.id",
            (tid,),
        )

    def attempts(self, trainee: str | None = None, *, task: str | None = None) -> list[dict]:
        """Attempts in the order they were recorded (of ``trainee`` and ``task`` if given):
        each a dict of the attempt's columns, ``trainee``, ``session``,
        ``software_version``, ``host``, ``score``/``passed``/``pass_mark`` (None when not
        scored), ``metrics`` (name → (value, unit, better), in recorded order) and
        ``pass_marks`` (name → the metric's pass mark in that attempt, where it had one).

        Raises:
            RecordsError: an unknown trainee.
        """
        where, params = [], []
        if trainee is not None:
            where.append("s.trainee_id = ?")
            params.append(self.trainee_id(trainee, create=False))
        if task is not None:
            where.append("a.task = ?")
            params.append(task)
        rows = self._all(
            "SELECT a.id, t.name AS trainee, a.session_id AS session, a.task, a.kind, "
            "a.condition, a.settings, a.repetition, a.started_at, a.ended_at, a.finished, "
            "s.software_version, s.host, sc.score, sc.passed, sc.pass_mark "
            "FROM attempts a JOIN sessions s ON s.id = a.session_id "
            "JOIN trainees t ON t.id = s.trainee_id LEFT JOIN scores sc ON sc.attempt_id = a.id"
            + (" WHERE " + " AND ".join(where) if where else "")
            + " ORDER BY a.id",
            params,
        )
        metrics: dict[int, dict] = {r["id"]: {} for r in rows}
        marks: dict[int, dict] = {r["id"]: {} for r in rows}
        if rows:
            for m in self._all(
                "SELECT m.attempt_id, m.name, m.value, m.unit, m.better, m.pass_mark "
                "FROM metrics m "
                "JOIN attempts a ON a.id = m.attempt_id JOIN sessions s ON s.id = a.session_id"
                + (" WHERE " + " AND ".join(where) if where else "")
                + " ORDER BY m.attempt_id, m.rowid",
                params,
            ):
                metrics[m["attempt_id"]][m["name"]] = (m["value"], m["unit"], m["better"])
                if m["pass_mark"] is not None:
                    marks[m["attempt_id"]][m["name"]] = m["pass_mark"]
        for r in rows:
            r["metrics"] = metrics[r["id"]]
            r["pass_marks"] = marks[r["id"]]
            r["finished"] = bool(r["finished"])
            r["passed"] = None if r["passed"] is None else bool(r["passed"])
        return rows

    def integrity(self) -> str:
        """SQLite's ``PRAGMA integrity_check`` (``ok`` for a sound file)."""
        return str(self._one("PRAGMA integrity_check")[0])
