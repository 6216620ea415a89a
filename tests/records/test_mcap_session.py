"""A recorded session (serve --record's recorder on a running system) replays exactly: the
recorded commands through the physics (mode 1) and the recorded states (mode 2) give the
recorded joint positions bit for bit; the file is self-contained and becomes a dataset."""

from __future__ import annotations

import json
import time

import h5py
import numpy as np
import pytest

from davinci_sim.cli import main
from davinci_sim.records.dataset import to_dataset
from davinci_sim.records.mcap_file import read_mcap
from davinci_sim.records.recording import SessionRecorder, recording_description
from davinci_sim.records.replay import (
    ReplayError,
    load_recording,
    replay_inputs,
    replay_states,
    replay_system,
)
from davinci_sim.system import SystemDescription, build_system


def wait_ticks(handle, n: int, timeout: float = 120.0) -> int:
    """Wait until the loop has run ``n`` more ticks; returns the tick then."""
    start = handle.snapshot().tick
    t0 = time.monotonic()
    while handle.snapshot().tick < start + n:
        assert time.monotonic() - t0 < timeout, "the loop does not tick"
        time.sleep(0.002)
    return handle.snapshot().tick


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """A short scripted session of PSM1 (homed at start), recorded: servo_cp moves, the
    jaw, a refused command, a query; the calls come at whatever tick they reach the loop."""
    path = tmp_path_factory.mktemp("rec") / "session.mcap"
    description = recording_description(
        SystemDescription(scene="psm1", home=True, runner="thread", real_time=False)
    )
    system = build_system(description, start=True)
    handle = system.handle
    recorder = SessionRecorder(path, description).attach(handle)
    try:
        wait_ticks(handle, 300)
        T = handle.call("PSM1", "measured_cp").result(30).T.copy()
        for k in range(4):
            goal = T.copy()
            goal[:3, 3] += [0.002 * k, -0.001 * k, 0.003]
            handle.call("PSM1", "servo_cp", goal).result(30)
            wait_ticks(handle, 40)
        handle.call("PSM1/jaw", "servo_jp", np.array([0.4])).result(30)
        handle.call("PSM1", "servo_jp", [np.nan] * 6).result(30)  # refused: changes nothing
        wait_ticks(handle, 150)
        # States to replay against: the recorder keeps the published snapshots, which come
        # at the publisher's pace, not the loop's (a fast loop gives few in 740 ticks).
        t0 = time.monotonic()
        while recorder.snapshots < 30:
            assert time.monotonic() - t0 < 120, "the recorder records no snapshots"
            time.sleep(0.01)
    finally:
        recorder.stop()
        system.stop()
    return path, recorder


def test_the_file_is_self_contained_and_foxglove_shaped(session):
    path, recorder = session
    c = read_mcap(path)
    assert c.complete and c.profile == "davinci-sim"
    meta = c.metadata["davinci_sim"]
    assert meta["kind"] == "session" and meta["scene"] == '"psm1"' or meta["scene"] == "psm1"
    assert len(meta["signature"]) == 40 and meta["mujoco"]
    assert json.loads(c.attachments["description.json"])["scene"] == "psm1"
    assert c.schemas["/tf"] == "foxglove.FrameTransforms"
    assert c.schemas["/PSM1/measured_cp"] == "foxglove.PoseInFrame"
    assert c.schemas["/PSM1/measured_js"] == "davinci_sim.JointState"
    assert c.schemas["/inputs/calls"] == "davinci_sim.Call"
    _, tf = c.topic("/tf")[-1]
    frames = {(t["parent_frame_id"], t["child_frame_id"]) for t in tf["transforms"]}
    assert any(child == "PSM1" for _, child in frames)
    _, js = c.topic("/PSM1/measured_js")[-1]
    assert len(js["name"]) == len(js["position"]) == 6
    methods = [m["method"] for _, m in c.topic("/inputs/calls")]
    assert methods.count("servo_cp") == 4 and "servo_jp" in methods
    assert recorder.calls == len(methods) and recorder.snapshots == len(c.topic("/sim/qpos"))
    times = [t for t, _ in c.topic("/sim/qpos")]
    assert times == sorted(times)


def test_mode_1_the_recorded_commands_give_the_recorded_states_bit_for_bit(session):
    path, _ = session
    recording = load_recording(path)
    assert len(recording.ticks) > 20 and not recording.unreplayable
    check = replay_inputs(recording)
    assert check.ticks == len(recording.ticks)
    assert check.bit_equal, check
    # every call ran again (the NaN servo_jp is refused again: a result, not an exception)
    assert check.calls == len(recording.calls) and check.failed_calls == 0
    # The commands matter: without them the replay does not give the recorded states.
    recording.calls = [c for c in recording.calls if c.method != "servo_cp"]
    assert not replay_inputs(recording).bit_equal


def test_mode_2_shows_the_recorded_states(session):
    path, _ = session
    recording = load_recording(path)
    check = replay_states(recording, speed=3.0)
    assert check.bit_equal and check.ticks >= (recording.ticks[-1] - recording.ticks[0]) / 3


def test_replay_serves_the_recording_through_a_runner(session):
    """What ``replay`` serves: the recorded calls queued at their ticks on a thread runner;
    every snapshot it publishes at a recorded tick has the recorded joint positions."""
    path, _ = session
    recording = load_recording(path)
    recorded = {int(t): q for t, q in zip(recording.ticks, recording.qpos, strict=True)}
    system = replay_system(recording, "inputs", speed=0)
    handle = system.handle
    compared = 0
    with system:
        deadline = time.monotonic() + 120
        while handle.snapshot().tick < max(recorded) and time.monotonic() < deadline:
            snap = handle.snapshot()
            if snap.tick in recorded:
                assert np.array_equal(snap.extras["qpos"], recorded.pop(snap.tick))
                compared += 1
            time.sleep(0.0005)
    assert compared > 0


def test_another_model_is_refused(session):
    path, _ = session
    recording = load_recording(path)
    recording.meta["signature"] = "0" * 40
    with pytest.raises(ReplayError, match="another model"):
        replay_inputs(recording)


def test_cli_check_and_dataset(session, tmp_path, capsys):
    path, _ = session
    assert main(["replay", str(path), "--check"]) == 0
    assert "bit-equal" in capsys.readouterr().out
    out = tmp_path / "d.hdf5"
    assert main(["replay", str(path), "--to-dataset", str(out)]) == 0
    recording = load_recording(path)
    with h5py.File(out) as f:
        g = f["data/demo_0"]
        n = len(recording.ticks) - 1
        assert g.attrs["num_samples"] == n and f["data"].attrs["total"] == n
        assert g["obs/PSM1_joint_pos"].shape == (n, 6) and g["actions"].shape == (n, 4)
        assert np.array_equal(g["states"][()], recording.qpos[:-1])
        assert np.array_equal(g["next_obs/PSM1_tip_pos"][:-1], g["obs/PSM1_tip_pos"][1:])
        # the action's jaw is the next jaw setpoint: the commanded 0.4 rad at the end
        assert g["actions"][-1, 3] == pytest.approx(0.4)
        assert not g.attrs["finished"] and g["dones"][-1] == 1  # (no task: one demo)


def test_to_dataset_refuses_files_without_a_demo(tmp_path):
    from davinci_sim.records.mcap_file import McapWriter

    with McapWriter(tmp_path / "e.mcap"):
        pass
    with pytest.raises(ValueError, match="no demo"):
        to_dataset([tmp_path / "e.mcap"], tmp_path / "d.hdf5")


def test_the_stereo_images_are_recorded_as_jpeg(tmp_path):
    """``serve --record-images``: each new stereo pair of the frames source as two
    foxglove.CompressedImage (a source of two synthetic pairs stands in for the render
    process, which the web console's tests start)."""
    import base64
    import io

    from PIL import Image

    from davinci_sim.sim.runtime.render import StereoFrame

    y, x = np.mgrid[0:480, 0:640]
    gradient = np.stack([x * 255 // 639, y * 255 // 479, (x + y) * 255 // 1118], axis=-1)
    pairs = [
        StereoFrame((gradient // k).astype(np.uint8), np.zeros((480, 640, 3), np.uint8),
                    tick=10 * k, time=0.01 * k, frame=k, render_time=0.0)
        for k in (1, 2)
    ]  # fmt: skip

    class Frames:
        stopped = False
        calls = 0

        def latest(self):
            Frames.calls += 1
            return pairs[min(Frames.calls - 1, 1)]

        def stop(self):
            Frames.stopped = True

    path = tmp_path / "images.mcap"
    description = recording_description(SystemDescription(scene="psm1", runner="thread"))
    system = build_system(description, start=True)
    recorder = SessionRecorder(path, description, frames=Frames())
    recorder.attach(system.handle)
    try:
        wait_ticks(system.handle, 50)
    finally:
        recorder.stop()
        system.stop()
    assert Frames.stopped and recorder.images == 2
    c = read_mcap(path)
    left, right = c.topic("/endoscope/left/compressed"), c.topic("/endoscope/right/compressed")
    assert len(left) == len(right) == 2
    assert c.schemas["/endoscope/left/compressed"] == "foxglove.CompressedImage"
    t, m = left[-1]
    assert m["format"] == "jpeg" and m["frame_id"] == "ECM/left" and t == right[-1][0] == 2e7
    image = Image.open(io.BytesIO(base64.b64decode(m["data"])))
    assert image.format == "JPEG" and image.size == (640, 480)
    decoded = np.asarray(image, dtype=float)
    assert np.abs(decoded - pairs[1].left).mean() < 2  # (the second pair, JPEG-lossy)


def test_a_session_of_the_process_runner_replays_too(tmp_path):
    """With the loop in its own process, the input log's calls come back as events."""
    path = tmp_path / "process.mcap"
    description = recording_description(
        SystemDescription(scene="psm1", home=True, runner="process", real_time=False)
    )
    system = build_system(description, start=True)
    handle = system.handle
    recorder = SessionRecorder(path, description).attach(handle)
    try:
        wait_ticks(handle, 200)
        T = handle.call("PSM1", "measured_cp").result(30).T.copy()
        for k in (1, 2):
            T[2, 3] += 0.002 * k
            handle.call("PSM1", "servo_cp", T.copy()).result(30)
            wait_ticks(handle, 50)
    finally:
        recorder.stop()
        system.stop()
    recording = load_recording(path)
    assert [c.method for c in recording.calls] == ["measured_cp", "servo_cp", "servo_cp"]
    check = replay_inputs(recording)
    assert check.bit_equal and check.calls == 3


def test_a_slower_state_rate_keeps_snapshots_apart(tmp_path):
    """``serve --record-rate 20``: states 50 ms apart at least; the calls all the same."""
    path = tmp_path / "slow.mcap"
    description = recording_description(
        SystemDescription(scene="psm1", runner="thread", real_time=False)
    )
    system = build_system(description, start=True)
    recorder = SessionRecorder(path, description, period=0.05).attach(system.handle)
    try:
        wait_ticks(system.handle, 400)
        system.handle.call("PSM1", "state_command", "enable").result(30)
        wait_ticks(system.handle, 20)
    finally:
        recorder.stop()
        system.stop()
    recording = load_recording(path)
    assert len(recording.ticks) >= 3 and np.diff(recording.ticks).min() >= 50
    assert [c.method for c in recording.calls] == ["state_command"]
    with pytest.raises(ValueError, match="> 0"):
        from davinci_sim.records.recording import recording_part

        recording_part(path, rate_hz=0.0)
