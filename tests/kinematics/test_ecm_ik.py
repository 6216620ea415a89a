"""ECM closed-form IK (dvrk.md 1.8): round trips, the dVRK formulas, projection, failures.

Round trips sample insertion ≥ 40 mm (below, the IK raises it to 40 mm on purpose, dvrk.md
1.7; tested separately) and revolute joints 0.02 rad inside their limits.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from davinci_sim.kinematics.ecm_ik import MIN_INSERTION, ecm_ik_closed_form
from davinci_sim.kinematics.fk import forward_kinematics

TOL = 1e-6


def _sample(chain, rng, n):
    lo, hi = chain.qmin + 0.02, chain.qmax - 0.02
    lo[2], hi[2] = MIN_INSERTION, chain.qmax[2]
    return rng.uniform(lo, hi, size=(n, chain.dof))


def test_round_trips_1000(ecm, rng):
    Q = _sample(ecm.chain, rng, 1000)
    for q, T in zip(Q, forward_kinematics(ecm.chain, Q), strict=True):
        r = ecm_ik_closed_form(ecm.chain, T, ecm.home)
        assert r.success and not r.adjusted, r.message
        assert r.position_error <= TOL and r.rotation_error <= TOL
        np.testing.assert_allclose(r.q, q, rtol=0, atol=1e-9)


def test_matches_the_dvrk_formulas(ecm, rng):
    """dvrk.md 1.8 writes q1 = asin(x/√(x²+z²)), q2 = −asin(y/|p|), q3 = |p| − 0.0007, exact
    for ±90° twists. With the JSON's 1.5708 twists they are off by ≤ 3.7e-6·(1 + 1/cos q2)
    rad (1.6e-5 at the largest pitch); q3 is exact."""
    Q = _sample(ecm.chain, rng, 1000)
    for T in forward_kinematics(ecm.chain, Q):
        x, y, z = T[:3, 3]
        d = math.sqrt(x * x + y * y + z * z)
        r = ecm_ik_closed_form(ecm.chain, T, ecm.home)
        assert r.q[0] == pytest.approx(math.asin(x / math.hypot(x, z)), abs=3e-5)
        assert r.q[1] == pytest.approx(-math.asin(y / d), abs=3e-5)
        assert r.q[2] == pytest.approx(d - 0.0007, abs=1e-12)


def test_orientation_is_projected_onto_the_shaft(ecm):
    q = np.array([0.3, 0.2, 0.1, -0.4])
    T = forward_kinematics(ecm.chain, q)
    tilted = T.copy()
    tilted[:3, :3] = T[:3, :3] @ Rotation.from_rotvec([0.2, 0.0, 0.0]).as_matrix()
    r = ecm_ik_closed_form(ecm.chain, tilted, ecm.home)
    assert r.success and r.adjusted and "projected" in r.message
    assert r.position_error <= TOL
    assert r.rotation_error == pytest.approx(0.2, abs=1e-9)
    np.testing.assert_allclose(r.q[:3], q[:3], atol=1e-9)
    # Tilting the goal about its own z axis is a pure roll change: reachable, no projection.
    rolled = T.copy()
    rolled[:3, :3] = T[:3, :3] @ Rotation.from_rotvec([0.0, 0.0, 0.3]).as_matrix()
    r = ecm_ik_closed_form(ecm.chain, rolled, ecm.home)
    assert r.success and not r.adjusted
    assert r.rotation_error <= TOL


def test_insertion_raised_to_40_mm(ecm):
    T = forward_kinematics(ecm.chain, np.array([0.1, 0.2, 0.01, 0.3]))
    r = ecm_ik_closed_form(ecm.chain, T, ecm.home)
    assert r.success and r.adjusted and "0.04" in r.message
    np.testing.assert_allclose(r.q, [0.1, 0.2, MIN_INSERTION, 0.3], atol=1e-9)
    assert r.position_error == pytest.approx(0.03, abs=1e-9)


def test_failures(ecm):
    T = forward_kinematics(ecm.chain, ecm.home)
    above = T.copy()
    above[2, 3] = 0.01
    r = ecm_ik_closed_form(ecm.chain, above, ecm.home)
    assert not r.success and "z" in r.message
    np.testing.assert_array_equal(r.q, ecm.home)
    close = T.copy()
    close[:3, 3] = [0.0, 0.0, -5e-5]
    r = ecm_ik_closed_form(ecm.chain, close, ecm.home)
    assert not r.success and "0.1 mm" in r.message
    # Pitch asin(0.1/0.1005) = 1.47 beyond its 65° limit: clamped values, success=False.
    beyond = forward_kinematics(ecm.chain, np.array([0.0, 0.9, 0.1, 0.0]))
    beyond[:3, 3] = [0.0, -0.1, -0.01]
    r = ecm_ik_closed_form(ecm.chain, beyond, ecm.home)
    assert not r.success and "clamped" in r.message
    assert np.all(r.q >= ecm.chain.qmin) and np.all(r.q <= ecm.chain.qmax)
    far = T.copy()
    far[:3, 3] = [0.0, 0.0, -1.0]
    r = ecm_ik_closed_form(ecm.chain, far, ecm.home)
    assert not r.success and "insertion" in r.message


def test_bad_input_raises(ecm, psm):
    T = forward_kinematics(ecm.chain, ecm.home)
    T[1, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        ecm_ik_closed_form(ecm.chain, T, ecm.home)
    with pytest.raises(ValueError, match="ECM"):
        ecm_ik_closed_form(psm.chain, np.eye(4), psm.home)
