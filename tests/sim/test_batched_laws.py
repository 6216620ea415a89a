"""The batched forms of the 1 kHz laws against their one-at-a-time originals: the study's
batch engine applies the same laws to many trials, so each must agree row by row."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from davinci_sim.console import teleop_math as tm
from davinci_sim.devices.hand import HandImpedance, hand_wrench, hand_wrenches
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


def test_rotation_vectors_match_the_scalar_law_including_near_zero_and_pi():
    rng = np.random.default_rng(1)
    R = _rotations(rng, 200)
    R[0] = np.eye(3)
    R[1] = so3.rotation_from_vector([1e-8, 0, 0])
    R[2] = so3.rotation_from_vector([0, np.pi - 1e-9, 0])
    R[3] = so3.rotation_from_vector([np.pi, 0, 0])
    batch = so3.rotation_vectors(R)
    for r, w in zip(R, batch, strict=True):
        np.testing.assert_allclose(w, so3.rotation_vector(r), atol=1e-12)
    assert so3.rotation_vectors(R.reshape(20, 10, 3, 3)).shape == (20, 10, 3)


@pytest.mark.parametrize("hold", [True, False])
def test_hand_wrenches_match_hand_wrench_row_by_row(hold):
    rng = np.random.default_rng(2)
    n = 100
    target, tip = _poses(rng, n, 0.6), _poses(rng, n, 0.6)
    tip[:, :3, 3] = target[:, :3, 3] + rng.normal(scale=0.01, size=(n, 3))
    twist = rng.normal(scale=0.3, size=(n, 6))
    K, D = rng.uniform(100, 600, n), rng.uniform(2, 20, n)
    base = HandImpedance(max_force=5.0)
    batch = hand_wrenches(target, tip, twist, K, D, base, hold_orientation=hold)
    clamped = 0
    for i in range(n):
        imp = HandImpedance(
            stiffness=K[i], damping=D[i], max_force=base.max_force, max_torque=base.max_torque
        )
        one = hand_wrench(target[i], tip[i], twist[i], imp, hold_orientation=hold)
        np.testing.assert_allclose(batch[i], one, atol=1e-12)
        clamped += np.isclose(np.linalg.norm(one[:3]), base.max_force)
    assert 0 < clamped < n  # both branches of the force clamp were exercised


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
