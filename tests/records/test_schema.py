"""The records file's schema: created from an empty file, migrated from version 1, a newer
version or a file that is not a database refused without being changed."""

from __future__ import annotations

import sqlite3

import pytest

from davinci_sim.records import MIGRATIONS, SCHEMA_VERSION, MetricInfo, RecordsDB, RecordsError
from davinci_sim.records.schema import migrate, version_of


def tables(path) -> dict[str, list[str]]:
    conn = sqlite3.connect(path)
    names = [r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
    out = {n: [c[1] for c in conn.execute(f"PRAGMA table_info({n})")] for n in names}
    conn.close()
    return out


def test_an_empty_file_gets_every_migration(tmp_path):
    path = tmp_path / "records.sqlite3"
    path.touch()  # an empty file is a new database to SQLite
    with RecordsDB(path) as db:
        assert db.version == SCHEMA_VERSION == len(MIGRATIONS) == 2
        assert db.conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    t = tables(path)
    assert set(t) == {"trainees", "sessions", "attempts", "metrics", "scores"}
    assert t["metrics"] == ["attempt_id", "name", "value", "unit", "better", "pass_mark"]
    assert t["scores"] == ["attempt_id", "score", "passed", "pass_mark"]
    assert {"software_version", "host", "started_at", "ended_at"} <= set(t["sessions"])
    assert {"settings", "condition", "repetition", "finished", "kind"} <= set(t["attempts"])


def test_a_missing_file_and_its_folders_are_created(tmp_path):
    path = tmp_path / "a" / "b" / "records.sqlite3"
    RecordsDB(path).close()
    assert path.exists()
    with pytest.raises(RecordsError, match="no records file"):
        RecordsDB(tmp_path / "other.sqlite3", create=False)
    assert not (tmp_path / "other.sqlite3").exists()


def version_1_file(path) -> None:
    """A file as davinci-sim wrote it at schema version 1, with one attempt."""
    conn = sqlite3.connect(path, isolation_level=None)
    assert migrate(conn, 1) == [1]
    conn.execute("INSERT INTO trainees (name, created_at) VALUES ('ana', '2026-01-01T00:00Z')")
    conn.execute("INSERT INTO sessions (trainee_id, started_at, software_version, host) "
                 "VALUES (1, '2026-01-01T00:00Z', '0.0.9', 'h')")  # fmt: skip
    conn.execute("INSERT INTO attempts (session_id, task, repetition, ended_at) "
                 "VALUES (1, 'seed_path', 1, '2026-01-01T00:01Z')")  # fmt: skip
    conn.execute("INSERT INTO metrics VALUES (1, 'deviation_error', 0.002, 'm')")
    conn.close()


def test_a_version_1_file_is_migrated_and_keeps_its_rows(tmp_path):
    path = tmp_path / "v1.sqlite3"
    version_1_file(path)
    conn = sqlite3.connect(path)
    assert version_of(conn) == 1 and "scores" not in tables(path)
    conn.close()
    with RecordsDB(path) as db:
        (a,) = db.attempts("ana")
        assert a["metrics"] == {"deviation_error": (0.002, "m", None)}  # no direction in v1
        assert a["score"] is None and a["passed"] is None and a["pass_marks"] == {}
        assert a["software_version"] == "0.0.9"
        # and the migrated file takes version 2's rows
        s = db.start_session("ana")
        db.record_attempt(s, task="seed_path", metrics={"deviation_error": 0.001},
                          info={"deviation_error": MetricInfo("m", "lower")})  # fmt: skip
        assert db.attempts("ana")[1]["metrics"]["deviation_error"] == (0.001, "m", "lower")
    conn = sqlite3.connect(path)
    assert version_of(conn) == 2
    conn.close()


def test_reopening_applies_nothing(tmp_path):
    path = tmp_path / "r.sqlite3"
    RecordsDB(path).close()
    conn = sqlite3.connect(path, isolation_level=None)
    assert migrate(conn) == []
    conn.close()


def test_a_newer_file_is_refused_and_left_as_it_is(tmp_path):
    path = tmp_path / "new.sqlite3"
    conn = sqlite3.connect(path)
    conn.execute("CREATE TABLE future (x)")
    conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION + 1}")
    conn.commit()
    conn.close()
    before = path.read_bytes()
    with pytest.raises(RecordsError, match="newer"):
        RecordsDB(path)
    assert set(tables(path)) == {"future"} and path.read_bytes() == before


def test_a_file_that_is_not_a_database_is_refused(tmp_path):
    path = tmp_path / "notes.sqlite3"
    path.write_text("not a database, just notes\n" * 100)
    with pytest.raises(RecordsError, match="not a usable records file"):
        RecordsDB(path)
    assert path.read_text().startswith("not a database")


def test_a_failing_migration_leaves_the_file_at_its_version(tmp_path, monkeypatch):
    import davinci_sim.records.schema as schema

    path = tmp_path / "v1.sqlite3"
    version_1_file(path)
    broken = (MIGRATIONS[0], MIGRATIONS[1] + "; CREATE TABLE trainees (x)")  # (exists: fails)
    monkeypatch.setattr(schema, "MIGRATIONS", broken)
    conn = sqlite3.connect(path, isolation_level=None)
    with pytest.raises(sqlite3.OperationalError):
        schema.migrate(conn, 2)
    assert version_of(conn) == 1
    assert [c[1] for c in conn.execute("PRAGMA table_info(metrics)")] == [
        "attempt_id", "name", "value", "unit"]  # (the ALTER was rolled back)  # fmt: skip
    conn.close()
