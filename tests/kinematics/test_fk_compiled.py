"""The compiled forward kinematics (``kinematics.fk_compiled``, numba) against the plain Python
float path of ``kinematics.fk``: the same operations, so the same bits, with numba and without
(the fallback when numba is missing, switched off or fails to compile)."""

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


@pytest.mark.parametrize("kernel", ["compiled", "python"])
def test_pose_and_jacobian_are_the_float_paths_bits(kernel):
    """Both conventions (the SUJ chains are standard DH, the arms modified), tool offsets."""
    run = fk_compiled.tip_pose_and_jacobian
    if kernel == "python":
        run = run.py_func
    rng = np.random.default_rng(1)
    for chain in _chains():
        cc = fk._consts(chain)
        for _ in range(50):
            q = rng.uniform(chain.qmin, chain.qmax)
            T, J = np.empty((4, 4)), np.empty((6, chain.dof))
            run(*cc.packed, q, T, J, True)
            J_ref, tip = fk._jacobian_spatial_floats(chain, q.tolist())
            assert np.array_equal(T, fk._to_matrix(tip)), chain.name
            assert np.array_equal(J, np.array(J_ref)), chain.name
            # and the public API, whichever path it takes
            T_api, J_api = fk.forward_kinematics_and_jacobian(chain, q)
            assert np.array_equal(T_api, T) and np.array_equal(J_api, J)
            assert np.array_equal(fk.forward_kinematics(chain, q), T)
            assert fk.fk_tuple(chain, q.tolist()) == tip


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
