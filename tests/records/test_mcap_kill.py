"""``serve --record`` killed with SIGKILL (no clean-up at all) leaves a file that reads up to
its last chunk and still replays exactly."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import davinci_sim
from davinci_sim.records.mcap_file import read_mcap
from davinci_sim.records.replay import load_recording, replay_inputs

SRC = str(Path(davinci_sim.__file__).resolve().parents[1])


def test_a_killed_serve_leaves_a_readable_replayable_recording(tmp_path):
    path = tmp_path / "killed.mcap"
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    cmd = [sys.executable, "-m", "davinci_sim.cli", "serve", "--scene", "psm1", "--home",
           "--no-web", "--no-server", "--images", "none", "--record", str(path)]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, env=env)
    seen = 0
    try:
        for line in proc.stdout:  # (the process prints "ready" once it records)
            if line.startswith("ready"):
                break
        deadline = time.monotonic() + 120
        while seen < 30 and time.monotonic() < deadline:  # a few closed chunks (1 s each)
            time.sleep(0.5)
            seen = len(read_mcap(path).topic("/sim/qpos"))
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    assert seen >= 30, "the recording did not grow"

    # mcap's own seeking reader needs the footer a killed process never wrote.
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        try:
            list(make_reader(f).iter_messages())
            own_reader = "read"
        except Exception:
            own_reader = "failed"
    assert own_reader == "failed"

    contents = read_mcap(path)
    assert not contents.complete and contents.problem is not None
    assert len(contents.topic("/sim/qpos")) >= seen
    assert "description.pickle" in contents.attachments  # (written before the first chunk)
    recording = load_recording(path)
    check = replay_inputs(recording)  # the arms homed in it: the physics ran the same
    assert check.bit_equal and check.ticks == len(recording.ticks)
