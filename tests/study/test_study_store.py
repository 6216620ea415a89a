"""A study loses nothing: rows kept as trials end, resumed after an interruption (Ctrl-C, a
kill) with the same rows as an uninterrupted run, a changed study refused, final files
written whole; and it says how long it will take before it starts."""

import csv
import dataclasses
import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from davinci_sim.cli import main
from davinci_sim.study import StudyConfig, StudyError, plan_trials, run_study, runner
from davinci_sim.study.batch import TrialBatch
from davinci_sim.study.report import COLUMNS, TIMING_COLUMNS, write_csv
from davinci_sim.study.store import PARTIAL, StudyRows, atomic_path

SRC = Path(__file__).resolve().parents[2] / "src"

#: Run the command line, interrupting itself with signal argv[1] once argv[2] rows are kept
#: (a deterministic interruption: right after a row was written, whatever the machine's speed).
INTERRUPTING_CLI = """
import os, signal, sys
# Ctrl-C as a terminal delivers it, whatever disposition this child inherited from the test
# process (an ignored or blocked SIGINT is inherited across exec; under the full suite the
# study then ran to its end)
signal.signal(signal.SIGINT, signal.default_int_handler)
signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
from davinci_sim.cli import main
from davinci_sim.study import store
sig, after = getattr(signal, sys.argv[1]), int(sys.argv[2])
append = store.StudyRows.append
def interrupting(self, index, row):
    append(self, index, row)
    if len(self.rows) >= after:
        os.kill(os.getpid(), sig)
store.StudyRows.append = interrupting
sys.exit(main(sys.argv[3:]))
"""


def _args(task, out, *extra):
    # 2 subjects (different speeds: the trials end at different ticks) x 2 conditions x 1
    return ["study", "--subjects", "2", "--repetitions", "1", "--conditions", "0:0,40:5",
            "--task", task, "--seed", "5", "-o", str(out), "--no-progress", *extra]  # fmt: skip


def _config(task):
    return StudyConfig(conditions=((0, 0), (40, 5)), n_subjects=2, n_repetitions=1, task=task,
                       seed=5)  # fmt: skip


def _cli(tmp_path, sig, after, argv):
    script = tmp_path / "interrupting_cli.py"
    script.write_text(INTERRUPTING_CLI)
    env = {**os.environ, "PYTHONPATH": str(SRC), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    return subprocess.run(
        [sys.executable, str(script), sig, str(after), *argv],
        capture_output=True, text=True, env=env, timeout=600,
    )  # fmt: skip


def _csv_rows(path):
    with open(path) as f:
        return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in csv.DictReader(f)]


@pytest.fixture(scope="module")
def reference(tmp_path_factory, short_task):
    """The same study run in one go: its rows."""
    return run_study(_config(short_task), progress=False).rows


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory, reference):
    """The reference's CSV rows, timing columns dropped."""
    path = tmp_path_factory.mktemp("reference") / "trials.csv"
    write_csv(reference, path)
    return _csv_rows(path)


@pytest.mark.parametrize(("sig", "workers"), [("SIGKILL", "2"), ("SIGINT", "1")])
def test_an_interrupted_study_keeps_its_rows_and_resumes_to_the_same_rows(
    sig, workers, tmp_path, short_task, uninterrupted, capsys
):
    out = tmp_path / "study"
    run = _cli(tmp_path, sig, 1, _args(short_task, out, "--workers", workers))
    if sig == "SIGKILL":
        assert run.returncode == -signal.SIGKILL
    else:  # Ctrl-C: one line saying what is kept and how to go on
        assert run.returncode == 130, run.stderr
        assert "--resume" in run.stderr and "Traceback" not in run.stderr
    assert not (out / "trials.csv").exists()
    lines = (out / PARTIAL).read_text().splitlines()
    header = json.loads(lines[0])
    assert header["config"]["seed"] == 5 and header["n_trials"] == 4
    kept = [json.loads(line) for line in lines[1:]]
    assert 1 <= len(kept) < 4
    plan = plan_trials(_config(short_task))
    for entry in kept:  # keyed by plan index and TrialSpec.key
        assert tuple(entry["key"]) == plan[entry["index"]].key

    if sig == "SIGKILL":  # and the kill came in the middle of writing a row
        with open(out / PARTIAL, "ab") as f:
            f.write(b'{"index": 3, "key": [5, 1, 1, 1], "row": {"subject": 1, "cond')
    capsys.readouterr()
    assert main(_args(short_task, out, "--resume", "--workers", "2")) == 0
    printed = capsys.readouterr().out
    assert ("note: ignored the last line" in printed) == (sig == "SIGKILL")
    # the time estimate: printed before the trials, a positive number of seconds
    estimate = re.search(r"estimate: (\d+) trials on .*, about ([\d.]+) s", printed)
    assert estimate and int(estimate[1]) == 4 - len(kept) and float(estimate[2]) > 0
    assert printed.index("estimate:") < printed.index("trials.csv")
    assert _csv_rows(out / "trials.csv") == uninterrupted
    assert not (out / PARTIAL).exists()  # finished: nothing left to resume
    assert "resumed: " in (out / "report.md").read_text()


def test_resume_refuses_a_different_study_in_one_line(tmp_path, short_task, capsys):
    out = tmp_path / "study"
    StudyRows.create(out, _config(short_task)).close()
    assert main(_args(short_task, out, "--resume", "--repetitions", "2")) == 2
    err = capsys.readouterr().err
    assert "n_repetitions 1 (stored) vs 2" in err and len(err.strip().splitlines()) == 1
    # how the trials run is not the study: other workers are fine
    rows = StudyRows.resume(out, dataclasses.replace(_config(short_task), workers=1))
    assert rows.rows == {}
    rows.close()
    # a task file edited since is another study
    task = tmp_path / "task.yaml"
    task.write_text(Path(short_task).read_text())
    StudyRows.create(tmp_path / "edited", _config(str(task))).close()
    task.write_text(Path(short_task).read_text().replace("min_progress: 0.5", "min_progress: 0.6"))
    with pytest.raises(StudyError, match="task_sha256"):
        StudyRows.resume(tmp_path / "edited", _config(str(task)))


def test_a_new_study_does_not_overwrite_an_unfinished_one(tmp_path, short_task, capsys):
    out = tmp_path / "study"
    StudyRows.create(out, _config(short_task)).close()
    before = (out / PARTIAL).read_bytes()
    assert main(_args(short_task, out)) == 2
    assert "--resume" in capsys.readouterr().err
    assert (out / PARTIAL).read_bytes() == before


def test_resume_without_an_unfinished_study_says_so(tmp_path, short_task, capsys):
    assert main(_args(short_task, tmp_path / "empty", "--resume")) == 2
    err = capsys.readouterr().err
    assert "no unfinished study" in err and len(err.strip().splitlines()) == 1


def test_resume_into_a_file_is_refused_before_work(tmp_path, short_task, capsys):
    target = tmp_path / "results.csv"
    target.write_text("keep me")
    assert main(_args(short_task, target, "--resume")) == 2
    assert "not a folder" in capsys.readouterr().err
    assert target.read_text() == "keep me"


def test_an_atomic_write_that_fails_leaves_the_old_file_and_no_other(tmp_path):
    target = tmp_path / "trials.csv"
    target.write_text("old")
    with pytest.raises(ValueError):  # a row with a column the CSV does not have
        write_csv([{"subject": 0, "not a column": 1}], target)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["trials.csv"]
    with atomic_path(tmp_path / "new.png") as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".png"
        tmp.write_bytes(b"x")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new.png", "trials.csv"]


def test_rows_reach_the_caller_as_trials_end(short_task):
    specs = plan_trials(_config(short_task))
    batch = TrialBatch(specs)
    seen = []
    rows = batch.run(on_row=lambda i, row: seen.append((i, row, int(batch.active.sum()))))
    assert sorted(i for i, _, _ in seen) == list(range(len(specs)))
    assert seen[0][2] > 0  # the first row came while other trials were still running
    for i, row, _ in seen:
        assert rows[i] is row
    assert list(rows[0]) == list(COLUMNS)


def test_no_worker_process_for_a_single_trial(short_task, monkeypatch):
    def no_pool(*args):
        raise AssertionError("a worker process was started for one trial")

    monkeypatch.setattr(runner, "_pool", no_pool)
    config = dataclasses.replace(_config(short_task), n_subjects=1, conditions=((40, 5),))
    result = run_study(dataclasses.replace(config, workers=2), progress=False)
    assert len(result.rows) == 1 and result.rows[0]["finished"]
    assert runner.processes(1, 2) == 1
    assert 1 <= runner.processes(400, 64) <= runner.usable_cores()


def test_a_study_stopped_while_writing_its_outputs_resumes_without_trials(
    tmp_path, short_task, reference, uninterrupted, capsys
):
    out = tmp_path / "study"
    rows = StudyRows.create(out, _config(short_task))
    for i, row in enumerate(reference):
        rows.append(i, row)
    rows.close()
    assert main(_args(short_task, out, "--resume")) == 0
    printed = capsys.readouterr().out
    assert "4 trials kept, 0 to run" in printed and "estimate:" not in printed
    assert _csv_rows(out / "trials.csv") == uninterrupted
