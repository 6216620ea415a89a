"""The pieces of a recording without a simulation: exact JSON of call arguments, the MCAP
writer and the reader of cut-off files, episodes to a dataset."""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pytest

from davinci_sim.records.dataset import to_dataset
from davinci_sim.records.episodes import EpisodeRecorder
from davinci_sim.records.jsonvalue import decode, encode
from davinci_sim.records.mcap_file import McapReadError, McapWriter, read_mcap
from davinci_sim.records.mcap_schemas import SCHEMAS, pose_fields
from davinci_sim.sim.types import CartesianPose


def roundtrip(value):
    return decode(json.loads(json.dumps(encode(value), allow_nan=False)))


def test_call_arguments_come_back_bit_for_bit():
    rng = np.random.default_rng(3)
    T = rng.standard_normal((4, 4))
    back = roundtrip([T, (1, "a", None), {"gripper": 0.1 + 0.2}, np.float32(0.3), [math.nan]])
    assert back[0].dtype == T.dtype and np.array_equal(back[0].view(np.int64), T.view(np.int64))
    assert back[1] == (1, "a", None) and back[2] == {"gripper": 0.1 + 0.2}
    assert back[3].dtype == np.float32 and back[3] == np.float32(0.3)
    assert math.isnan(back[4][0])
    q = np.array([1.0, math.inf, -math.inf, math.nan])
    r = roundtrip(q)
    assert np.array_equal(r[:3], q[:3]) and math.isnan(r[3])
    pose = CartesianPose(T, "ECM", "PSM1", 1.5)
    p = roundtrip(pose)
    assert isinstance(p, CartesianPose) and np.array_equal(p.T, T) and p.moving_frame == "PSM1"


def test_values_that_cannot_be_kept_are_refused():
    with pytest.raises(TypeError):
        encode(object())
    with pytest.raises(TypeError):
        encode({1: 2})
    with pytest.raises(TypeError):
        encode(np.array(["a"]))
    with pytest.raises(ValueError, match="not a class of davinci_sim"):
        decode({"__dataclass__": "os:system", "fields": {}})


def test_pose_fields_is_the_rotation_as_a_unit_quaternion():
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("xyz", [0.3, -0.2, 1.1])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R.as_matrix(), [1, 2, 3]
    p, q = pose_fields(T)
    back = Rotation.from_quat([q["x"], q["y"], q["z"], q["w"]])
    assert (back.inv() * R).magnitude() < 1e-12
    assert (p["x"], p["y"], p["z"]) == (1, 2, 3)


def test_foxglove_schemas_have_the_fields_foxglove_reads():
    tf = SCHEMAS["foxglove.FrameTransforms"]["properties"]["transforms"]["items"]["properties"]
    assert set(tf) == {"timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"}
    pose = SCHEMAS["foxglove.PoseInFrame"]["properties"]
    assert set(pose) == {"timestamp", "frame_id", "pose"}
    assert set(SCHEMAS["foxglove.CompressedImage"]["properties"]) == {
        "timestamp", "frame_id", "data", "format"}  # fmt: skip


def write_file(path, n=400, chunk_size=4000):
    with McapWriter(path, chunk_size=chunk_size) as w:
        w.attach("task.yaml", "text/yaml", b"name: t\n")
        w.metadata("davinci_sim", {"kind": "test", "n": n})
        for i in range(n):
            w.write("/x", "davinci_sim.Qpos", i * 1000, {"tick": i, "qpos": [i * 0.5] * 8})


def test_a_cut_off_file_reads_up_to_its_last_whole_chunk(tmp_path):
    path = tmp_path / "full.mcap"
    write_file(path)
    full = read_mcap(path)
    assert full.complete and full.problem is None
    assert [m["tick"] for _, m in full.topic("/x")] == list(range(400))
    assert (
        full.schemas["/x"] == "davinci_sim.Qpos" and full.attachments["task.yaml"] == b"name: t\n"
    )
    assert full.metadata["davinci_sim"] == {"kind": "test", "n": "400"}
    data = path.read_bytes()
    counts = []
    for cut in range(64, len(data), 97):  # any cut after the header: a prefix, never an error
        part = tmp_path / "cut.mcap"
        part.write_bytes(data[:cut])
        got = read_mcap(part)
        ticks = [m["tick"] for _, m in got.topic("/x")]
        assert ticks == list(range(len(ticks)))
        assert not got.complete and got.problem is not None
        counts.append(len(ticks))
    # Chunks of ~4 kB: cuts inside the data keep the whole chunks before them; cuts in the
    # summary after the data keep every message.
    assert counts == sorted(counts) and counts[0] == 0 and counts[-1] == 400
    assert len(set(counts)) > 5
    (tmp_path / "empty.mcap").write_bytes(b"")
    with pytest.raises(McapReadError):
        read_mcap(tmp_path / "empty.mcap")


def test_a_chunk_is_closed_after_the_flush_period(tmp_path):
    now = [0.0]
    path = tmp_path / "f.mcap"
    w = McapWriter(path, flush_period=1.0, clock=lambda: now[0])
    for i in range(5):
        now[0] = i * 0.3  # 0, 0.3 .. 1.2 s: the chunk closes at the message at 1.2 s
        w.write("/x", "davinci_sim.Qpos", i, {"tick": i, "qpos": []})
    assert [m["tick"] for _, m in read_mcap(path).topic("/x")] == [0, 1, 2, 3, 4]
    w.close()


def test_episodes_become_robomimic_demos(tmp_path):
    path = tmp_path / "ep.mcap"
    rng = np.random.default_rng(0)
    expected = []
    with EpisodeRecorder(path, env_id="Test-v0", dt=0.05) as rec:
        for length in (5, 3):
            obs = {"tip": rng.standard_normal(3), "joints": rng.standard_normal(6)}
            rec.reset(obs, {})
            ep = {"obs": [obs], "act": [], "rew": []}
            for k in range(length):
                a = rng.standard_normal(4)
                obs = {"tip": rng.standard_normal(3), "joints": rng.standard_normal(6)}
                r = float(k)
                rec.step(obs, a, r, k == length - 1, False, {"distance": 0.1})
                ep["obs"].append(obs), ep["act"].append(a), ep["rew"].append(r)
            expected.append(ep)
    out = tmp_path / "d.hdf5"
    summary = to_dataset([path], out)
    assert (summary.demos, summary.steps) == (2, 8)
    with h5py.File(out) as f:
        assert f["data"].attrs["total"] == 8
        assert json.loads(f["data"].attrs["env_args"])[0]["env_id"] == "Test-v0"
        for i, ep in enumerate(expected):
            g = f[f"data/demo_{i}"]
            T = len(ep["act"])
            assert g.attrs["num_samples"] == T and bool(g.attrs["finished"])
            assert np.array_equal(g["obs/tip"][()], [o["tip"] for o in ep["obs"][:-1]])
            assert np.array_equal(g["next_obs/joints"][()], [o["joints"] for o in ep["obs"][1:]])
            assert np.array_equal(g["actions"][()], ep["act"])
            assert np.array_equal(g["rewards"][()], ep["rew"])
            assert g["dones"][()].tolist() == [0] * (T - 1) + [1]
        assert [n.decode() for n in f["mask/finished"][()]] == ["demo_0", "demo_1"]


def test_a_session_splits_into_one_demo_per_repetition(tmp_path):
    """A session's demos end where the task reports a finished repetition (reward 1 at
    that step); the rest after the last report is an unfinished demo. Actions: the
    setpoint tip's displacement (camera frame) and the next jaw setpoint."""
    from davinci_sim.records.mcap_schemas import stamp

    path = tmp_path / "s.mcap"
    n, dt = 12, 0.01
    tips = [[0.001 * k, -0.002 * k, 0.1 + 0.0005 * k * k] for k in range(n)]
    with McapWriter(path) as w:
        w.metadata("davinci_sim", {"kind": "session"})
        for k in range(n):
            t, ns = stamp(k * dt), int(round(k * dt * 1e9))
            w.write("/sim/qpos", "davinci_sim.Qpos", ns, {"tick": 10 * k, "qpos": [k, -k]})
            js = {"timestamp": t, "tick": 10 * k, "name": list("abcdef"), "position": [k] * 6,
                  "velocity": [], "effort": []}  # fmt: skip
            w.write("/PSM1/measured_js", "davinci_sim.JointState", ns, js)
            setpoint = {**js, "position": [2 * k] * 6}
            w.write("/PSM1/setpoint_js", "davinci_sim.JointState", ns, setpoint)
            w.write("/PSM1/jaw/setpoint_js", "davinci_sim.JointState", ns,
                    {**js, "name": ["jaw"], "position": [0.1 * k]})  # fmt: skip
            for topic, p in (("measured_cp", [0, 0, k]), ("setpoint_cp", tips[k])):
                pose = {"position": dict(zip("xyz", p, strict=True)),
                        "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}  # fmt: skip
                w.write(f"/PSM1/{topic}", "foxglove.PoseInFrame", ns,
                        {"timestamp": t, "frame_id": "ECM", "pose": pose})  # fmt: skip
            state = {"timestamp": t, "tick": 10 * k, "state": {"distance_to_path": 0.01 * k}}
            w.write("/task/state", "davinci_sim.State", ns, state)
        for k in (3.5, 7.2):  # two repetitions finish between snapshots 3-4 and 7-8
            w.write("/task/results", "davinci_sim.Event", int(k * dt * 1e9),
                    {"timestamp": stamp(k * dt), "source": "task", "event": "results",
                     "payload": {"repetition": 1}})  # fmt: skip
    out = tmp_path / "d.hdf5"
    assert to_dataset([path], out).demos == 3
    with h5py.File(out) as f:
        demos = [f[f"data/demo_{i}"] for i in range(3)]
        assert [g.attrs["num_samples"] for g in demos] == [4, 4, 3]
        assert [bool(g.attrs["finished"]) for g in demos] == [True, True, False]
        assert demos[0]["rewards"][()].tolist() == [0, 0, 0, 1]
        assert demos[1]["rewards"][()].tolist() == [0, 0, 0, 1]
        assert demos[2]["rewards"][()].tolist() == [0, 0, 0]
        actions = np.concatenate([g["actions"][()] for g in demos])
        expected = np.diff(np.array(tips), axis=0)
        assert np.allclose(actions[:, :3], expected, atol=0, rtol=1e-12)
        assert np.allclose(actions[:, 3], 0.1 * np.arange(1, n))
        joint = np.concatenate([g["actions_joint"][()] for g in demos])
        assert joint[:, 0].tolist() == [2 * k for k in range(1, n)]
        states = np.concatenate([g["states"][()] for g in demos])
        assert states[:, 0].tolist() == list(range(n - 1))
        assert demos[1]["obs/task_distance"][0, 0] == pytest.approx(0.04)
        assert demos[1]["obs/PSM1_tip_pos"][0].tolist() == [0, 0, 4]
        assert demos[1]["next_obs/PSM1_tip_pos"][-1].tolist() == [0, 0, 8]


def test_a_recorded_description_may_name_no_other_code():
    """``description.pickle`` is read with a restricted unpickler: the simulator's own
    dataclasses and numpy arrays come back, anything else is refused."""
    import os
    import pickle

    from davinci_sim.records.replay import safe_unpickle
    from davinci_sim.system import SystemDescription, TaskDescription

    d = SystemDescription(scene="psm1", task=TaskDescription("seed_path", condition="B=40"))
    assert safe_unpickle(pickle.dumps(d)) == d
    assert np.array_equal(safe_unpickle(pickle.dumps(np.eye(3))), np.eye(3))

    class Evil:
        def __reduce__(self):
            return (os.system, ("true",))

    with pytest.raises(pickle.UnpicklingError, match="may not name"):
        safe_unpickle(pickle.dumps(Evil()))
