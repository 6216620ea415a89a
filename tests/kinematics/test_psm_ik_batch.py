"""Closed-form PSM IK on batches (the study's use): each row reaches its goal (checked by
the slow 4x4-product FK, an independent oracle), is the answer the arm gets alone (the same
kernel: bit for bit, whatever the batch), edge cases, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from davinci_sim.kinematics.fk import forward_kinematics, forward_kinematics_matmul
from davinci_sim.kinematics.psm_ik import (
    SAFE_DISTANCE_FROM_RCM,
    BatchIKResult,
    psm_ik_closed_form,
    psm_ik_closed_form_batch,
)

SHAFT0 = -0.0156  # frame 4 at (q3 − 0.0156) from the RCM (dvrk.md 1.2 [derived])
Q3_SAFE = SAFE_DISTANCE_FROM_RCM - SHAFT0


def _assert_rows_reach_their_goals_as_alone(chain, T, seeds, result, **tolerances):
    assert isinstance(result, BatchIKResult)
    n = T.shape[0]
    assert result.q.shape == (n, 6) and result.q.dtype == float
    assert result.success.shape == (n,) and result.success.dtype == bool
    reached = 0
    for i in range(n):
        r = psm_ik_closed_form(chain, T[i], seeds[i], **tolerances)
        np.testing.assert_array_equal(result.q[i], r.q, err_msg=f"row {i}")
        assert bool(result.success[i]) == r.success, f"row {i}: {r.message}"
        if r.success and not r.adjusted:  # the pose is reached (independent FK)
            F = forward_kinematics_matmul(chain, result.q[i])
            np.testing.assert_allclose(F, T[i], rtol=0, atol=1e-9, err_msg=f"row {i}")
            assert np.all(result.q[i] >= chain.qmin - 1e-9) and np.all(
                result.q[i] <= chain.qmax + 1e-9
            )
            reached += 1
    return reached


def _sample(chain, rng, n, q3=(0.0, 0.24)):
    lo, hi = chain.qmin.copy(), chain.qmax.copy()
    lo[2], hi[2] = q3
    return rng.uniform(lo, hi, size=(n, chain.dof))


def test_random_workspace_equals_scalar(psm):
    """Full joint ranges (insertion 0-240 mm, so σ = −1 rows and the 45 mm rule are in)."""
    rng = np.random.default_rng(0)
    Q = _sample(psm.chain, rng, 400)
    T = forward_kinematics(psm.chain, Q)
    seeds = Q + rng.normal(0.0, 0.05, Q.shape)
    r = psm_ik_closed_form_batch(psm.chain, T, seeds)
    _assert_rows_reach_their_goals_as_alone(psm.chain, T, seeds, r)
    assert r.success.mean() > 0.95


def test_far_seeds_pick_the_same_branch(psm):
    """Seeds anywhere in the limits or at home: other wrist/shaft branches win, identically."""
    rng = np.random.default_rng(1)
    Q = _sample(psm.chain, rng, 300, q3=(0.04, 0.24))
    T = forward_kinematics(psm.chain, Q)
    seeds = _sample(psm.chain, rng, 300)
    seeds[::3] = psm.home
    r = psm_ik_closed_form_batch(psm.chain, T, seeds)
    _assert_rows_reach_their_goals_as_alone(psm.chain, T, seeds, r)
    # Each roll the turn nearest the seed's (dvrk.md 1.8): some are past the ±260° limit,
    # those rows only fail (the arm clips them).
    roll = r.q[:, 3]
    assert np.all(np.abs(roll - seeds[:, 3]) <= math.pi + 1e-9)
    np.testing.assert_array_equal(r.success, np.abs(roll) <= psm.chain.qmax[3])
    assert r.success.mean() > 0.8
    # Far seeds do select other branches than the generating configuration.
    assert np.any(np.abs(r.q - Q).max(axis=1) > 0.1)


def test_edge_cases_in_one_batch(psm):
    chain = psm.chain
    home_T = forward_kinematics(chain, psm.home)
    rows = []  # (goal, seed)
    near_rcm = home_T.copy()
    near_rcm[:3, 3] = [0.0, 0.0, -0.0005]
    rows.append((near_rcm, psm.home))  # 0: within 1 mm of the RCM
    far = home_T.copy()
    far[:3, 3] = [0.0, 0.0, -1.0]
    rows.append((far, psm.home))  # 1: unreachable, beyond the insertion range
    shallow_q = np.array([0.1, -0.2, 0.05, 0.3, 0.2, -0.1])
    shallow_T = forward_kinematics(chain, shallow_q)
    rows.append((shallow_T, psm.home))  # 2: 45 mm rule, insertion raised to the minimum
    seed = shallow_q.copy()
    seed[2] = 0.055
    rows.append((shallow_T, seed))  # 3: 45 mm rule, current insertion kept (shallower)
    roll_q = np.array([0.1, 0.2, 0.1, -3.0, 0.3, 0.4])
    seed = roll_q.copy()
    seed[3] = 3.0
    rows.append((forward_kinematics(chain, roll_q), seed))  # 4: roll −3 seen from 3: −3 + 2π
    roll_q = roll_q.copy()
    roll_q[3] = 0.0
    seed[3] = 4.0
    rows.append((forward_kinematics(chain, roll_q), seed))  # 5: 2π, beyond the limit
    seed = seed.copy()
    seed[3] = -4.0
    rows.append((forward_kinematics(chain, roll_q), seed))  # 6: −2π, beyond the limit
    at_limit = np.array([0.1, 0.2, 0.1, chain.qmax[3], 0.3, 0.4])
    rows.append((forward_kinematics(chain, at_limit), at_limit))  # 7: roll at its limit
    bent = np.array([0.0, 0.0, 0.1, 0.0, 1.55, 0.0])
    rows.append((forward_kinematics(chain, bent), psm.home))  # 8: wrist beyond ±80°
    inside = np.array([0.2, -0.1, 0.01, 0.5, 0.1, 0.2])
    seed = inside.copy()
    seed[2] = 0.0
    rows.append((forward_kinematics(chain, inside), seed))  # 9: inside the cannula (σ = −1)
    T = np.array([g for g, _ in rows])
    seeds = np.array([s for _, s in rows])
    r = psm_ik_closed_form_batch(chain, T, seeds)
    _assert_rows_reach_their_goals_as_alone(chain, T, seeds, r)
    np.testing.assert_array_equal(
        r.success, [False, False, True, True, True, False, False, True, False, True]
    )
    np.testing.assert_array_equal(r.q[0], psm.home)  # rejected: q is the seed
    assert r.q[2, 2] == pytest.approx(Q3_SAFE, abs=1e-12)
    np.testing.assert_allclose(np.delete(r.q[2], 2), np.delete(shallow_q, 2), atol=1e-9)
    assert r.q[3, 2] == pytest.approx(0.055, abs=1e-12)
    assert r.q[4, 3] == pytest.approx(-3.0 + 2 * math.pi, abs=1e-9)
    assert r.q[5, 3] == pytest.approx(2 * math.pi, abs=1e-9)
    assert r.q[6, 3] == pytest.approx(-2 * math.pi, abs=1e-9)
    np.testing.assert_allclose(r.q[7], at_limit, atol=1e-9)
    np.testing.assert_allclose(r.q[9], inside, atol=1e-9)


def test_shallow_rows_use_the_vectorised_insertion_rule(psm):
    """Insertion 35-60 mm: the 45 mm rule applies."""
    rng = np.random.default_rng(2)
    Q = _sample(psm.chain, rng, 200, q3=(0.036, 0.06))
    T = forward_kinematics(psm.chain, Q)
    seeds = Q + rng.normal(0.0, 0.05, Q.shape)
    seeds[::2, 2] = 0.12  # deep seed: raised to the minimum; else seed near the goal
    r = psm_ik_closed_form_batch(psm.chain, T, seeds)
    _assert_rows_reach_their_goals_as_alone(psm.chain, T, seeds, r)
    assert np.all(r.q[::2, 2] == pytest.approx(Q3_SAFE, abs=1e-12))


def test_tolerances_are_passed_on(psm):
    """An impossible tolerance: every row fails its FK check (after the DLS polish)."""
    rng = np.random.default_rng(3)
    Q = _sample(psm.chain, rng, 4, q3=(0.07, 0.24))
    T = forward_kinematics(psm.chain, Q)
    tol = {"position_tolerance": 0.0, "rotation_tolerance": 0.0}
    r = psm_ik_closed_form_batch(psm.chain, T, Q, **tol)
    _assert_rows_reach_their_goals_as_alone(psm.chain, T, Q, r, **tol)


def test_shapes_one_and_zero_rows(psm):
    q = np.array([[0.1, -0.2, 0.12, 0.3, 0.2, -0.1]])
    r = psm_ik_closed_form_batch(psm.chain, forward_kinematics(psm.chain, q), q)
    assert r.q.shape == (1, 6) and r.success.shape == (1,)
    assert r.success[0]
    np.testing.assert_allclose(r.q, q, atol=1e-12)
    r = psm_ik_closed_form_batch(psm.chain, np.empty((0, 4, 4)), np.empty((0, 6)))
    assert r.q.shape == (0, 6) and r.success.shape == (0,) and r.success.dtype == bool


def test_bad_input_raises(psm):
    T = forward_kinematics(psm.chain, np.tile(psm.home, (3, 1)))
    seeds = np.tile(psm.home, (3, 1))
    with pytest.raises(ValueError, match=r"shape \(n, 4, 4\)"):
        psm_ik_closed_form_batch(psm.chain, T[0], seeds[0])
    with pytest.raises(ValueError, match=r"shape \(n, 4, 4\)"):
        psm_ik_closed_form_batch(psm.chain, T[:, :3], seeds)
    with pytest.raises(ValueError, match="q_seed"):
        psm_ik_closed_form_batch(psm.chain, T, seeds[:, :5])
    with pytest.raises(ValueError, match="q_seed"):
        psm_ik_closed_form_batch(psm.chain, T, seeds[:2])
    bad = T.copy()
    bad[1, 0, 3] = np.nan
    with pytest.raises(ValueError, match=r"finite.*\[1\]"):
        psm_ik_closed_form_batch(psm.chain, bad, seeds)
    bad_seeds = seeds.copy()
    bad_seeds[2, 0] = np.inf
    with pytest.raises(ValueError, match=r"q_seed must be finite.*\[2\]"):
        psm_ik_closed_form_batch(psm.chain, T, bad_seeds)


def test_non_psm_chain_is_refused(ecm):
    with pytest.raises(ValueError, match="PSM"):
        psm_ik_closed_form_batch(ecm.chain, np.eye(4)[None], np.zeros((1, 4)))


def test_compiled_kernel_and_python_give_the_same_bits(psm):
    """The kernel compiled (numba) and as plain Python (``DAVINCI_SIM_JIT=0``, or numba
    missing): the same operations, the same answers to the bit."""
    from davinci_sim.kinematics import psm_closed_form
    from davinci_sim.kinematics.psm_ik import _packed

    rng = np.random.default_rng(4)
    Q = _sample(psm.chain, rng, 60)
    T = forward_kinematics(psm.chain, Q)
    S = Q + rng.normal(0.0, 0.3, Q.shape)
    T[0, :3, 3] *= 1e-3  # too close
    T[1, :3, 3] *= 30.0  # unreachable
    p = _packed(psm.chain)
    outs = []
    for kernel in (psm_closed_form.closed_form_rows, psm_closed_form.closed_form_rows.py_func):
        out = (np.empty((60, 6)), np.empty(60, bool), np.empty(60, np.int64), np.empty((60, 5)))
        kernel(p.geometry, p.tool, p.revolute, p.lim_lo, p.lim_hi, *p.fk, T, S,
               np.array([1e-9, 1e-9]), *out)  # fmt: skip
        outs.append(out)
    for a, b in zip(*outs, strict=True):
        np.testing.assert_array_equal(a, b)
    assert outs[0][2][0] == psm_closed_form.TOO_CLOSE
    assert not outs[0][1][:2].any() and outs[0][1].mean() > 0.5
