"""Every attempt at the console is recorded: a system runs a task session behind its runner
(as ``serve --task`` does), the records part listens to it through the handle, and a
synthetic trainee at the MTM finishes repetitions; each becomes an attempt of the trainee's
session with the task's declared metrics and units. A records file that cannot be written
is said on the session's message channel, and the simulation goes on."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from davinci_sim.records import RecordsDB, records_part
from davinci_sim.system import ConsoleDescription, SystemDescription, TaskDescription, build_system
from davinci_sim.tasks import load_task

#: A 3-cm path near where PSM1 homes (the seed's path would take ~4x the simulated time).
SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")


def wait_for(handle, condition, sim_seconds: float) -> bool:
    """Poll ``condition()`` until it holds or the simulation has run ``sim_seconds`` more
    (simulated time: the test does not depend on the machine's speed)."""
    end = handle.snapshot().time + sim_seconds
    while not condition():
        if handle.snapshot().time > end:
            return False
        time.sleep(0.02)
    return True


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("records")
    path = folder / "records.sqlite3"
    description = SystemDescription(
        scene="psm1_ecm_mtmr",
        home=True,
        runner="thread",
        real_time=False,
        task=TaskDescription(SHORT_TASK, condition="40:5"),
        console=ConsoleDescription(
            hand_inputs=("MTMR",), operator_present=True, teleop_enabled=True
        ),
    )
    system = build_system(description)
    events = []
    system.handle.subscribe(lambda source, event, payload: events.append((source, event, payload)))
    info: dict = {}
    recorder = records_part("ana", path=path, task=SHORT_TASK, condition="40:5")(system, info)
    broken = records_part("ana", path=folder, task=SHORT_TASK)(system, {})  # a folder: unusable
    system.start()
    handle = system.handle
    finished = []
    try:
        for trainee in ("ana", "ben"):
            if trainee != "ana":
                recorder.set_trainee(trainee)
            n = len(recorder.recorded)
            assert handle.call("synthetic", "start", subject=3, practice=5).result(10)
            finished.append(wait_for(handle, lambda n=n: len(recorder.recorded) > n, 60.0))
            wait_for(handle, lambda: not handle.snapshot().extras["synthetic"]["running"], 10.0)
        recorder.flush(10)
        broken.flush(10)
        t_after = handle.snapshot().time
        wait_for(handle, lambda: False, 0.2)  # the loop goes on after the failures
        running_on = handle.snapshot().time > t_after
        refused = handle.call("task", "report", "loud", "x").result(10)  # not a level
    finally:
        recorder.stop()
        broken.stop()
        system.stop()
    yield path, info, recorder, broken, events, finished, (running_on, refused)


def test_each_finished_repetition_is_an_attempt_of_the_trainee(run):
    path, info, recorder, _, events, finished, _ = run
    assert finished == [True, True]
    assert info == {"records": str(path), "trainee": "ana"}
    rows = [p for s, e, p in events if s == "task" and e == "results"]
    assert len(rows) == 2
    task = load_task(SHORT_TASK)
    with RecordsDB(path) as db:
        assert [t["name"] for t in db.trainees()] == ["ana", "ben"]
        for trainee, row in zip(("ana", "ben"), rows, strict=True):
            (attempt,) = db.attempts(trainee)
            assert attempt["task"] == task.name and attempt["kind"] == "path"
            assert attempt["repetition"] == row["repetition"]
            assert attempt["condition"] == row["condition"] == "viscous(B=40, G_max=5)"
            assert '"B": 40.0' in attempt["settings"] and '"G_max": 5.0' in attempt["settings"]
            assert list(attempt["metrics"]) == [m.name for m in task.METRICS]
            for m in task.METRICS:
                value, unit, better = attempt["metrics"][m.name]
                assert value == pytest.approx(row[m.name]) and (unit, better) == (m.unit, m.better)
            assert attempt["started_at"] < attempt["ended_at"]
        (ana,) = db.sessions("ana")
        assert ana["ended_at"] is not None and ana["source"] == "serve"  # ended at set_trainee
        (ben,) = db.sessions("ben")
        assert ben["ended_at"] is not None  # ended at stop


def test_a_records_file_that_cannot_be_written_is_said_and_the_simulation_goes_on(run):
    _, _, _, broken, events, _, (running_on, refused) = run
    assert len(broken.failed) == 2 and broken.recorded == []
    errors = [p.text for s, e, p in events if s == "task" and e == "error"]
    assert len(errors) >= 3  # at the start, at each attempt (and when it stopped)
    assert "records: cannot start 'ana''s session in" in errors[0]
    assert "records: cannot record repetition 1" in errors[1] and "(1 attempt(s) kept" in errors[1]
    assert "records: cannot record repetition" in errors[2] and "(2 attempt(s) kept" in errors[2]
    assert running_on
    assert not refused and "level must be" in refused.message


def test_the_loop_in_its_own_process_is_recorded_too(tmp_path):
    """``serve``'s runner with the web console: the session lives in the loop process, its
    rows come through the handle's events."""
    path = tmp_path / "records.sqlite3"
    description = SystemDescription(
        scene="psm1_ecm_mtmr",
        home=True,
        runner="process",
        real_time=False,
        task=TaskDescription(SHORT_TASK),
        console=ConsoleDescription(
            hand_inputs=("MTMR",), operator_present=True, teleop_enabled=True
        ),
    )
    system = build_system(description)
    part = records_part("ana", path=path, task=SHORT_TASK)
    system.start()
    recorder = part(system, {})
    rows = []
    system.handle.subscribe(lambda s, e, p: rows.append(p) if e == "results" else None)
    try:
        handle = system.handle
        assert handle.call("synthetic", "start", subject=3, practice=5).result(30)
        assert wait_for(handle, lambda: len(recorder.recorded) == 1, 60.0)
        (row,) = rows
    finally:
        recorder.stop()
        system.stop()
    with RecordsDB(path) as db:
        (attempt,) = db.attempts("ana")
    assert attempt["metrics"]["deviation_error"][0] == pytest.approx(row["deviation_error"])
