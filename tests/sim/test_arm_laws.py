"""The tick's laws shared by the live objects and the study's batch engine
(:mod:`davinci_sim.sim.arm_laws`, ``devices.hand.handle_xfrc``,
``haptics.fixture.fixture_force_camera``): right against independent formulas, and each
row of a batch the same bits as that row alone (a trial must not depend on its batch, and
the live arm is a batch of one)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from davinci_sim.devices.hand import handle_xfrc
from davinci_sim.geometry import so3
from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.fixture import fixture_force_camera
from davinci_sim.haptics.viscous import ViscousGuidance
from davinci_sim.kinematics import fk
from davinci_sim.kinematics.arms import load_arm
from davinci_sim.sim import arm_laws as laws


def _rotation(rng) -> np.ndarray:
    return so3.rotation_from_vector(rng.uniform(-2, 2, 3))


def _transform(rng) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = _rotation(rng), rng.normal(scale=0.1, size=3)
    return T


@pytest.fixture
def psm_batch():
    rng = np.random.default_rng(4)
    chain = load_arm("PSM1").chain
    q = rng.uniform(chain.qmin, chain.qmax, (9, chain.dof))
    q[:, 2] = rng.uniform(0.08, 0.2, 9)  # inserted
    return rng, chain, q


def _rows_alone(fn, *batched):
    return np.stack([fn(*(b[i] for b in batched)) for i in range(len(batched[0]))])


def test_pose_and_twist_in_reference(psm_batch):
    rng, chain, q = psm_batch
    qd = rng.normal(size=q.shape)
    T_ref_base = _transform(rng)
    T, J = laws.tip_kinematics(chain, q)
    np.testing.assert_allclose(laws.tip_pose(chain, q), T, atol=1e-15)
    # one configuration (the live arm's measured_cp and setpoint_cp): the same bits
    np.testing.assert_array_equal(laws.tip_pose(chain, q[0]), laws.tip_kinematics(chain, q[0])[0])
    P = laws.pose_in_reference(T_ref_base, T)
    np.testing.assert_allclose(P, np.einsum("ij,njk->nik", T_ref_base, T), atol=1e-15)
    R = T_ref_base[:3, :3]
    twist = laws.twist_in_reference(R, J, qd)
    v = np.einsum("nij,nj->ni", J, qd)
    np.testing.assert_allclose(twist[:, :3], v[:, :3] @ R.T, atol=1e-14)
    np.testing.assert_allclose(twist[:, 3:], v[:, 3:] @ R.T, atol=1e-14)
    # the tip's linear velocity is the derivative of its position (finite difference)
    h = 1e-7
    p1 = laws.pose_in_reference(T_ref_base, laws.tip_pose(chain, q + h * qd))[:, :3, 3]
    np.testing.assert_allclose((p1 - P[:, :3, 3]) / h, twist[:, :3], atol=1e-6)
    one = _rows_alone(lambda j, w: laws.twist_in_reference(R, j, w), J, qd)
    np.testing.assert_array_equal(one, twist)


def test_joint_velocity_solves_and_falls_back_to_least_squares_per_row(psm_batch):
    rng, chain, q = psm_batch
    _, J = laws.tip_kinematics(chain, q)
    twist = rng.normal(size=(len(q), 6))
    qd = laws.joint_velocity(J, twist)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", J, qd), twist, atol=1e-9)
    np.testing.assert_array_equal(_rows_alone(laws.joint_velocity, J, twist), qd)
    # One singular row (two equal columns): least squares for it, the others unchanged.
    J_bad = J.copy()
    J_bad[3, :, 5] = J_bad[3, :, 4]
    qd_bad = laws.joint_velocity(J_bad, twist)
    np.testing.assert_array_equal(np.delete(qd_bad, 3, 0), np.delete(qd, 3, 0))
    want = np.linalg.lstsq(J_bad[3], twist[3], rcond=None)[0]
    np.testing.assert_allclose(qd_bad[3], want, atol=1e-9)
    assert np.isfinite(qd_bad).all()


def test_wrench_effort_is_jacobian_transpose_times_the_wrench_clamped(psm_batch):
    rng, chain, q = psm_batch
    _, J = laws.tip_kinematics(chain, q)
    R = _rotation(rng)
    w = rng.normal(scale=2.0, size=(len(q), 6))
    tau = laws.wrench_effort(J, R, w, chain.ftmax)
    w_base = np.concatenate([w[:, :3] @ R.T, w[:, 3:] @ R.T], axis=1)
    want = np.clip(np.einsum("nij,ni->nj", J, w_base), -chain.ftmax, chain.ftmax)
    np.testing.assert_allclose(tau, want, atol=1e-12)
    assert np.any(np.abs(tau) == chain.ftmax)  # some efforts were clamped
    one = _rows_alone(lambda j, x: laws.wrench_effort(j, R, x, chain.ftmax), J, w)
    np.testing.assert_array_equal(one, tau)


def test_tracking_fault_after_the_fault_time_of_continuous_error():
    tol = np.array([0.35, 0.35, 0.03])
    effort = np.zeros(3, dtype=bool)
    q_ref = np.zeros(3)
    bad_q = np.array([0.0, 0.0, 0.05])
    since, t = math.nan, 0.0
    faults = []
    for k in range(80):
        t = k * 2.0**-10  # s (binary-exact ticks: no rounding at the threshold)
        q = bad_q if 10 <= k < 75 else np.zeros(3)
        bad = laws.tracking_bad(q, q_ref, tol, effort).any()
        since, fault = laws.tracking_fault(bad, since, t)
        faults.append(bool(fault))
    first = faults.index(True)
    assert first == 10 + math.ceil(laws.TRACKING_FAULT_TIME / 2.0**-10)
    assert not any(faults[75:]) and math.isnan(since)  # cleared when back within tolerance
    # a joint in effort mode is not watched
    assert not laws.tracking_bad(bad_q, q_ref, tol, np.array([False, False, True])).any()
    # one arm (floats) and a batch of one (arrays): the same rule
    since1, since_a = math.nan, np.array([np.nan])
    for k, b in enumerate([True] * 60 + [False, True]):
        t = k * 2.0**-10
        since1, f1 = laws.tracking_fault(np.bool_(b), since1, t)
        since_a, f_a = laws.tracking_fault(np.array([b]), since_a, t)
        assert bool(f1) == bool(f_a[0]) and np.array_equal([since1], since_a, equal_nan=True)
    # a batch: rows independent
    S, F = laws.tracking_fault(np.array([True, True, False]), np.array([0.0, np.nan, 0.0]), 0.06)
    assert F.tolist() == [True, False, False] and S[1] == 0.06 and math.isnan(S[2])


def test_within_limits_has_the_slack_of_the_arm_checks():
    qmin, qmax = np.array([-1.0, 0.0]), np.array([1.0, 0.2])
    q = np.array([[1.0 + 5e-10, 0.1], [1.0 + 2e-9, 0.1], [0.0, -1e-3]])
    assert laws.within_limits(q, qmin, qmax).tolist() == [True, False, False]


def test_handle_xfrc_moves_the_tip_force_to_the_centre_of_mass():
    rng = np.random.default_rng(2)
    T_world_hrsv = _transform(rng)
    R, p = T_world_hrsv[:3, :3], T_world_hrsv[:3, 3]
    w = rng.normal(size=(5, 6))
    tip = rng.normal(scale=0.1, size=(5, 3))
    com = rng.normal(scale=0.1, size=(5, 3))
    x = handle_xfrc(w, tip, R, p, com)
    f = w[:, :3] @ R.T
    lever = tip @ R.T + p - com
    np.testing.assert_allclose(x[:, :3], f, atol=1e-14)
    np.testing.assert_allclose(x[:, 3:], w[:, 3:] @ R.T + np.cross(lever, f), atol=1e-14)
    one = _rows_alone(lambda a, b, c: handle_xfrc(a, b, R, p, c), w, tip, com)
    np.testing.assert_array_equal(one, x)


def test_fixture_force_camera_changes_frames_both_ways():
    rng = np.random.default_rng(5)
    path = Polyline(np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.1, 0.1, 0.0]]))
    fixture = ViscousGuidance(path, B=40.0, G_max=5.0)
    T_frame_camera = _transform(rng)
    R, t = T_frame_camera[:3, :3], T_frame_camera[:3, 3]
    # tips near the path, in the camera frame
    p_frame = np.array([[0.05, 0.003, 0.0], [0.1, 0.05, -0.002], [0.02, -0.004, 0.001]])
    p = (p_frame - t) @ R
    v = rng.normal(scale=0.05, size=(3, 3))
    f = fixture_force_camera(fixture, T_frame_camera, p, v)
    want = fixture.force(p @ R.T + t, v @ R.T) @ R
    np.testing.assert_allclose(f, want, atol=1e-12)
    assert np.abs(f).max() > 0.1
    np.testing.assert_array_equal(fixture_force_camera(fixture, None, p, v), fixture.force(p, v))
    one = _rows_alone(lambda a, b: fixture_force_camera(fixture, T_frame_camera, a, b), p, v)
    np.testing.assert_allclose(one, f, atol=0)


def test_one_arms_wrench_effort_row_is_the_numpy_law():
    """Jᵀw of one arm (the live MTM's haptic wrench) runs the compiled row; it gives the
    numpy law's bits, signed zeros (a zero wrench) and clamped joints included, and the
    same values as a row of a batch."""
    from scipy.spatial.transform import Rotation

    from davinci_sim.sim.arm_laws import wrench_effort

    rng = np.random.default_rng(4)
    for i in range(3000):
        n = int(rng.integers(3, 8))
        J = rng.normal(0, 0.3, (6, n))
        R = Rotation.random(random_state=int(rng.integers(1_000_000))).as_matrix()
        w = rng.normal(0, 2, 6) * rng.choice([1e-12, 1.0, 10.0]) * (i % 5 != 0)
        ftmax = rng.uniform(0.05, 2.0, n)
        one = wrench_effort(J, R, w, ftmax)
        w_base = so3.rotate_pairs(R, w)
        tau = np.sum(np.swapaxes(J, -1, -2) * w_base[None, :], axis=-1)
        numpy_law = np.minimum(np.maximum(tau, -ftmax), ftmax)
        np.testing.assert_array_equal(one, numpy_law, strict=True)
        assert (np.signbit(one) == np.signbit(numpy_law)).all()
        two = wrench_effort(np.stack([J, J]), R, np.stack([w, w]), ftmax)
        np.testing.assert_array_equal(one, two[0], strict=True)


def test_one_arms_twist_row_is_the_numpy_law():
    """measured_cv of one arm runs the compiled row: the numpy law's bits, signed zeros
    (joints at rest) included."""
    from scipy.spatial.transform import Rotation

    from davinci_sim.sim.arm_laws import twist_in_reference

    rng = np.random.default_rng(6)
    for i in range(3000):
        n = int(rng.integers(3, 8))
        J = rng.normal(0, 0.3, (6, n))
        R = Rotation.random(random_state=int(rng.integers(1_000_000))).as_matrix()
        qd = rng.normal(0, 1, n) * (rng.random(n) < 0.6) * (i % 4 != 0)
        one = twist_in_reference(R, J, qd)
        numpy_law = so3.rotate_pairs(R, np.sum(J * qd[None, :], axis=-1))
        np.testing.assert_array_equal(one, numpy_law, strict=True)
        assert (np.signbit(one) == np.signbit(numpy_law)).all()


def test_square_solve_of_the_compiled_period_is_joint_velocitys_solve(psm_batch):
    """The compiled rows' solve (ArmChunk's twist feed-forward) gives numpy's answer to
    rounding, compiled and as Python, and declines where ``joint_velocity`` falls back to
    least squares (a zero pivot, an answer beyond ``_SINGULAR_QD``)."""
    rng, chain, q = psm_batch
    _, J = laws.tip_kinematics(chain, q)
    solvers = [laws.solve_square_into]
    numba = pytest.importorskip("numba")
    from davinci_sim.kinematics import jit

    if jit.ENABLED:
        solve = laws.solve_square_into

        @numba.njit
        def compiled(J, b, A, out):
            return solve(J, b, A, out)

        solvers.append(compiled)
    A, out = np.empty((6, 6)), np.empty(6)
    for solver in solvers:
        for i in range(len(q)):
            w = rng.normal(0, 0.05, 6)
            assert solver(J[i], w, A, out)
            np.testing.assert_allclose(out, laws.joint_velocity(J[i], w), rtol=1e-9, atol=1e-12)
        singular = J[0].copy()
        singular[:, 3] = 0.0  # (a joint that moves nothing: an exact zero pivot)
        assert not solver(singular, np.ones(6), A, out)
        nearly = J[0].copy()
        nearly[:, 3] = 1e-9 * nearly[:, 4]  # (two parallel columns: a huge answer)
        qd = np.full(6, np.nan)
        if np.isfinite(laws._solve(nearly, np.ones(6))).all():
            qd = laws._solve(nearly, np.ones(6))
        declined = not solver(nearly, np.ones(6), A, out)
        assert declined == (not np.abs(qd).max() < laws._SINGULAR_QD)


def _locked_wrist_reference(chain, q, R_base_goal, steps, damping):
    """The orientation lock's DLS as numpy and LAPACK compute it (the law's oracle)."""
    from scipy.linalg.lapack import dgesv

    q = np.array(q, dtype=float)
    for _ in range(steps):
        T, J_spatial = fk.forward_kinematics_and_jacobian(chain, q)
        err = so3.rotation_vector(R_base_goal @ T[:3, :3].T)
        J = J_spatial[3:, 3:]
        q[3:] += J.T @ dgesv(J @ J.T + damping * np.eye(3), err)[2]
    return np.clip(q[3:], chain.qmin[3:], chain.qmax[3:])


@pytest.mark.parametrize("compiled", [True, False])
def test_locked_wrist_goal_is_the_damped_least_squares(compiled):
    chain = load_arm("MTMR").chain
    n = chain.dof
    law = laws.locked_wrist_goal if compiled else laws.locked_wrist_goal.py_func
    rng = np.random.default_rng(3)
    for _ in range(50):
        q = rng.uniform(chain.qmin, chain.qmax)
        T = fk.forward_kinematics(chain, q)
        R_goal = so3.rotation_from_vector(rng.normal(0.0, 0.3, 3)) @ T[:3, :3]
        goal = np.empty(n - 3)
        seed = q.copy()
        assert law(*fk._consts(chain).packed, seed, 3, R_goal, 2, 1e-4, chain.qmin[3:],
                   chain.qmax[3:], np.empty((4, 4)), np.empty((6, n)), np.empty((n, 12)),
                   np.empty((3, 3)), np.empty(3), goal)  # fmt: skip
        expected = _locked_wrist_reference(chain, q, R_goal, 2, 1e-4)
        np.testing.assert_allclose(goal, expected, rtol=0, atol=1e-12)


def test_locked_wrist_goal_reaches_the_orientation():
    """Iterated tick after tick (each seeded with the last answer), the wrist turns the
    handle to the locked orientation."""
    chain = load_arm("MTMR").chain
    n = chain.dof
    q = np.array([0.0, 0.2, 0.1, 0.0, 0.3, 0.2, 0.1])
    T = fk.forward_kinematics(chain, q)
    R_goal = so3.rotation_from_vector([0.2, -0.1, 0.15]) @ T[:3, :3]
    goal = np.empty(n - 3)
    for _ in range(10):
        laws.locked_wrist_goal(*fk._consts(chain).packed, q, 3, R_goal, 2, 1e-4, chain.qmin[3:],
                               chain.qmax[3:], np.empty((4, 4)), np.empty((6, n)),
                               np.empty((n, 12)), np.empty((3, 3)), np.empty(3), goal)  # fmt: skip
        q[3:] = goal
    R = fk.forward_kinematics(chain, q)[:3, :3]
    assert so3.angle_between(R, R_goal) < 1e-6  # (acos: no finer near 0)


@pytest.mark.parametrize("compiled", [True, False])
def test_tracking_watch_is_each_arms_tracking_law(compiled):
    """The watch over many arms gives, arm by arm, ``tracking_bad`` then ``tracking_fault``
    (the first bad joint, when it became bad, whether it faults now), over ticks of random
    errors, for the watched arms only."""
    watch = laws.tracking_watch if compiled else laws.tracking_watch.py_func
    rng = np.random.default_rng(5)
    sizes = [6, 7, 3, 1]
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    n = int(starts[-1])
    adr, idx = rng.permutation(n).astype(np.int64), rng.permutation(n).astype(np.int64)
    tol = rng.uniform(0.01, 0.3, n)
    since = np.full(len(sizes), np.nan)
    expected = since.copy()
    first, fault = np.empty(len(sizes), dtype=np.int64), np.empty(len(sizes), dtype=bool)
    for tick in range(200):
        t = 0.001 * tick
        qpos, q_ref = rng.normal(0, 0.1, n), rng.normal(0, 0.1, n)
        effort = rng.random(n) < 0.2
        watched = rng.random(len(sizes)) < 0.8
        watch(qpos, adr, q_ref, idx, tol, effort, starts, watched, since, t, first, fault)
        for k in range(len(sizes)):
            if not watched[k]:
                assert first[k] == -1 and not fault[k]
                since[k] = expected[k]  # (unwatched: the arm's own value stays)
                continue
            j = slice(starts[k], starts[k + 1])
            bad = laws.tracking_bad(qpos[adr[j]], q_ref[idx[j]], tol[j], effort[idx[j]])
            assert first[k] == (int(np.argmax(bad)) if bad.any() else -1)
            expected[k], now = laws.tracking_fault(bool(bad.any()), expected[k], t)
            assert fault[k] == now
            np.testing.assert_array_equal(since[k], expected[k])
