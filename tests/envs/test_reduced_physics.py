"""The vector environment's reduced physics (envs/reduced.py): ``psm`` (the ECM's branch
welded) equals single environments on the full scene to rounding; ``arm`` (the PSM's setup
joints welded too) stays within the stated tolerance of them."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

pytest.importorskip("gymnasium")

import davinci_sim.sim.simulation as simulation  # noqa: E402
from davinci_sim.envs import ENVIRONMENTS  # noqa: E402
from davinci_sim.envs.base import DavinciEnv  # noqa: E402
from davinci_sim.envs.vector import DavinciVectorEnv  # noqa: E402

#: ``physics="arm"`` against the full scene: the tool tip within this, m (the setup joints'
#: yield the welded scene leaves out: ~0.3 mm after 30 random actions), the joints within
#: ARM_JOINT_TOLERANCE (rad, m).
ARM_TIP_TOLERANCE = 1e-3
ARM_JOINT_TOLERANCE = 5e-3


@pytest.fixture
def held_frames(monkeypatch):
    """The live simulation holding the base frames as the batch does (see envs.vector)."""
    monkeypatch.setattr(simulation, "BASE_FRAME_TOLERANCE", np.inf)


def _run(env_id: str, physics: str, steps: int, n: int = 2):
    """The vector environment (``physics``) and ``n`` single ones, the same seeds and random
    actions; yields (row, vector obs row, vector reward, single's step) per row and step."""
    kw = {**ENVIRONMENTS[env_id], "max_episode_steps": 5}
    vec = DavinciVectorEnv(n, physics=physics, **kw)
    singles = [DavinciEnv(**kw) for _ in range(n)]
    out = []
    try:
        vec.reset(seed=7)
        for i, env in enumerate(singles):
            env.reset(seed=7 + i)
        rng = np.random.default_rng(3)
        pending = [False] * n
        for _ in range(steps):
            a = rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32)
            obs_v, reward_v, term_v, trunc_v, _ = vec.step(a)
            for i, env in enumerate(singles):
                if pending[i]:
                    obs, reward, term, trunc = env.reset()[0], 0.0, False, False
                    pending[i] = False
                else:
                    obs, reward, term, trunc, _ = env.step(a[i])
                    pending[i] = term or trunc
                row = {k: v[i] for k, v in obs_v.items()}
                out.append((row, reward_v[i], (term_v[i], trunc_v[i]), obs, reward, (term, trunc)))
        return vec, out
    finally:
        vec.close()
        for env in singles:
            env.close()


@pytest.mark.parametrize("env_id", ["DavinciSim/Reach-v0", "DavinciSim/PathFollow-v0"])
def test_psm_physics_equals_the_full_scene(held_frames, env_id):
    vec, rows = _run(env_id, "psm", steps=12)
    assert vec.model.nv == 14  # (24 less the ECM and its setup joints)
    for obs_v, r_v, ends_v, obs, r, ends in rows:
        for k in obs:
            np.testing.assert_allclose(obs_v[k], obs[k], rtol=0, atol=1e-9, err_msg=k)
        assert r_v == pytest.approx(r, rel=1e-9, abs=1e-9)
        assert ends_v == ends


def test_arm_physics_stays_within_the_stated_tolerance(held_frames):
    vec, rows = _run("DavinciSim/Reach-v0", "arm", steps=12)
    assert vec.model.nv == 8  # the PSM's six joints and the jaw's two fingers
    for obs_v, _, ends_v, obs, _, ends in rows:
        d = np.linalg.norm(obs_v["tip_position"] - obs["tip_position"])
        assert d <= ARM_TIP_TOLERANCE
        np.testing.assert_allclose(
            obs_v["joint_position"], obs["joint_position"], rtol=0, atol=ARM_JOINT_TOLERANCE
        )
        np.testing.assert_array_equal(obs_v["target"], obs["target"])
        assert ends_v == ends


def test_welded_bodies_stay_where_the_start_has_them():
    full = DavinciVectorEnv(1)
    arm = DavinciVectorEnv(1, physics="arm")
    try:
        d_full, d_arm = full._data0, mujoco.MjData(arm.model)
        mujoco.mj_copyData(d_arm, arm.model, arm._data0)
        mujoco.mj_kinematics(full.model, d_full)
        mujoco.mj_kinematics(arm.model, d_arm)
        for b in range(arm.model.nbody):
            name = arm.model.body(b).name
            np.testing.assert_allclose(
                d_arm.xpos[b], d_full.xpos[full.model.body(name).id], atol=1e-9, err_msg=name
            )
        assert {arm.model.joint(j).name.split("/")[0] for j in range(arm.model.njnt)} == {"PSM1"}
    finally:
        full.close()
        arm.close()


def test_unknown_physics_is_refused():
    with pytest.raises(ValueError, match="physics"):
        DavinciVectorEnv(1, physics="fast")
