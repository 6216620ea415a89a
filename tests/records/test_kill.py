"""A process killed abruptly (SIGKILL: no clean-up at all) loses no attempt it recorded,
and the file it leaves is sound."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import davinci_sim
from davinci_sim.records import RecordsDB

SRC = str(Path(davinci_sim.__file__).resolve().parents[1])

#: Records attempts in a loop, printing each id once record_attempt has returned; after
#: ``stop_after`` attempts it waits to be killed (0: it keeps recording).
WRITER = textwrap.dedent("""
    import sys, time
    from davinci_sim.records import MetricInfo, RecordsDB
    path, stop_after = sys.argv[1], int(sys.argv[2])
    db = RecordsDB(path)
    session = db.start_session("kim", source="kill test")
    info = {f"m{j}": MetricInfo("s", "lower") for j in range(20)}
    i = 0
    while True:
        i += 1
        metrics = {f"m{j}": i + j / 100 for j in range(20)}
        a = db.record_attempt(session, task="seed_path", repetition=i, metrics=metrics,
                              info=info)
        print(a, flush=True)
        if i == stop_after:
            print("done", flush=True)
            time.sleep(600)
""")


#: The console's way: an AttemptRecorder (its writer thread) is given the session's rows;
#: once flushed, it prints the ids it recorded and waits to be killed.
RECORDER = textwrap.dedent("""
    import sys, time
    from davinci_sim.records import AttemptRecorder
    path, n = sys.argv[1], int(sys.argv[2])
    recorder = AttemptRecorder(path, "kim", source="kill test").start()
    for i in range(1, n + 1):
        recorder.submit({"task": "seed_path", "condition": "B=40", "repetition": i,
                         **{f"m{j}": i + j / 100 for j in range(20)}})
    recorder.flush()
    for a in recorder.recorded:
        print(a, flush=True)
    print("done", flush=True)
    time.sleep(600)
""")


def run_and_kill(path: Path, stop_after: int, kill_after_lines: int, script=WRITER) -> list[int]:
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-c", script, str(path), str(stop_after)],
                            stdout=subprocess.PIPE, text=True, env=env)  # fmt: skip
    ids = []
    try:
        for line in proc.stdout:
            if line.strip() == "done":
                break
            ids.append(int(line))
            if len(ids) == kill_after_lines:
                break
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    return ids


def check_file(path: Path, ids: list[int]) -> list[dict]:
    with RecordsDB(path) as db:
        assert db.integrity() == "ok"
        attempts = db.attempts("kim")
    recorded = [a["id"] for a in attempts]
    assert recorded[: len(ids)] == ids  # every attempt it said it recorded is there
    for a in attempts:  # and each attempt is whole: all its metrics, no half attempt
        assert len(a["metrics"]) == 20
        assert a["metrics"]["m3"][0] == pytest.approx(a["repetition"] + 0.03)
    return attempts


def test_killed_after_recording_loses_nothing(tmp_path):
    path = tmp_path / "r.sqlite3"
    ids = run_and_kill(path, stop_after=5, kill_after_lines=0)
    assert len(ids) == 5
    # the killed process did not close the file: its commits are in the write-ahead log,
    # which the next opening recovers
    assert (tmp_path / "r.sqlite3-wal").stat().st_size > 0
    attempts = check_file(path, ids)
    assert len(attempts) == 5


def test_killed_while_recording_keeps_every_recorded_attempt_whole(tmp_path):
    path = tmp_path / "r.sqlite3"
    ids = run_and_kill(path, stop_after=0, kill_after_lines=40)  # killed mid-stream
    attempts = check_file(path, ids)
    assert len(attempts) >= 40
    # the file stays usable: the next process goes on where the killed one stopped
    with RecordsDB(path) as db:
        s = db.start_session("kim")
        db.record_attempt(s, task="seed_path", metrics={})
        assert len(db.attempts("kim")) == len(attempts) + 1


def test_a_killed_console_keeps_every_attempt_its_recorder_wrote(tmp_path):
    path = tmp_path / "r.sqlite3"
    ids = run_and_kill(path, stop_after=7, kill_after_lines=0, script=RECORDER)
    assert len(ids) == 7
    attempts = check_file(path, ids)
    assert [a["repetition"] for a in attempts] == list(range(1, 8))
    with RecordsDB(path) as db:
        (session,) = db.sessions("kim")
    assert session["ended_at"] is None  # (killed: the session was never ended)
