"""The vector environment on the batch laws against N single environments on the live
simulation: the same seeds and actions give the same observations, rewards and episode
ends, autoresets included."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gymnasium")

import davinci_sim.sim.simulation as simulation  # noqa: E402
from davinci_sim.envs import ENVIRONMENTS, make_vector  # noqa: E402
from davinci_sim.envs.base import DavinciEnv  # noqa: E402
from davinci_sim.envs.vector import DavinciVectorEnv  # noqa: E402


def _compare(
    env_id: str, action_space: str, steps: int, n: int = 3, physics: str = "full",
    atol: float = 1e-9,
) -> int:  # fmt: skip
    """Steps ``n`` single environments and a vector of ``n`` (with ``physics``) with the same
    random actions, their observations and rewards equal within ``atol``; returns how many
    autoresets happened."""
    kw = {**ENVIRONMENTS[env_id], "action_space": action_space, "max_episode_steps": 5}
    vec = DavinciVectorEnv(n, physics=physics, **kw)
    singles = [DavinciEnv(**kw) for _ in range(n)]
    try:
        obs_v, _ = vec.reset(seed=20)
        for i, env in enumerate(singles):
            obs, _ = env.reset(seed=20 + i)
            for k in obs:
                np.testing.assert_allclose(obs_v[k][i], obs[k], rtol=0, atol=atol, err_msg=k)
        rng = np.random.default_rng(5)
        pending = [False] * n
        resets = 0
        for _ in range(steps):
            actions = rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32)
            obs_v, reward_v, term_v, trunc_v, info_v = vec.step(actions)
            for i, env in enumerate(singles):
                if pending[i]:  # NEXT_STEP: this step resets the row, its action ignored
                    obs, _ = env.reset()
                    reward, term, trunc = 0.0, False, False
                    pending[i] = False
                    resets += 1
                else:
                    obs, reward, term, trunc, info = env.step(actions[i])
                    pending[i] = term or trunc
                    assert info["is_success"] == info_v["is_success"][i]
                for k in obs:
                    np.testing.assert_allclose(obs_v[k][i], obs[k], rtol=0, atol=atol, err_msg=k)
                assert reward_v[i] == pytest.approx(reward, rel=1e-9, abs=atol)
                assert (term_v[i], trunc_v[i]) == (term, trunc)
        return resets
    finally:
        vec.close()
        for env in singles:
            env.close()


@pytest.fixture
def held_frames(monkeypatch):
    """The live simulation holding the base frames as the batch does (see envs.vector)."""
    monkeypatch.setattr(simulation, "BASE_FRAME_TOLERANCE", np.inf)


@pytest.mark.parametrize(
    ("env_id", "action_space"),
    [("DavinciSim/Reach-v0", "cartesian"), ("DavinciSim/Reach-v0", "joint"),
     ("DavinciSim/PathFollow-v0", "cartesian")],
)  # fmt: skip
def test_vector_env_equals_single_envs_step_by_step(held_frames, env_id, action_space):
    resets = _compare(env_id, action_space, steps=13)
    assert resets >= 3  # every row truncated (5 steps) and came back at least once


def test_autoreset_is_next_step(held_frames):
    import gymnasium as gym

    vec = gym.make_vec("DavinciSim/Reach-v0", num_envs=2, vectorization_mode="vector_entry_point",
                       max_episode_steps=2)  # fmt: skip
    try:
        assert isinstance(vec, DavinciVectorEnv)
        obs0, _ = vec.reset(seed=1)
        zero = np.zeros(vec.action_space.shape, dtype=np.float32)
        vec.step(zero)
        _, _, term, trunc, _ = vec.step(zero)
        assert trunc.all() and not term.any()
        obs, reward, term, trunc, info = vec.step(np.ones_like(zero))  # ignored: a reset
        np.testing.assert_array_equal(reward, 0.0)
        assert not term.any() and not trunc.any() and not info["_is_success"].any()
        np.testing.assert_allclose(obs["tip_position"], obs0["tip_position"], atol=1e-12)
        assert not np.allclose(obs["target"], obs0["target"])  # a new episode, new targets
        np.testing.assert_array_equal(vec.steps, 0)
    finally:
        vec.close()


def test_vector_env_refuses_what_it_does_not_run():
    with pytest.raises(ValueError, match="runs"):
        make_vector("DavinciSim/PegTransfer-v0", 2)
    with pytest.raises(ValueError, match="num_envs"):
        DavinciVectorEnv(0)
    with pytest.raises(ValueError, match="images"):
        DavinciVectorEnv(2, images=True)


def test_same_step_autoreset_returns_the_new_episode_and_keeps_the_last(held_frames):
    vec = DavinciVectorEnv(2, autoreset_mode="SameStep", max_episode_steps=2)
    ref = DavinciVectorEnv(2, max_episode_steps=100)  # (NEXT_STEP: the last observation)
    try:
        obs0, _ = vec.reset(seed=3)
        ref.reset(seed=3)
        a = np.full(vec.action_space.shape, 0.5, dtype=np.float32)
        vec.step(a)
        ref.step(a)
        obs, reward, term, trunc, info = vec.step(a)
        last, reward_ref, *_ = ref.step(a)
        assert trunc.all() and info["_final_obs"].all()
        for i in range(2):  # the last observation in info, the new episode's first returned
            np.testing.assert_array_equal(info["final_obs"][i]["tip_position"],
                                          last["tip_position"][i])  # fmt: skip
        np.testing.assert_array_equal(reward, reward_ref)
        np.testing.assert_allclose(obs["tip_position"], obs0["tip_position"], atol=1e-12)
        assert not np.allclose(obs["target"], obs0["target"])
        with pytest.raises(ValueError, match="autoreset_mode"):
            DavinciVectorEnv(1, autoreset_mode="Disabled")
    finally:
        vec.close()
        ref.close()


def test_threads_step_the_same_physics():
    one = DavinciVectorEnv(5, max_episode_steps=4)
    two = DavinciVectorEnv(5, threads=2, max_episode_steps=4)
    try:
        a_obs, _ = one.reset(seed=0)
        b_obs, _ = two.reset(seed=0)
        rng = np.random.default_rng(2)
        for _ in range(6):
            a = rng.uniform(-1, 1, one.action_space.shape).astype(np.float32)
            a_obs, a_rew, *_ = one.step(a)
            b_obs, b_rew, *_ = two.step(a)
            for k in a_obs:
                np.testing.assert_array_equal(a_obs[k], b_obs[k], err_msg=k)
            np.testing.assert_array_equal(a_rew, b_rew)
    finally:
        one.close()
        two.close()
