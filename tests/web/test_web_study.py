"""The web console's study tab: a small study runs in the background, reports progress and
offers its outputs; bad requests are refused before anything starts."""

import threading
from pathlib import Path

import pytest

from davinci_sim.web.study_job import StudyJob

SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")


def collector():
    """(messages, done, notify): a job's messages, set done when it ends."""
    messages: list[dict] = []
    done = threading.Event()

    def notify(m):
        messages.append(m)
        if m["state"] in ("done", "failed"):
            done.set()

    return messages, done, notify


def test_a_small_study_reports_progress_and_its_outputs():
    messages, done, notify = collector()
    job = StudyJob(SHORT_TASK, notify)
    assert job.start(subjects=1, repetitions=1) is None
    assert job.start(subjects=1, repetitions=1) == "a study is already running"
    assert done.wait(300), "the study did not end"
    final = messages[-1]
    assert final["state"] == "done", final
    assert final["total"] == 4  # Table I: four conditions, one subject, one repetition
    progress = [m["done"] for m in messages if m["state"] == "running"]
    assert progress[0] == 0 and progress == sorted(progress) and progress[-1] == 4
    assert {"trials.csv", "report.md"} <= set(final["files"])
    assert any(f.endswith(".png") for f in final["files"])
    assert "short_path" in final["report"] or "B" in final["report"]
    csv = job.file("trials.csv").decode()
    assert len(csv.strip().splitlines()) == 1 + 4
    assert job.file("../../etc/passwd") is None and job.file("nope.png") is None
    job.close()


def test_the_study_tab_runs_a_needle_exercise_on_the_live_engine():
    """A needle exercise's study (its trainee on both MTMs, live engine) from the tab: the
    exercise's own columns and report."""
    messages, done, notify = collector()
    job = StudyJob("needle_pickup", notify)
    assert job.start(subjects=1, repetitions=1) is None
    assert done.wait(600), "the study did not end"
    final = messages[-1]
    assert final["state"] == "done", final
    assert final["total"] == 1 and "needle_pickup" in final["report"]
    header = job.file("trials.csv").decode().splitlines()[0].split(",")
    assert "handoffs" in header and "deviation_error" not in header
    job.close()


@pytest.mark.parametrize(
    "subjects, repetitions, words",
    [(0, 1, "subjects"), (11, 1, "subjects"), (1, 0, "repetitions"), (1, 6, "repetitions")],
)
def test_a_study_too_small_or_too_large_is_refused(subjects, repetitions, words):
    job = StudyJob(SHORT_TASK, lambda m: None)
    assert words in job.start(subjects, repetitions)
    assert not job.running


def test_a_study_of_an_unknown_task_fails_with_a_message():
    messages, done = [], threading.Event()
    job = StudyJob(
        "no_such_task", lambda m: (messages.append(m), m["state"] == "failed" and done.set())
    )
    why = job.start(1, 1)
    if why is None:  # refused while planning, in the thread
        assert done.wait(60)
        assert messages[-1]["state"] == "failed" and "no_such_task" in messages[-1]["message"]
    else:
        assert "no_such_task" in why


def run_job(job: StudyJob, subjects: int = 1, repetitions: int = 1) -> list[dict]:
    messages, done, job.notify = collector()
    assert job.start(subjects=subjects, repetitions=repetitions) is None
    assert done.wait(300), "the study did not end"
    return messages


def test_a_kept_study_writes_its_rows_through_the_studys_store(tmp_path):
    job = StudyJob(SHORT_TASK, lambda m: None, root=tmp_path / "studies")
    final = run_job(job)[-1]
    assert final["state"] == "done", final
    folder = Path(final["folder"])
    assert folder.parent == tmp_path / "studies" and folder.name.startswith("short_path-")
    assert (folder / "trials.csv").is_file() and not (folder / "trials.partial.jsonl").exists()
    job.close()
    assert (folder / "trials.csv").is_file()  # (kept: not a temporary folder)


def test_a_study_cut_short_keeps_its_rows_and_says_how_to_resume(tmp_path, monkeypatch):
    import davinci_sim.study as study
    from davinci_sim.study import StudyConfig
    from davinci_sim.study.store import StudyRows

    def broken(result, folder):
        raise OSError("the disk is full")

    monkeypatch.setattr(study, "write_outputs", broken)  # (after every trial's row)
    job = StudyJob(SHORT_TASK, lambda m: None, root=tmp_path)
    final = run_job(job)[-1]
    assert final["state"] == "failed" and "the disk is full" in final["message"]
    assert "4 of 4 trials are kept" in final["message"] and "--resume" in final["message"]
    folder = job.folder
    assert folder is not None and str(folder) in final["message"]
    config = StudyConfig(n_subjects=1, n_repetitions=1, task=SHORT_TASK, seed=0, workers=1)
    kept = StudyRows.resume(folder, config)  # what `davinci-sim study --resume` reads
    assert sorted(kept.rows) == [0, 1, 2, 3]
    kept.close()
