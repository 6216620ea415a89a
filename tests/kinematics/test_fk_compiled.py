"""The forward-kinematics kernel (``kinematics.fk_compiled``, numba) compiled and as plain
Python (the fallback when numba is missing, switched off or fails to compile): the same
operations, so the same bits; a row's bits do not depend on its batch; and the public API is
that kernel. (Against independent references: ``test_fk_batch``, ``test_fk_reference``,
``test_jacobians``.)"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from davinci_sim.kinematics import fk, fk_compiled
from davinci_sim.kinematics import jit as _jit
from davinci_sim.kinematics.arms import load_arm, load_suj
from davinci_sim.sim.arms import suj_arm_kinematics


def _chains():
    arms = [load_arm(n).chain for n in ("PSM1", "ECM", "MTMR")]
    return arms + [suj_arm_kinematics(s).chain for s in load_suj().values()]


def test_compiled_and_python_kernel_give_the_same_bits_alone_and_in_a_batch():
    """Both conventions (the SUJ chains are standard DH, the arms modified), tool offsets."""
    rng = np.random.default_rng(1)
    for chain in _chains():
        cc = fk._consts(chain)
        Q = rng.uniform(chain.qmin, chain.qmax, (50, chain.dof))
        out = {}
        for name, run in (
            ("compiled", fk_compiled.tip_poses),
            ("python", fk_compiled.tip_poses.py_func),
        ):
            T, J, F = (
                np.empty((50, 4, 4)),
                np.empty((50, 6, chain.dof)),
                np.empty((50, chain.dof, 12)),
            )
            run(*cc.packed, Q, T, J, True, F)
            out[name] = T, J, F
        for a, b in zip(out["compiled"], out["python"], strict=True):
            assert np.array_equal(a, b), chain.name
        T, J, F = out["compiled"]
        for i in range(0, 50, 7):  # one configuration alone, through the public API
            T_api, J_api = fk.forward_kinematics_and_jacobian(chain, Q[i])
            assert np.array_equal(T_api, T[i]) and np.array_equal(J_api, J[i]), chain.name
            assert np.array_equal(fk.forward_kinematics(chain, Q[i]), T[i])
            assert np.array_equal(fk.jacobian_spatial(chain, Q[i]), J[i])
            tip = fk.fk_tuple(chain, Q[i].tolist())
            assert tip == (*T[i, :3, :3].ravel().tolist(), *T[i, :3, 3].tolist())
            frames = fk.joint_frames(chain, Q[i])
            assert np.array_equal(frames[1:, :3, :3].reshape(chain.dof, 9), F[i, :, :9])
            assert np.array_equal(frames[1:, :3, 3], F[i, :, 9:])


def test_the_compiled_pose_is_the_matrix_product_of_the_dh_links():
    rng = np.random.default_rng(2)
    for chain in _chains():
        q = rng.uniform(chain.qmin, chain.qmax, (20, chain.dof))
        want = fk.forward_kinematics_matmul(chain, q)
        got = np.stack([fk.forward_kinematics(chain, row) for row in q])
        np.testing.assert_allclose(got, want, atol=1e-12)


def test_a_function_numba_cannot_compile_runs_as_python_with_a_warning():
    if not _jit.ENABLED:
        pytest.skip("numba is not available or switched off: jit returns the function")

    def uses_a_python_object(x):
        return {"x": x}["x"] + 1.0  # a dict of mixed use: not numba's nopython subset

    f = _jit.jit(lambda x: uses_a_python_object(x))
    with pytest.warns(RuntimeWarning, match="running it as plain Python"):
        assert f(1.0) == 2.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert f(2.0) == 3.0  # warned once, then plain Python


def test_jit_off_returns_the_function_itself(monkeypatch):
    monkeypatch.setattr(_jit, "ENABLED", False)

    def g(x):
        return x + 1

    assert _jit.jit(g) is g and g.py_func is g
