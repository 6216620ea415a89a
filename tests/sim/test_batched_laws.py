"""The batched forms of the 1 kHz laws against their one-at-a-time originals: the study's
batch engine applies the same laws to many trials, so each must agree row by row."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from davinci_sim.console import teleop_math as tm
from davinci_sim.devices.hand import HandImpedance, hand_wrenches
from davinci_sim.devices.safety import WrenchLimits, clamp_wrench, clamp_wrenches
from davinci_sim.geometry import so3
from davinci_sim.kinematics import fk
from davinci_sim.kinematics.arms import load_arm
from davinci_sim.sim.servo import servo_ctrl


def _rotations(rng, n, max_angle=np.pi):
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = rng.uniform(0, max_angle, n)
    return np.stack([so3.rotation_from_vector(a * t) for a, t in zip(axes, angles, strict=True)])


def _poses(rng, n, max_angle=np.pi):
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = _rotations(rng, n, max_angle)
    T[:, :3, 3] = rng.normal(scale=0.05, size=(n, 3))
    return T


def test_rotation_vector_floats_invert_rodrigues_including_near_zero_and_pi():
    rng = np.random.default_rng(1)
    W = rng.normal(size=(200, 3))
    W *= (rng.uniform(0, np.pi, 200) / np.linalg.norm(W, axis=1))[:, None]
    W[0] = 0.0
    W[1] = [1e-8, 0, 0]
    W[2] = [0, np.pi - 1e-9, 0]
    W[3] = [np.pi, 0, 0]
    W[4] = [0, 0, np.pi - 1e-4]
    for w in W:
        R = so3.rotation_from_vector(w)
        got = np.array(so3.rotation_vector_floats(*R.ravel().tolist()))
        # the rotation it names is R (at π, w and −w name the same rotation)
        np.testing.assert_allclose(so3.rotation_from_vector(got), R, atol=1e-7)
        assert np.linalg.norm(got) == pytest.approx(np.linalg.norm(w), abs=1e-7)


def _hand_reference(target, tip, twist, K, D, imp, hold):
    """The spring-damper written out in numpy, one row: F = K·dp − D·v, τ = K_r·θ·axis − D_r·ω
    (θ·axis recovered by scipy-free Rodrigues inversion: the log of R_target·R_tipᵀ by its
    eigenvector), each clamped."""
    f = K * (target[:3, 3] - tip[:3, 3]) - D * twist[:3]
    tau = -imp.rotational_damping * twist[3:]
    if hold:
        R = target[:3, :3] @ tip[:3, :3].T
        vals, vecs = np.linalg.eig(R)
        axis = np.real(vecs[:, np.argmin(np.abs(vals - 1.0))])
        angle = np.arctan2(
            0.5 * np.dot([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]], axis),
            0.5 * (np.trace(R) - 1.0),
        )
        tau = tau + imp.rotational_stiffness * angle * axis
    for v, limit in ((f, imp.max_force), (tau, imp.max_torque)):
        n = np.linalg.norm(v)
        if n > limit:
            v *= limit / n
    return np.concatenate([f, tau])


@pytest.mark.parametrize("hold", [True, False])
def test_hand_wrenches_against_a_numpy_reference_and_alone_as_in_a_batch(hold):
    rng = np.random.default_rng(2)
    n = 100
    target, tip = _poses(rng, n, 0.6), _poses(rng, n, 0.6)
    tip[:, :3, 3] = target[:, :3, 3] + rng.normal(scale=0.01, size=(n, 3))
    twist = rng.normal(scale=0.3, size=(n, 6))
    K, D = rng.uniform(100, 600, n), rng.uniform(2, 20, n)
    imp = HandImpedance(max_force=5.0, max_torque=0.2)
    batch = hand_wrenches(target, tip, twist, K, D, imp, hold_orientation=hold)
    clamped = [0, 0]
    for i in range(n):
        ref = _hand_reference(target[i], tip[i], twist[i], K[i], D[i], imp, hold)
        np.testing.assert_allclose(batch[i], ref, atol=1e-12)
        one = hand_wrenches(target[i : i + 1], tip[i : i + 1], twist[i : i + 1], K[i : i + 1],
                            D[i : i + 1], imp, hold_orientation=hold)  # fmt: skip
        np.testing.assert_array_equal(one[0], batch[i])  # a row's bits do not depend on n
        clamped[0] += np.isclose(np.linalg.norm(ref[:3]), imp.max_force)
        clamped[1] += np.isclose(np.linalg.norm(ref[3:]), imp.max_torque)
    assert 0 < clamped[0] < n  # both branches of the force clamp were exercised
    assert not hold or 0 < clamped[1] < n
    # without a target the hands only damp
    rest = hand_wrenches(None, tip, twist, K, D, HandImpedance(max_force=1e9, max_torque=1e9))
    np.testing.assert_allclose(rest[:, :3], -D[:, None] * twist[:, :3], rtol=1e-15)


def test_hand_kernel_compiled_and_python_give_the_same_bits():
    from davinci_sim.devices import hand

    rng = np.random.default_rng(3)
    n = 50
    target, tip = _poses(rng, n), _poses(rng, n)
    twist = rng.normal(size=(n, 6))
    args = (target, True, True, tip, twist, rng.uniform(100, 600, n), rng.uniform(2, 20, n))
    args += (0.3, 0.004, 20.0, 0.5)
    compiled, python = np.empty((n, 6)), np.empty((n, 6))
    hand._hand_rows(*args, compiled)
    hand._hand_rows.py_func(*args, python)
    np.testing.assert_array_equal(compiled, python)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_clamp_wrenches_match_clamp_wrench(seed):
    rng = np.random.default_rng(seed)
    n = 16
    limits = WrenchLimits(max_force=3.0, max_torque=0.1, max_force_rate=200.0)
    w = rng.normal(scale=rng.uniform(0.01, 10), size=(n, 6))
    prev = np.array([clamp_wrench(x, np.zeros(6), limits, 1.0)[0] for x in rng.normal(size=(n, 6))])
    batch = clamp_wrenches(w, prev, limits, 0.001)
    for i in range(n):
        np.testing.assert_allclose(
            batch[i], clamp_wrench(w[i], prev[i], limits, 0.001)[0], atol=1e-12
        )


def test_follow_pose_and_twist_broadcast_over_a_batch():
    rng = np.random.default_rng(3)
    n = 20
    psm0, mtm0, mtm = _poses(rng, n), _poses(rng, n), _poses(rng, n)
    offset = _rotations(rng, n)
    scale = rng.uniform(0.1, 1.0, n)
    twist = rng.normal(size=(n, 6))
    goals = tm.follow_pose(psm0, mtm0, mtm, offset, scale)
    twists = tm.follow_twist(twist, scale, use_angular=True)
    for i in range(n):
        goal = tm.follow_pose(psm0[i], mtm0[i], mtm[i], offset[i], scale[i])
        np.testing.assert_allclose(goals[i], goal, atol=1e-15)
        np.testing.assert_allclose(
            goal[:3, 3], psm0[i, :3, 3] + scale[i] * (mtm[i, :3, 3] - mtm0[i, :3, 3])
        )
        np.testing.assert_allclose(twists[i], tm.follow_twist(twist[i], scale[i], use_angular=True))


def test_batched_pose_and_jacobian_equal_the_single_configuration_ones():
    kin = load_arm("MTMR")
    rng = np.random.default_rng(4)
    q = rng.uniform(kin.chain.qmin, kin.chain.qmax, size=(30, kin.chain.dof))
    T, J = fk.forward_kinematics_and_jacobian(kin.chain, q)
    for i in range(len(q)):
        T1, J1 = fk.forward_kinematics_and_jacobian(kin.chain, q[i])
        np.testing.assert_allclose(T[i], T1, atol=1e-12)
        np.testing.assert_allclose(J[i], J1, atol=1e-12)


def test_servo_ctrl_realises_pd_gravity_and_effort_modes():
    kp, kv = np.array([100.0, 50.0]), np.array([2.0, 1.0])
    q, qd, bias = np.array([0.1, 0.2]), np.array([0.5, -0.5]), np.array([1.0, -2.0])
    q_ref, qd_ref, ff = np.array([0.3, 0.0]), np.array([0.1, 0.2]), np.array([0.5, 0.25])
    effort = np.array([False, True])
    ctrl = servo_ctrl(q, qd, bias, q_ref, qd_ref, ff, effort, np.array([True, True]), kp, kv)
    # The actuator force kp·(ctrl − q) − kv·q̇ is the servo law of sim/servo.py.
    force = kp * (ctrl - q) - kv * qd
    np.testing.assert_allclose(force[0], 100 * 0.2 + 2 * (0.1 - 0.5) + 1.0 + 0.5)
    np.testing.assert_allclose(force[1], -2.0 + 0.25)  # effort mode: gravity + feed-forward
    batch = servo_ctrl(
        np.stack([q, q]), np.stack([qd, qd]), np.stack([bias, bias]), q_ref, qd_ref, ff,
        effort, np.array([True, False]), kp, kv,
    )  # fmt: skip
    np.testing.assert_allclose(
        batch[0],
        servo_ctrl(q, qd, bias, q_ref, qd_ref, ff, effort, np.array([True, False]), kp, kv),
    )


def test_one_actuators_servo_ctrl_is_the_batch_law_bit_for_bit():
    """The compiled rows' servo (sim.rows_chunk) on floats: the batch law's bits, masks
    included."""
    from davinci_sim.sim.servo import servo_ctrl_scalar

    rng = np.random.default_rng(8)
    n = 500
    args = [rng.normal(size=n) for _ in range(6)]
    effort, gravity = rng.random(n) < 0.3, rng.random(n) < 0.7
    kp, kv = rng.uniform(1, 500, n), rng.uniform(0.1, 20, n)
    batch = servo_ctrl(*args, effort, gravity, kp, kv)
    one = [servo_ctrl_scalar(*(float(a[i]) for a in args), bool(effort[i]), bool(gravity[i]),
                             float(kp[i]), float(kv[i])) for i in range(n)]  # fmt: skip
    np.testing.assert_array_equal(np.array(one), batch, strict=True)
