"""PSM IK: closed form and dVRK reference (DLS) round trips, agreement, rules and failures.

Sampling domain of the round trips (what is excluded and why):
* insertion ≥ 0.065 m: below 0.0606 m the 45 mm shaft-end rule (dvrk.md 1.7) deliberately
  moves the answer off the goal; that region is tested on its own below;
* every revolute joint ≥ 0.02 rad inside its limits: at a limit the answer's validity hinges
  on the 1e-9 limit slack, not on the solver;
* nothing else: the wrist singularities of a PSM are outside its ±80° wrist limits.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from davinci_sim.kinematics.arms import load_arm
from davinci_sim.kinematics.fk import forward_kinematics
from davinci_sim.kinematics.psm_ik import (
    SAFE_DISTANCE_FROM_RCM,
    psm_ik_closed_form,
    psm_ik_reference,
)

TOL = 1e-6  # m and rad, the required round-trip accuracy
SHAFT0 = -0.0156  # frame 4 at (q3 − 0.0156) from the RCM (dvrk.md 1.2 [derived])
Q3_SAFE = SAFE_DISTANCE_FROM_RCM - SHAFT0


def _sample(chain, rng, n, *, q3=(0.065, 0.24)):
    lo, hi = chain.qmin + 0.02, chain.qmax - 0.02
    lo[2], hi[2] = q3
    return rng.uniform(lo, hi, size=(n, chain.dof))


def _assert_round_trip(r, q_true=None, *, q_tol=1e-9):
    assert r.success, r.message
    assert not r.adjusted, r.message
    assert r.position_error <= TOL and r.rotation_error <= TOL
    if q_true is not None:
        np.testing.assert_allclose(r.q, q_true, rtol=0, atol=q_tol)


def test_closed_form_round_trips_1000(psm, rng):
    """Seeded near the truth, the closed form returns exactly the truth (nearest branch)."""
    Q = _sample(psm.chain, rng, 1000)
    T = forward_kinematics(psm.chain, Q)
    seeds = Q + rng.normal(0.0, 0.05, Q.shape)
    worst = 0.0
    for q, Tg, seed in zip(Q, T, seeds, strict=True):
        r = psm_ik_closed_form(psm.chain, Tg, seed)
        _assert_round_trip(r, q)
        worst = max(worst, r.position_error, r.rotation_error)
    assert worst < 1e-12  # exact: machine precision, not merely within TOL


def test_closed_form_from_home_seed(psm, rng):
    """From a far seed a different wrist branch may win, but the goal is still reached."""
    for q in _sample(psm.chain, rng, 300):
        r = psm_ik_closed_form(psm.chain, forward_kinematics(psm.chain, q), psm.home)
        _assert_round_trip(r)


def test_reference_round_trips_1000(psm, rng):
    Q = _sample(psm.chain, rng, 1000)
    for q in Q:
        seed = q + rng.normal(0.0, 0.05, 6)
        r = psm_ik_reference(psm.chain, forward_kinematics(psm.chain, q), seed)
        _assert_round_trip(r, q)
        assert 0 < r.iterations < 1000


def test_closed_form_agrees_with_reference(psm, rng):
    both = 0
    for q in _sample(psm.chain, rng, 200, q3=(0.0, 0.24)):
        seed = q + rng.normal(0.0, 0.05, 6)
        T = forward_kinematics(psm.chain, q)
        ref = psm_ik_reference(psm.chain, T, seed)
        cf = psm_ik_closed_form(psm.chain, T, seed)
        if ref.success:
            both += 1
            assert cf.success and cf.adjusted == ref.adjusted, cf.message
            np.testing.assert_allclose(cf.q, ref.q, rtol=0, atol=1e-9)
    # The DLS only fails (1000 steps) with the wrist within ~2 mm of the RCM, where the
    # yaw/pitch lever vanishes; that is a few percent of this insertion range.
    assert both >= 180


def test_inside_the_cannula_is_solved_exactly(psm, rng):
    """q3 < 0.0156 puts the wrist behind the RCM (the σ = −1 branch). A seed at zero
    insertion means the 45 mm rule keeps q3 (never pull out further), so the pose is exact."""
    for q in _sample(psm.chain, rng, 200, q3=(0.0, Q3_SAFE)):
        T = forward_kinematics(psm.chain, q)
        seed = q.copy()
        seed[2] = 0.0
        r = psm_ik_closed_form(psm.chain, T, seed)
        if np.linalg.norm(T[:3, 3]) < 1e-3:
            assert not r.success and "RCM" in r.message
            continue
        _assert_round_trip(r, q)


def test_safety_rule_limits_insertion(psm):
    """dvrk.md 1.8: shaft end closer than 45 mm -> insertion to the minimum, or kept at the
    current insertion if that is already shallower."""
    q = np.array([0.1, -0.2, 0.03, 0.3, 0.2, -0.1])
    T = forward_kinematics(psm.chain, q)
    for solve in (psm_ik_closed_form, psm_ik_reference):
        deep = solve(psm.chain, T, psm.home)  # current insertion 0.12 > minimum
        assert deep.success and deep.adjusted and "45 mm" in deep.message
        assert deep.q[2] == pytest.approx(Q3_SAFE, abs=1e-12)
        np.testing.assert_allclose(np.delete(deep.q, 2), np.delete(q, 2), atol=1e-9)
        assert deep.position_error == pytest.approx(Q3_SAFE - 0.03, abs=1e-9)
        shallow_seed = q.copy()
        shallow_seed[2] = 0.045  # current insertion shallower than minimum, deeper than goal
        shallow = solve(psm.chain, T, shallow_seed)
        assert shallow.success and shallow.adjusted
        assert shallow.q[2] == pytest.approx(0.045, abs=1e-12)


def test_roll_nearest_current_roll(psm):
    q = np.array([0.1, 0.2, 0.1, -3.0, 0.3, 0.4])
    T = forward_kinematics(psm.chain, q)
    seed = q.copy()
    seed[3] = 3.0
    for solve in (psm_ik_closed_form, psm_ik_reference):
        r = solve(psm.chain, T, seed)
        assert r.success, r.message
        assert r.q[3] == pytest.approx(-3.0 + 2 * math.pi, abs=1e-9)
    # Roll 0 seen from 4.0: the nearest turn, 2π, is beyond the ±260° limit. It is the
    # answer still (as the dVRK's: the arm clips it, the tool stops at its limit), not 0, a
    # whole turn back, which a servo stream would ask for in one tick.
    q[3], seed[3] = 0.0, 4.0
    T = forward_kinematics(psm.chain, q)
    for solve in (psm_ik_closed_form, psm_ik_reference):
        r = solve(psm.chain, T, seed)
        assert not r.success and r.reached and "roll" in r.message, r.message
        assert r.q[3] == pytest.approx(2 * math.pi, abs=1e-9)


def test_failures_are_results_not_exceptions(psm):
    T = forward_kinematics(psm.chain, psm.home)
    at_rcm = T.copy()
    at_rcm[:3, 3] = [0.0, 0.0, -0.0005]
    far = T.copy()
    far[:3, 3] = [0.0, 0.0, -1.0]
    for solve in (psm_ik_closed_form, psm_ik_reference):
        r = solve(psm.chain, at_rcm, psm.home)
        assert not r.success and "RCM" in r.message
        np.testing.assert_array_equal(r.q, psm.home)
        r = solve(psm.chain, far, psm.home)
        assert not r.success and "insertion" in r.message
    # A wrist bent beyond its ±80° limits: reachable geometrically, not within limits.
    bent = forward_kinematics(psm.chain, np.array([0.0, 0.0, 0.1, 0.0, 1.55, 0.0]))
    r = psm_ik_closed_form(psm.chain, bent, psm.home)
    assert not r.success and "joint limits" in r.message


@pytest.mark.parametrize("solve", [psm_ik_closed_form, psm_ik_reference])
def test_bad_input_raises(psm, solve):
    T = forward_kinematics(psm.chain, psm.home)
    bad = T.copy()
    bad[0, 3] = np.nan
    with pytest.raises(ValueError, match="finite"):
        solve(psm.chain, bad, psm.home)
    with pytest.raises(ValueError, match="shape"):
        solve(psm.chain, T[:3], psm.home)
    with pytest.raises(ValueError, match="q_seed"):
        solve(psm.chain, T, psm.home[:5])
    with pytest.raises(ValueError, match="q_seed"):
        solve(psm.chain, T, np.full(6, np.inf))


def test_non_psm_chain_is_refused():
    with pytest.raises(ValueError, match="PSM"):
        psm_ik_closed_form(load_arm("ECM").chain, np.eye(4), np.zeros(4))


_CHAIN = load_arm("PSM1").chain
_JOINT = [st.floats(j.qmin, j.qmax) for j in _CHAIN.joints]


@settings(max_examples=300, deadline=None)
@given(q=st.tuples(*_JOINT), seed=st.tuples(*_JOINT))
def test_closed_form_any_config_any_seed(q, seed):
    """Any in-limit configuration is found from any in-limit seed (maybe another branch),
    but for the roll: the turn nearest the seed's may be past its limit (then the answer,
    which the arm clips)."""
    q, seed = np.array(q), np.array(seed)
    T = forward_kinematics(_CHAIN, q)
    r = psm_ik_closed_form(_CHAIN, T, seed)
    if np.linalg.norm(T[:3, 3]) < 1e-3:
        assert not r.success
        return
    assert abs(r.q[3] - seed[3]) <= math.pi + 1e-9  # (dvrk.md 1.8: nearest the seed's)
    if not r.success:  # (the roll alone past its limit, the wrist on the seed's branch)
        assert r.reached and r.message.startswith("joint limits: roll="), r.message
        assert abs(r.q[3]) > _CHAIN.qmax[3]
        assert np.all(np.abs(np.delete(r.q, 3)) <= np.delete(_CHAIN.qmax, 3) + 1e-6)
        return
    if not r.adjusted:
        assert r.position_error <= 1e-9 and r.rotation_error <= 1e-9
