"""``davinci-sim trainees list|show|export|curve``: what a trainer reads of the records, and a
one-line error (exit 2) for bad input."""

from __future__ import annotations

import csv
import io

import pytest
from PIL import Image

from davinci_sim.cli import main
from davinci_sim.records import MetricInfo, RecordsDB, Score
from davinci_sim.records.report import curve_metrics

INFO = {"deviation_error": MetricInfo("m", "lower"), "completion_time": MetricInfo("s", "lower"),
        "peak_force": MetricInfo("N", "neither")}  # fmt: skip


@pytest.fixture
def records(tmp_path):
    """ana: two sessions of seed_path (5 attempts, the last 3 scored) and one of ring_walk;
    ben: one attempt."""
    path = tmp_path / "records.sqlite3"
    with RecordsDB(path) as db:
        for session_attempts in ((0, 1, 2), (3, 4)):
            s = db.start_session("ana", version="1.2.3", host="console-1")
            for i in session_attempts:
                score = Score(45.0 + 10 * i, 45.0 + 10 * i >= 70, 70.0) if i >= 2 else None
                db.record_attempt(s, task="seed_path", kind="path", condition="B=40",
                                  settings={"type": "viscous", "B": 40.0}, repetition=i + 1,
                                  metrics={"deviation_error": 0.003 - 0.0003 * i,
                                           "completion_time": 20.0 - i, "peak_force": 2.0},
                                  info=INFO, score=score)  # fmt: skip
            db.end_session(s)
        s = db.start_session("ana")
        db.record_attempt(s, task="ring_walk", kind="ring", metrics={"contacts": 3},
                          info={"contacts": MetricInfo("1", "lower")})  # fmt: skip
        s = db.start_session("ben")
        db.record_attempt(s, task="seed_path", metrics={"deviation_error": 0.004}, info=INFO)
    return path


def run(capsys, *argv) -> tuple[int, str, str]:
    code = main(["trainees", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_list(records, capsys):
    code, out, _ = run(capsys, "list", "--records", str(records))
    assert code == 0
    lines = out.splitlines()
    assert lines[1].split()[:3] == ["ana", "3", "6"] and lines[2].split()[:3] == ["ben", "1", "1"]


def test_the_records_file_can_come_from_the_environment(records, capsys, monkeypatch):
    monkeypatch.setenv("DAVINCI_SIM_RECORDS", str(records))
    code, out, _ = run(capsys, "list")
    assert code == 0 and "ana" in out


def test_show(records, capsys):
    code, out, _ = run(capsys, "show", "ana", "--records", str(records))
    assert code == 0
    assert "3 session(s), 6 attempt(s)" in out
    assert "task 'seed_path' (path): 5 attempt(s), 2 of 3 scored passed" in out
    assert "latest: attempt 5, repetition 5, condition B=40" in out and "score 85 (pass)" in out
    line = next(x for x in out.splitlines() if x.strip().startswith("deviation_error"))
    assert line.split() == ["deviation_error", "0.0018", "m", "best", "0.0018"]
    assert "davinci-sim 1.2.3 on console-1" in out
    assert "task 'ring_walk' (ring): 1 attempt(s)" in out


def test_export_csv_has_one_row_per_attempt_with_the_metrics_as_columns(records, tmp_path,
                                                                         capsys):  # fmt: skip
    out_file = tmp_path / "attempts.csv"
    code, out, _ = run(capsys, "export", "--csv", str(out_file), "--records", str(records))
    assert code == 0 and "7 attempt(s)" in out
    rows = list(csv.DictReader(out_file.open()))
    assert [r["trainee"] for r in rows] == ["ana"] * 6 + ["ben"]
    assert [r["task"] for r in rows] == ["seed_path"] * 5 + ["ring_walk", "seed_path"]
    assert {"deviation_error", "completion_time", "peak_force", "contacts", "score"} <= set(rows[0])
    assert float(rows[4]["deviation_error"]) == pytest.approx(0.0018)
    assert rows[4]["score"] == "85.0" and rows[4]["passed"] == "True"
    assert rows[0]["score"] == "" and rows[0]["contacts"] == "" and rows[5]["contacts"] == "3.0"
    code, out, _ = run(capsys, "export", "--csv", "--trainee", "ben", "--records", str(records))
    assert code == 0
    (ben,) = list(csv.DictReader(io.StringIO(out)))
    assert float(ben["deviation_error"]) == 0.004 and ben["trainee"] == "ben"


def test_curve_writes_a_png(records, tmp_path, capsys):
    png = tmp_path / "ana.png"
    argv = ["curve", "ana", "--task", "seed_path", "-o", str(png), "--pass-mark",
            "deviation_error=0.002", "--records", str(records)]  # fmt: skip
    code, out, _ = run(capsys, *argv)
    assert code == 0 and out.strip() == str(png)
    image = Image.open(png)
    assert image.format == "PNG"
    # score, deviation error, completion time (peak force has no better direction)
    assert image.size[0] > 2.5 * image.size[1]
    png2 = tmp_path / "all.png"
    assert main(["trainees", "curve", "ana", "-o", str(png2), "--records", str(records)]) == 0
    assert Image.open(png2).size[1] > 1.5 * Image.open(png).size[1]  # one row per task


def test_curves_in_columns(records):
    from davinci_sim.records.report import curves_png

    with RecordsDB(records) as db:
        wide = Image.open(io.BytesIO(curves_png(db, "ana", task="seed_path")))
        two = Image.open(io.BytesIO(curves_png(db, "ana", task="seed_path", columns=2)))
    assert wide.size == (1200, 320) and two.size == (800, 640)  # 3 panels of 400 x 320 px


def test_the_default_curves_are_the_score_and_the_metrics_with_a_direction(records):
    with RecordsDB(records) as db:
        assert curve_metrics(db.attempts("ana", task="seed_path")) == [
            "score", "deviation_error", "completion_time"]  # fmt: skip
        assert curve_metrics(db.attempts("ben")) == ["deviation_error"]  # (what was recorded)


@pytest.mark.parametrize(
    "argv, words",
    [
        (["show", "nobody"], "no trainee 'nobody'"),
        (["curve", "nobody", "-o", "x.png"], "no trainee 'nobody'"),
        (["curve", "ana", "--task", "nothing", "-o", "x.png"], "no attempts of task 'nothing'"),
        (["curve", "ana", "--metric", "speed", "-o", "x.png"], "no metric 'speed'"),
        (["curve", "ana", "--pass-mark", "deviation_error=abc", "-o", "x.png"], "METRIC=VALUE"),
        (["curve", "ana", "-o", "{missing}/x.png"], "cannot write"),
        (["export", "--csv", "{missing}/x.csv"], "cannot write"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(records, tmp_path, capsys, monkeypatch, argv, words):
    monkeypatch.chdir(tmp_path)
    argv = [a.replace("{missing}", str(tmp_path / "missing")) for a in argv]
    code, out, err = run(capsys, *argv, "--records", str(records))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and words in err and err.startswith("davinci-sim trainees")
    assert not (tmp_path / "x.png").exists()


def test_a_missing_records_file_is_an_error_and_is_not_created(tmp_path, capsys):
    path = tmp_path / "none.sqlite3"
    code, _, err = run(capsys, "list", "--records", str(path))
    assert code == 2 and "no records file" in err and not path.exists()
