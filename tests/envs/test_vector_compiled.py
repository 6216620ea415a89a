"""The vector environment's compiled control period (:class:`~davinci_sim.sim.rows_chunk.ArmChunk`)
against its Python ticks (the batch laws, the oracle): the same actions give the same
observations, rewards, episode ends and task metrics to 1e-12, with the kernel's stops
(a tick it hands to Python) and tracking faults on the way."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from davinci_sim.envs import ENVIRONMENTS  # noqa: E402
from davinci_sim.envs.vector import DavinciVectorEnv  # noqa: E402
from davinci_sim.sim import rows_chunk  # noqa: E402
from davinci_sim.sim.rows_chunk import ArmChunk  # noqa: E402

pytestmark = pytest.mark.skipif(not rows_chunk.COMPILED, reason="needs numba")

ATOL = 1e-12


def _pair(n: int, physics: str = "full", **kw) -> tuple[DavinciVectorEnv, DavinciVectorEnv]:
    """A compiled environment and one on the Python ticks, same configuration."""
    compiled = DavinciVectorEnv(n, physics=physics, **kw)
    python = DavinciVectorEnv(n, physics=physics, **kw)
    assert compiled._chunk is not None
    python._chunk = None
    return compiled, python


def _assert_same(a: tuple, b: tuple) -> None:
    obs_a, rew_a, term_a, trunc_a, info_a = a
    obs_b, rew_b, term_b, trunc_b, info_b = b
    for k in obs_a:
        np.testing.assert_allclose(obs_a[k], obs_b[k], rtol=0, atol=ATOL, err_msg=k)
    np.testing.assert_allclose(rew_a, rew_b, rtol=0, atol=ATOL)
    np.testing.assert_array_equal(term_a, term_b)
    np.testing.assert_array_equal(trunc_a, trunc_b)
    assert info_a.keys() == info_b.keys()
    for k in info_a:
        if not k.startswith("_") and k not in ("final_obs", "final_info"):
            np.testing.assert_allclose(info_a[k], info_b[k], rtol=0, atol=ATOL, err_msg=k)


def _run(envs, steps: int, seed: int = 3, before_step=None) -> list[tuple]:
    """Steps both with the same random actions, equal at every step; the compiled steps."""
    compiled, python = envs
    out = []
    try:
        obs_a, obs_b = compiled.reset(seed=7)[0], python.reset(seed=7)[0]
        for k in obs_a:
            np.testing.assert_allclose(obs_a[k], obs_b[k], rtol=0, atol=ATOL, err_msg=k)
        rng = np.random.default_rng(seed)
        for i in range(steps):
            a = rng.uniform(-1, 1, compiled.action_space.shape)
            if before_step is not None:
                before_step(i, compiled, python)
            out.append(compiled.step(a))
            _assert_same(out[-1], python.step(a))
    finally:
        compiled.close()
        python.close()
    return out


@pytest.mark.parametrize(
    ("env_id", "action_space", "physics"),
    [
        ("DavinciSim/Reach-v0", "cartesian", "full"),
        ("DavinciSim/Reach-v0", "joint", "psm"),
        ("DavinciSim/PathFollow-v0", "cartesian", "full"),
    ],
)
def test_compiled_period_equals_the_python_ticks(env_id, action_space, physics):
    kw = {**ENVIRONMENTS[env_id], "action_space": action_space, "max_episode_steps": 4}
    _run(_pair(3, physics, **kw), steps=9)  # (autoresets on the way)


def test_a_row_the_kernel_stops_runs_that_tick_in_python(monkeypatch):
    """A singular Jacobian has no compiled solve: the kernel stops the row before that
    tick, the Python tick runs it (least squares), and the kernel goes on from the next."""
    kw = {**ENVIRONMENTS["DavinciSim/Reach-v0"], "max_episode_steps": 50}
    handed = []
    python_tick = DavinciVectorEnv._python_tick

    def counting(self, ramp, k, running, fault, T_goal):
        if self._chunk is not None:
            handed.append((k, np.flatnonzero(running).tolist()))
        return python_tick(self, ramp, k, running, fault, T_goal)

    def singular_row_1(i, compiled, python):
        if i in (1, 3):
            compiled.J_psm[1] = 0.0
            python.J_psm[1] = 0.0

    monkeypatch.setattr(DavinciVectorEnv, "_python_tick", counting)
    _run(_pair(3, **kw), steps=5, before_step=singular_row_1)
    assert handed == [(1, [1]), (1, [1])]


def test_a_tracking_fault_stops_the_row_at_the_same_tick():
    kw = {**ENVIRONMENTS["DavinciSim/Reach-v0"], "max_episode_steps": 50}
    compiled, python = _pair(3, **kw)
    # A tolerance no servo keeps while moving (10 µrad, 10 µm): moving rows fault after 50 ms.
    tiny = np.full(6, 1e-5)
    compiled.tolerance = python.tolerance = tiny
    compiled._chunk = ArmChunk(
        compiled._stepper, compiled._servo, compiled.chain, compiled.psm_act, compiled.psm_q,
        tiny, compiled.T_camera_rcm, copy_gravcomp=compiled._gravcomp,
        timestep=compiled.model.opt.timestep,
    )  # fmt: skip
    steps = _run((compiled, python), steps=6)
    faulted = np.array([info["fault"] for *_, info in steps])
    assert faulted.any()
