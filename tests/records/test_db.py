"""Writing and reading the records: each attempt committed as it is recorded, all of it or
nothing, metrics stored generically, the default location."""

from __future__ import annotations

import math
import sqlite3
from pathlib import Path

import pytest

from davinci_sim.records import MetricInfo, RecordsDB, RecordsError, Score, default_path
from davinci_sim.records.recorder import metric_info
from davinci_sim.tasks import load_task


@pytest.fixture
def db(tmp_path):
    with RecordsDB(tmp_path / "r.sqlite3") as db:
        yield db


def test_an_attempt_is_committed_when_record_attempt_returns(db):
    s = db.start_session("ana", source="test", version="9.9", host="bench")
    other = sqlite3.connect(db.path)  # another reader sees it at once: it is committed
    assert other.execute("SELECT COUNT(*) FROM attempts").fetchone()[0] == 0
    a = db.record_attempt(s, task="seed_path", kind="path", condition="B=40",
                          settings={"type": "viscous", "B": 40.0, "G_max": 5.0}, repetition=3,
                          metrics={"deviation_error": 0.0021, "clutch_count": 2},
                          info={"deviation_error": MetricInfo("m", "lower")})  # fmt: skip
    assert other.execute("SELECT COUNT(*) FROM attempts").fetchone()[0] == 1
    assert other.execute("SELECT name, value, unit, better FROM metrics WHERE attempt_id = ? "
                         "ORDER BY rowid", (a,)).fetchall() == [
        ("deviation_error", 0.0021, "m", "lower"), ("clutch_count", 2.0, None, None)]  # fmt: skip
    other.close()
    (row,) = db.attempts("ana")
    assert row["trainee"] == "ana" and row["session"] == s and row["repetition"] == 3
    assert row["software_version"] == "9.9" and row["host"] == "bench"
    assert row["condition"] == "B=40" and row["kind"] == "path" and row["finished"] is True
    assert '"G_max": 5.0' in row["settings"]


def test_nan_is_stored_as_not_measured_and_text_is_not_a_metric(db):
    s = db.start_session("ana")
    db.record_attempt(s, task="t", metrics={"a": math.nan, "b": math.inf, "c": "x", "d": True})
    (row,) = db.attempts()
    assert row["metrics"] == {"a": (None, None, None), "b": (None, None, None),
                              "d": (1.0, None, None)}  # fmt: skip


def test_a_score_is_stored_with_its_pass_mark(db):
    s = db.start_session("ana")
    db.record_attempt(s, task="t", metrics={}, score=Score(82.5, True, 70.0))
    db.record_attempt(s, task="t", metrics={}, score=Score(None, None, None))
    db.record_attempt(s, task="t", metrics={})
    rows = db.attempts("ana", task="t")
    assert [(r["score"], r["passed"], r["pass_mark"]) for r in rows] == [
        (82.5, True, 70.0), (None, None, None), (None, None, None)]  # fmt: skip


def test_a_failing_attempt_writes_nothing(db):
    s = db.start_session("ana")
    with pytest.raises(sqlite3.IntegrityError):  # a metric named twice: the key refuses it
        db.record_attempt(s, task="t", metrics=_Twice())
    assert db.attempts() == []
    assert db.conn.execute("SELECT COUNT(*) FROM metrics").fetchone()[0] == 0
    with pytest.raises(sqlite3.IntegrityError):  # no such session
        db.record_attempt(s + 100, task="t", metrics={"a": 1.0})
    assert db.attempts() == []


class _Twice(dict):
    def items(self):
        return [("a", 1.0), ("a", 2.0)]


def test_trainees_and_sessions(db):
    s1 = db.start_session("ana")
    db.record_attempt(s1, task="t", metrics={"a": 1.0})
    db.end_session(s1)
    s2 = db.start_session("ana")
    db.start_session("ben")
    assert [(t["name"], t["sessions"], t["attempts"]) for t in db.trainees()] == [
        ("ana", 2, 1), ("ben", 1, 0)]  # fmt: skip
    sessions = db.sessions("ana")
    assert [s["id"] for s in sessions] == [s1, s2]
    assert sessions[0]["ended_at"] is not None and sessions[1]["ended_at"] is None
    with pytest.raises(RecordsError, match="no trainee 'cy'"):
        db.sessions("cy")
    with pytest.raises(RecordsError, match="no trainee"):
        db.attempts("cy")
    assert [t["name"] for t in db.trainees()] == ["ana", "ben"]  # (asking created nobody)


@pytest.mark.parametrize("name", ["", "   ", "a\nb", "x" * 101, None, 3])
def test_bad_trainee_names_are_refused(db, name):
    with pytest.raises(RecordsError, match="name"):
        db.start_session(name)
    assert db.trainees() == []


def test_the_declared_metrics_give_units_and_directions():
    task = load_task("seed_path")
    info = metric_info(task)
    assert [*info] == [m.name for m in task.METRICS]
    assert info["deviation_error"] == MetricInfo("m", "lower")
    assert info["mean_speed"] == MetricInfo("m/s", "higher")


def test_default_path():
    assert default_path({"DAVINCI_SIM_RECORDS": "/x/r.db"}) == Path("/x/r.db")
    assert default_path({"XDG_DATA_HOME": "/data"}) == Path("/data/davinci-sim/records.sqlite3")
    home = Path.home() / ".local" / "share" / "davinci-sim" / "records.sqlite3"
    assert default_path({}) == home
    assert default_path({"XDG_DATA_HOME": "relative"}) == home  # (the spec ignores it)
