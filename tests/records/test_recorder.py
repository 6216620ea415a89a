"""The recorder on its own: rows become attempts (score columns as the score), a locked file
is reported and the next attempt goes in once it is free, the trainee can change."""

from __future__ import annotations

import sqlite3

from davinci_sim.records import AttemptRecorder, RecordsDB, Score
from davinci_sim.records.recorder import split_row
from davinci_sim.tasks import load_task


def row(repetition: int, **extra) -> dict:
    return {"task": "seed_path", "condition": "B=40", "repetition": repetition,
            "deviation_error": 0.002, "completion_time": 12.5, **extra}  # fmt: skip


def test_a_row_is_split_into_metrics_and_score():
    metrics, score = split_row(row(1))
    assert metrics == {"deviation_error": 0.002, "completion_time": 12.5} and score is None
    metrics, score = split_row(row(1, score=81.0, passed=1, pass_mark=70.0))
    assert "score" not in metrics and score == Score(81.0, True, 70.0)
    metrics, _ = split_row(row(1, guidance_B=28.0))  # an adaptive fixture's B: not a metric
    assert "guidance_B" not in metrics


def test_an_adaptive_repetitions_B_is_kept_with_its_settings(tmp_path):
    path = tmp_path / "r.sqlite3"
    settings = {"type": "adaptive", "mode": "assist_as_needed"}
    recorder = AttemptRecorder(
        path, "ana", task=load_task("seed_path"), condition="aan", settings=settings
    )
    recorder.start()
    recorder.submit(dict(row(1, guidance_B=28.0), condition="aan"))
    assert recorder.flush(30)
    recorder.stop()
    with RecordsDB(path) as db:
        (attempt,) = db.attempts("ana")
    assert "guidance_B" not in attempt["metrics"]
    assert '"guidance_B": 28.0' in attempt["settings"] and '"adaptive"' in attempt["settings"]


def test_rows_become_attempts_with_units_settings_and_times(tmp_path):
    path = tmp_path / "r.sqlite3"
    task = load_task("seed_path")
    recorder = AttemptRecorder(path, "ana", task=task, condition="B=40",
                               settings={"type": "viscous", "B": 40.0, "G_max": 5.0})  # fmt: skip
    recorder.start()
    recorder.submit(row(1, score=81.0, passed=True, pass_mark=70.0))
    recorder.submit(dict(row(2), condition=task.conditions[0]["name"]))  # a named condition
    recorder.submit(dict(row(3), condition="spring(k=100)"))  # changed at the console
    assert recorder.flush(30)
    recorder.stop()
    with RecordsDB(path) as db:
        a1, a2, a3 = db.attempts("ana")
        (session,) = db.sessions("ana")
    assert a1["metrics"]["deviation_error"] == (0.002, "m", "lower")
    assert (a1["score"], a1["passed"], a1["pass_mark"]) == (81.0, True, 70.0)
    assert a1["kind"] == "path" and '"G_max": 5.0' in a1["settings"]
    assert a1["started_at"] < a1["ended_at"]  # ended_at - completion_time (12.5 s)
    assert '"name": ' in a2["settings"]  # the task's entry of that condition
    assert a3["settings"] == '{"label": "spring(k=100)"}'
    assert session["ended_at"] is not None


def test_a_locked_file_is_reported_and_the_next_attempt_goes_in(tmp_path):
    path = tmp_path / "r.sqlite3"
    errors: list[str] = []
    recorder = AttemptRecorder(path, "ana", on_error=errors.append).start()
    recorder.flush(30)
    lock = sqlite3.connect(path, isolation_level=None)
    lock.execute("BEGIN EXCLUSIVE")  # another process holds the file
    recorder.submit(row(1))
    assert recorder.flush(60)
    assert len(errors) == 1 and "cannot record repetition 1 of 'ana'" in errors[0]
    assert "locked" in errors[0] and recorder.failed == [row(1)]
    recorder.submit(row(2))  # still locked: kept too
    assert recorder.flush(60)
    assert "(2 attempt(s) kept" in errors[1] and recorder.failed == [row(1), row(2)]
    lock.execute("ROLLBACK")
    lock.close()
    recorder.submit(row(3))  # free again: 1 and 2 go in first, then 3
    recorder.set_trainee("ben")
    recorder.submit(row(4))
    recorder.stop()
    assert recorder.failed == [] and len(errors) == 2
    with RecordsDB(path) as db:
        assert [a["repetition"] for a in db.attempts("ana")] == [1, 2, 3]
        assert [a["repetition"] for a in db.attempts("ben")] == [4]
        assert len(db.sessions("ana")) == 1  # the failure did not end ana's session


def test_rows_that_cannot_be_written_before_the_trainee_changes_are_given_up(tmp_path):
    errors: list[str] = []
    recorder = AttemptRecorder(tmp_path, "ana", on_error=errors.append).start()  # a folder
    recorder.submit(row(1))
    recorder.set_trainee("ben")
    recorder.submit(row(2))
    recorder.stop()
    assert recorder.failed == [row(1), row(2)] and recorder.recorded == []
    assert "1 attempt(s) of 'ana' could not be recorded and are given up" in errors
    assert "1 attempt(s) of 'ben' could not be recorded and are given up" in errors


def test_the_marks_of_the_tasks_scoring_are_kept_with_the_attempt_and_drawn(tmp_path):
    from types import SimpleNamespace

    from matplotlib.figure import Figure

    from davinci_sim.records.report import _draw_one

    class Scoring:  # what the trainer scores give a task: Task.scoring (tasks/scoring.py)
        pass_score = 70.0

        def score(self, values):
            assert values["deviation_error"] == 0.002  # the row's metric values
            return SimpleNamespace(marks={"deviation_error": 0.0025})

    seed = load_task("seed_path")
    task = SimpleNamespace(name=seed.name, kind=seed.kind, METRICS=seed.METRICS,
                           scoring=Scoring(), conditions=())  # fmt: skip
    path = tmp_path / "r.sqlite3"
    recorder = AttemptRecorder(path, "ana", task=task).start()
    recorder.submit(row(1, score=64.0, passed=False))
    recorder.stop()
    with RecordsDB(path) as db:
        (a,) = db.attempts("ana")
    assert a["pass_marks"] == {"deviation_error": 0.0025}
    assert (a["score"], a["passed"], a["pass_mark"]) == (64.0, False, 70.0)
    ax = Figure().subplots()
    _draw_one(ax, [a], "deviation_error", None)  # the recorded mark: the band at 2.5 mm
    assert any(list(line.get_ydata()) == [0.0025, 0.0025] for line in ax.lines)
    ax = Figure().subplots()
    _draw_one(ax, [a], "score", None)
    assert any(list(line.get_ydata()) == [70.0, 70.0] for line in ax.lines)
