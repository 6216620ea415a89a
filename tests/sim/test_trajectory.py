"""Joint trajectories: limits respected, synchronised arrival, exact end points."""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from davinci_sim.sim.trajectory import plan_trajectory, step_towards, step_towards_row

vec = st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3)
lim = st.lists(st.floats(0.05, 5.0), min_size=3, max_size=3)


@settings(max_examples=150, deadline=None)
@given(vec, vec, lim, lim)
@example([0.05, 0.05000000000000001, 0.0], [0.05000000000000001, 0.05000000000000001, 0.0],
         [1.0, 1.0, 1.0], [1.0, 1.0, 1.0])  # fmt: skip
def test_trajectory_respects_limits_and_arrives_together(q0, q1, v, a):
    q0, q1, v, a = map(np.array, (q0, q1, v, a))
    tr = plan_trajectory(q0, q1, v, a)
    ts = np.linspace(0.0, tr.duration, 801)
    samples = [tr.sample(t) for t in ts]
    Q = np.array([s[0] for s in samples])
    V = np.array([s[1] for s in samples])
    assert np.allclose(Q[0], q0) and np.allclose(Q[-1], q1)
    assert np.all(np.abs(V) <= v * (1 + 1e-9) + 1e-12)
    if tr.duration > 0:
        dt = ts[1] - ts[0]
        # Acceleration from the sampled velocity (a kink can straddle one sample).
        acc = np.abs(np.diff(V, axis=0)) / dt
        assert np.all(acc <= a * (1 + 1e-6) + 1e-9)
        # Velocity is the derivative of position (trapezoid rule on the samples), within the
        # positions' rounding over a sample's time (a move of an ulp: dt 7e-12 s, hypothesis).
        dq = np.diff(Q, axis=0) / dt
        rounding = 4 * np.finfo(float).eps * np.abs(Q).max() / dt
        assert np.allclose(dq, 0.5 * (V[1:] + V[:-1]),
                           atol=1e-6 + 0.25 * a.max() * dt + rounding)  # fmt: skip


def test_minimum_time_matches_trapezoid_formula():
    # One joint, 1 rad at 1 rad/s and 1 rad/s^2: accelerate 1 s (0.5 rad), cruise 0 s,
    # decelerate 1 s -> triangle of 2 s exactly; 3 rad -> 1 + 2 + 1 = 4 s.
    assert plan_trajectory([0.0], [1.0], [1.0], [1.0]).duration == pytest.approx(2.0)
    assert plan_trajectory([0.0], [3.0], [1.0], [1.0]).duration == pytest.approx(4.0)


def test_slow_joint_sets_the_duration_and_others_slow_down():
    tr = plan_trajectory([0.0, 0.0], [3.0, 0.1], [1.0, 1.0], [1.0, 1.0])
    assert tr.duration == pytest.approx(4.0)
    q_mid, _ = tr.sample(2.0)
    assert q_mid[1] == pytest.approx(0.05)  # symmetric profile: half way at half time


def test_zero_motion_and_bad_limits():
    tr = plan_trajectory([1.0, 2.0], [1.0, 2.0], [1.0, 1.0], [1.0, 1.0])
    assert tr.duration == 0.0
    assert np.array_equal(tr.sample(0.3)[0], [1.0, 2.0])
    with pytest.raises(ValueError, match="v_max"):
        plan_trajectory([0.0], [1.0], [0.0], [1.0])
    with pytest.raises(ValueError, match="a_max"):
        plan_trajectory([0.0], [1.0], [1.0], [np.inf])


def test_step_towards_reaches_the_goal_within_the_limits_from_a_moving_start():
    dt, v_max, a_max = 1e-3, np.array([1.5, 6.0]), np.array([0.8, 6.0])
    q, qd = np.array([0.0, 1.0]), np.array([0.5, -2.0])  # moving, one joint away
    goal = np.array([1.0, -1.0])
    for i in range(6000):
        if i == 2000:
            goal = np.array([0.5, 0.0])  # the goal moves mid-way
        q_next, qd_next = step_towards(q, qd, goal, v_max, a_max, dt)
        assert np.all(np.abs(qd_next) <= v_max + 1e-12)
        assert np.all(np.abs(qd_next - qd) <= a_max * dt + 1e-12)
        q, qd = q_next, qd_next
    assert np.allclose(q, goal, atol=1e-6) and np.allclose(qd, 0.0, atol=1e-3)


_values = st.one_of(
    st.floats(-3.0, 3.0),
    st.sampled_from([0.0, -0.0, float("nan"), 1e-300, -1e-300]),
)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(_values, min_size=3, max_size=3),
    st.lists(_values, min_size=3, max_size=3),
    st.lists(_values, min_size=3, max_size=3),
    st.floats(0.1, 1.0),
)
def test_the_float_step_is_numpys_step_bit_for_bit(q, qd, goal, ratio):
    """step_towards_row (the MTM lock's compiled step) against step_towards, NaN and signed
    zeros included."""
    q, qd, goal = np.array(q), np.array(qd), np.array(goal)
    v_max, a_max, dt = np.array([1.0, 2.0, 3.5]), np.array([4.0, 8.0, 15.0]), 0.001
    want_q, want_qd = step_towards(q, qd, goal, v_max * ratio, a_max * ratio, dt)
    got_q, got_qd = np.empty(3), np.empty(3)
    step_towards_row(q, qd, goal, v_max, a_max, ratio, dt, got_q, got_qd)
    np.testing.assert_array_equal(np.signbit(got_qd), np.signbit(want_qd))
    np.testing.assert_array_equal(got_q, want_q)
    np.testing.assert_array_equal(got_qd, want_qd)
