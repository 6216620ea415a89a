"""Environments spread over local Ray workers equal the same rows in one vector environment."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gymnasium")
ray = pytest.importorskip("ray")

from davinci_sim.envs import make_vector  # noqa: E402
from davinci_sim.envs.ray_envs import RayVectorEnv  # noqa: E402


def test_ray_workers_give_the_rows_of_one_vector_env():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        spread = RayVectorEnv("DavinciSim/Reach-v0", workers=2, envs_per_worker=2,
                              max_episode_steps=3)  # fmt: skip
        local = make_vector("DavinciSim/Reach-v0", 4, max_episode_steps=3)
        obs_r, _ = spread.reset(seed=7)
        obs_l, _ = local.reset(seed=7)
        for k in obs_l:
            np.testing.assert_array_equal(obs_r[k], obs_l[k], err_msg=k)
        rng = np.random.default_rng(0)
        for _ in range(5):  # through a truncation and the autoreset after it
            a = rng.uniform(-1, 1, local.action_space.shape).astype(np.float32)
            obs_r, rew_r, term_r, trunc_r, info_r = spread.step(a)
            obs_l, rew_l, term_l, trunc_l, info_l = local.step(a)
            for k in obs_l:
                np.testing.assert_array_equal(obs_r[k], obs_l[k], err_msg=k)
            np.testing.assert_array_equal(rew_r, rew_l)
            np.testing.assert_array_equal(trunc_r, trunc_l)
            np.testing.assert_array_equal(term_r, term_l)
            np.testing.assert_array_equal(info_r["reward_distance"], info_l["reward_distance"])
        assert spread.num_envs == 4 and spread.action_space.shape == (4, 4)
        spread.close()
        local.close()
    finally:
        ray.shutdown()


def test_ray_vector_env_refuses_bad_settings():
    with pytest.raises(ValueError, match="runs"):
        RayVectorEnv("DavinciSim/PegTransfer-v0")
    with pytest.raises(ValueError, match="workers"):
        RayVectorEnv("DavinciSim/Reach-v0", workers=0)
