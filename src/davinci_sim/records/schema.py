"""The trainee records' SQLite schema and its migrations.

The schema's version is SQLite's ``PRAGMA user_version`` (0 for a new, empty file). Opening
a file applies, in order, every migration of :data:`MIGRATIONS` above its version, each in
its own transaction that also sets the new version, so a file is always at one version of
the list, never between two. A file of a version this code does not know (written by a
newer davinci-sim) is refused, not changed.

Version 1 — trainees, sessions, attempts and their metrics:

* ``trainees(id, name UNIQUE, created_at)``;
* ``sessions(id, trainee_id, started_at, ended_at, software_version, host, source)``: one
  sitting at the console (a ``serve`` run, a page's trainee); ``ended_at`` is NULL while it
  runs, or when the process stopped without ending it;
* ``attempts(id, session_id, task, kind, condition, settings, repetition, started_at,
  ended_at, finished)``: one repetition of a task; ``condition`` the session's label of the
  condition, ``settings`` the condition's fixture entry as JSON (``{}`` when unknown);
* ``metrics(attempt_id, name, value, unit)``: one row per metric of an attempt, stored
  generically so any task kind's declared metrics fit (``value`` NULL for NaN: not
  measured; ``unit`` the declared SI unit, NULL if not declared).

Version 2 — scores:

* ``metrics.better``: ``lower``, ``higher`` or ``neither`` (the declaration's direction),
  NULL when not declared;
* ``metrics.pass_mark``: the mark the metric was judged against in this attempt (the
  programme's, or the expert reference's mean + 1 SD), in the metric's unit; NULL when it
  had none (the history keeps the mark of its day when a programme changes it);
* ``scores(attempt_id, score, passed, pass_mark)``: the attempt's overall score (%),
  whether it passed, and the score it had to reach (each NULL when not known).

Times are ISO 8601 text in UTC (``2026-11-23T15:02:03.123+00:00``).
"""

from __future__ import annotations

import sqlite3

#: The migrations, in order: migration i (0-based) takes a file from version i to i + 1.
MIGRATIONS: tuple[str, ...] = (
    # 1: trainees, sessions, attempts, metrics.
    """
    CREATE TABLE trainees (
        id INTEGER PRIMARY KEY,
        name TEXT NOT NULL UNIQUE,
        created_at TEXT NOT NULL
    );
    CREATE TABLE sessions (
        id INTEGER PRIMARY KEY,
        trainee_id INTEGER NOT NULL REFERENCES trainees(id),
        started_at TEXT NOT NULL,
        ended_at TEXT,
        software_version TEXT NOT NULL,
        host TEXT NOT NULL,
        source TEXT NOT NULL DEFAULT ''
    );
    CREATE INDEX sessions_trainee ON sessions(trainee_id);
    CREATE TABLE attempts (
        id INTEGER PRIMARY KEY,
        session_id INTEGER NOT NULL REFERENCES sessions(id),
        task TEXT NOT NULL,
        kind TEXT,
        condition TEXT NOT NULL DEFAULT '',
        settings TEXT NOT NULL DEFAULT '{}',
        repetition INTEGER,
        started_at TEXT,
        ended_at TEXT NOT NULL,
        finished INTEGER NOT NULL DEFAULT 1
    );
    CREATE INDEX attempts_session ON attempts(session_id);
    CREATE TABLE metrics (
        attempt_id INTEGER NOT NULL REFERENCES attempts(id) ON DELETE CASCADE,
        name TEXT NOT NULL,
        value REAL,
        unit TEXT,
        PRIMARY KEY (attempt_id, name)
    );
    """,
    # 2: the metrics' better direction; the attempts' scores.
    """
    ALTER TABLE metrics ADD COLUMN better TEXT;
    ALTER TABLE metrics ADD COLUMN pass_mark REAL;
    CREATE TABLE scores (
        attempt_id INTEGER PRIMARY KEY REFERENCES attempts(id) ON DELETE CASCADE,
        score REAL,
        passed INTEGER,
        pass_mark REAL
    );
    """,
)

#: The version a file has once opened by this code.
SCHEMA_VERSION = len(MIGRATIONS)


class SchemaError(RuntimeError):
    """A records file this code cannot use (a newer schema version)."""


def version_of(conn: sqlite3.Connection) -> int:
    """The file's schema version (``PRAGMA user_version``)."""
    return int(conn.execute("PRAGMA user_version").fetchone()[0])


def migrate(conn: sqlite3.Connection, target: int = SCHEMA_VERSION) -> list[int]:
    """Apply the migrations from the file's version up to ``target``; returns the versions
    reached, in order (empty: already there). ``conn`` must be in autocommit mode
    (``isolation_level=None``): each migration is one explicit transaction.

    Raises:
        SchemaError: the file is at a version above ``target`` (a newer schema).
    """
    if not 0 <= target <= len(MIGRATIONS):
        raise ValueError(f"no schema version {target}; versions 0..{len(MIGRATIONS)}")
    applied = []
    # BEGIN IMMEDIATE takes the write lock first, so two processes opening a new file do not
    # both migrate it: the second one sees the first one's version once it gets the lock.
    while True:
        conn.execute("BEGIN IMMEDIATE")
        try:
            current = version_of(conn)
            if current > target:
                raise SchemaError(
                    f"records schema version {current} is newer than this davinci-sim's "
                    f"({target}); use a newer davinci-sim"
                )
            if current == target:
                conn.execute("COMMIT")
                return applied
            for statement in _statements(MIGRATIONS[current]):
                conn.execute(statement)
            conn.execute(f"PRAGMA user_version = {current + 1}")
            conn.execute("COMMIT")
        except BaseException:
            conn.execute("ROLLBACK")
            raise
        applied.append(current + 1)


def _statements(script: str) -> list[str]:
    """The statements of a migration script (``;``-separated; the scripts have no ``;`` in
    literals). ``executescript`` would commit the open transaction first, so each statement
    runs on its own inside the migration's transaction."""
    return [s.strip() for s in script.split(";") if s.strip()]
