"""Recording wrappers: what a rollout of Reach (single, and vector with both autoreset
modes) returned is what the MCAP file holds, episode by episode, and the dataset converter
turns the files into one demo per episode."""

from __future__ import annotations

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")
h5py = pytest.importorskip("h5py")

import davinci_sim.envs  # noqa: E402,F401 (registers the ids)
from davinci_sim.envs import RecordEpisodes, RecordVectorEpisodes  # noqa: E402
from davinci_sim.envs.recording import row_file  # noqa: E402
from davinci_sim.envs.vector import DavinciVectorEnv  # noqa: E402
from davinci_sim.records.dataset import to_dataset  # noqa: E402
from davinci_sim.records.mcap_file import read_mcap  # noqa: E402

STEPS = 3  # max_episode_steps: short episodes, several per file


def _episodes(contents) -> list[list[dict]]:
    """The file's ``/episode/step`` messages grouped by episode, in order."""
    out: dict[int, list[dict]] = {}
    for _, m in contents.topic("/episode/step"):
        out.setdefault(m["episode"], []).append(m)
    assert list(out) == list(range(len(out)))
    return [out[e] for e in range(len(out))]


def _check(recorded: list[dict], expected: dict) -> None:
    """One recorded episode against what the environment returned: its first observation,
    then per step the action, observation, reward and end flags."""
    assert [m["step"] for m in recorded] == list(range(len(recorded)))
    first = recorded[0]
    assert first["action"] is None and first["reward"] is None
    np.testing.assert_array_equal(
        first["observation"]["tip_position"], expected["obs0"]["tip_position"]
    )
    steps = expected["steps"]
    assert len(recorded) - 1 == len(steps)
    for m, (obs, action, reward, term, trunc) in zip(recorded[1:], steps, strict=True):
        np.testing.assert_array_equal(np.asarray(m["action"]), np.asarray(action))
        assert m["reward"] == pytest.approx(float(reward), rel=0, abs=0)
        assert (m["terminated"], m["truncated"]) == (bool(term), bool(trunc))
        for k in ("tip_position", "joint_position", "target"):
            np.testing.assert_array_equal(m["observation"][k], obs[k], err_msg=k)


def _demos(path) -> list[int]:
    with h5py.File(path) as h5:
        names = sorted(h5["data"], key=lambda s: int(s.split("_")[1]))
        return [int(h5["data"][n].attrs["num_samples"]) for n in names]


def test_single_environment_episodes_to_mcap_and_dataset(tmp_path):
    env = RecordEpisodes(gym.make("DavinciSim/Reach-v0", max_episode_steps=STEPS), tmp_path)
    rng = np.random.default_rng(1)
    expected = []
    try:
        for episode in range(3):
            obs, _ = env.reset(seed=10 + episode)
            ep = {"obs0": obs, "steps": []}
            done = False
            while not done:
                action = env.action_space.sample() if episode else rng.uniform(-1, 1, 4)
                obs, r, term, trunc, _ = env.step(action)
                ep["steps"].append((obs, action, r, term, trunc))
                done = term or trunc
            expected.append(ep)
    finally:
        env.close()
    contents = read_mcap(tmp_path / "episodes.mcap")
    assert contents.complete
    meta = contents.metadata["davinci_sim"]
    assert meta["kind"] == "episodes" and meta["env_id"] == "DavinciSim/Reach-v0"
    assert "env_kwargs" in meta
    episodes = _episodes(contents)
    assert len(episodes) == 3
    for recorded, exp in zip(episodes, expected, strict=True):
        _check(recorded, exp)
    # The snapshots: one per reset and step, on the steps' time line (Foxglove's 3-D panel).
    n_messages = sum(len(e) for e in episodes)
    step_times = [t for t, _ in contents.topic("/episode/step")]
    tf_times = [t for t, _ in contents.topic("/tf")]
    assert tf_times == step_times and len(tf_times) == n_messages
    assert np.all(np.diff(step_times) > 0)
    assert contents.schemas["/tf"] == "foxglove.FrameTransforms"
    assert len(contents.topic("/sim/qpos")) == n_messages
    # The tip in the recorded pose is the observed one (both in the camera frame).
    _, pose = contents.topic("/PSM1/measured_cp")[-1]
    p = pose["pose"]["position"]
    tip = expected[-1]["steps"][-1][0]["tip_position"]
    np.testing.assert_allclose([p["x"], p["y"], p["z"]], tip, atol=1e-12)

    summary = to_dataset([tmp_path / "episodes.mcap"], tmp_path / "d.hdf5")
    assert summary.demos == 3
    assert _demos(tmp_path / "d.hdf5") == [len(e["steps"]) for e in expected]
    with h5py.File(tmp_path / "d.hdf5") as h5:
        d0 = h5["data/demo_0"]
        actions = np.array([s[1] for s in expected[0]["steps"]])
        np.testing.assert_array_equal(d0["actions"][:], actions)
        np.testing.assert_array_equal(d0["rewards"][:], [s[2] for s in expected[0]["steps"]])
        assert list(d0["dones"][:]) == [0] * (len(actions) - 1) + [1]
        np.testing.assert_array_equal(
            d0["next_obs/tip_position"][-1], expected[0]["steps"][-1][0]["tip_position"]
        )


def _row(obs: dict, i: int) -> dict:
    return {k: v[i] for k, v in obs.items()}


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_vector_rows_episodes_to_mcap_and_dataset(tmp_path, mode):
    n, ticks = 2, 2 * STEPS + 2
    vec = DavinciVectorEnv(n, autoreset_mode=mode, max_episode_steps=STEPS)
    env = RecordVectorEpisodes(vec, tmp_path)
    rng = np.random.default_rng(2)
    # What the environment returned, split into episodes by Gymnasium's convention.
    rows: list[list[dict]] = [[] for _ in range(n)]
    pending = [False] * n
    try:
        obs, _ = env.reset(seed=4)
        for i in range(n):
            rows[i].append({"obs0": _row(obs, i), "steps": []})
        for _ in range(ticks):
            actions = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
            obs, reward, term, trunc, info = env.step(actions)
            for i in range(n):
                if mode == "NextStep" and pending[i]:
                    assert reward[i] == 0.0 and not (term[i] or trunc[i])
                    rows[i].append({"obs0": _row(obs, i), "steps": []})
                    pending[i] = False
                    continue
                ended = bool(term[i] or trunc[i])
                last = info["final_obs"][i] if mode == "SameStep" and ended else _row(obs, i)
                rows[i][-1]["steps"].append((last, actions[i], reward[i], term[i], trunc[i]))
                if ended and mode == "SameStep":
                    rows[i].append({"obs0": _row(obs, i), "steps": []})
                pending[i] = ended
    finally:
        env.close()
    assert all(len(r) >= 3 for r in rows)  # (episodes of STEPS steps at most)
    total_demos = 0
    for i in range(n):
        contents = read_mcap(tmp_path / row_file(i))
        assert contents.complete
        episodes = _episodes(contents)
        assert len(episodes) == len(rows[i])
        for recorded, exp in zip(episodes, rows[i], strict=True):
            _check(recorded, exp)
        assert len(contents.topic("/tf")) == len(contents.topic("/episode/step"))
        _, pose = contents.topic("/PSM1/measured_cp")[-1]
        p = pose["pose"]["position"]
        np.testing.assert_allclose([p["x"], p["y"], p["z"]], obs["tip_position"][i], atol=1e-12)
        total_demos += sum(1 for e in rows[i] if e["steps"])
    summary = to_dataset([tmp_path / row_file(i) for i in range(n)], tmp_path / "v.hdf5")
    assert summary.demos == total_demos
    assert sum(_demos(tmp_path / "v.hdf5")) == sum(len(e["steps"]) for r in rows for e in r)


def test_vector_recording_refuses_disabled_autoreset(tmp_path):
    class Fake(gym.vector.VectorEnv):
        metadata = {"autoreset_mode": "Disabled"}
        num_envs = 1

    with pytest.raises(ValueError, match="NEXT_STEP or SAME_STEP"):
        RecordVectorEpisodes(Fake(), tmp_path)
    assert not any(tmp_path.iterdir())
