"""The pure laws of teleoperation and camera control, and the rotation helpers."""

import math

import numpy as np
import pytest
from console_helpers import rotation_about
from hypothesis import given
from hypothesis import strategies as st

from davinci_sim.console import camera_control as cc
from davinci_sim.console import teleop_math as tm
from davinci_sim.geometry import so3

angles = st.floats(-3.0, 3.0)
axes = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda a: np.linalg.norm(a) > 0.1
)


def pose(R, p):
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


@given(axes, angles)
def test_rotation_vector_inverts_rodrigues(axis, angle):
    w = np.asarray(axis) / np.linalg.norm(axis) * angle
    R = so3.rotation_from_vector(w)
    assert so3.is_rotation(R)
    np.testing.assert_allclose(so3.rotation_vector(R), w, atol=1e-7)
    assert so3.rotation_angle(R) == pytest.approx(abs(angle), abs=1e-7)


def test_rotation_vector_near_pi_and_zero():
    for angle in (np.pi, np.pi - 1e-9, 1e-12, 0.0):
        w = np.array([0.0, 0.6, 0.8]) * angle
        np.testing.assert_allclose(
            so3.rotation_vector(so3.rotation_from_vector(w)) * np.sign(w[2] or 1), w, atol=1e-6
        )
    assert not so3.is_rotation(np.diag([1.0, 1.0, -1.0]))
    assert not so3.is_rotation(np.full((3, 3), np.nan))


def test_follow_pose_scale_offset_and_locks():
    R_mtm0 = rotation_about([0, 0, 1], 0.3)
    R_psm0 = rotation_about([1, 0, 0], -0.5)
    T_psm0 = pose(R_psm0, [0.01, 0.02, 0.15])
    T_mtm0 = pose(R_mtm0, [0.1, 0.0, 0.4])
    offset = tm.alignment_offset(R_mtm0, R_psm0)
    dR = rotation_about([0.2, 1, 0], 0.4)
    T_mtm = pose(dR @ R_mtm0, [0.13, -0.01, 0.42])
    T = tm.follow_pose(T_psm0, T_mtm0, T_mtm, offset, 0.2)
    np.testing.assert_allclose(T[:3, 3], [0.016, 0.018, 0.154])
    np.testing.assert_allclose(T[:3, :3] @ R_psm0.T, dR, atol=1e-12)  # same spatial turn
    np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
    locked = tm.follow_pose(
        T_psm0, T_mtm0, T_mtm, offset, 0.2, translation_locked=True, rotation_locked=True
    )
    np.testing.assert_array_equal(locked, T_psm0)
    # At the anchor the goal is the PSM's initial pose (no jump when following starts).
    np.testing.assert_allclose(
        tm.follow_pose(T_psm0, T_mtm0, T_mtm0, offset, 0.2), T_psm0, atol=1e-15
    )


@given(axes, angles, axes, angles, st.floats(0.05, 1.0),
       st.tuples(*[st.floats(-0.05, 0.05)] * 3))  # fmt: skip
def test_lead_pose_is_what_following_maps_to_the_goal(a1, t1, a2, t2, scale, dp):
    """A hand aiming at lead_pose's MTM pose puts the tool at the goal (the scripted
    trainees' way through the console)."""
    R_mtm0, R_psm0 = rotation_about(a1, t1), rotation_about([0, 1, 0], 0.7)
    T_psm0 = pose(R_psm0, [0.01, 0.02, 0.15])
    T_mtm0 = pose(R_mtm0, [0.1, 0.0, 0.4])
    offset = tm.alignment_offset(R_mtm0, R_psm0)
    goal = pose(rotation_about(a2, t2) @ R_psm0, T_psm0[:3, 3] + np.asarray(dp))
    T_mtm = tm.lead_pose(T_psm0, T_mtm0, goal, offset, scale)
    np.testing.assert_allclose(tm.follow_pose(T_psm0, T_mtm0, T_mtm, offset, scale), goal,
                               atol=1e-12)  # fmt: skip
    assert so3.is_rotation(T_mtm[:3, :3])


def test_lead_pose_refuses_a_scale_that_is_not_positive():
    for bad in (0.0, -0.2, math.nan, math.inf):
        with pytest.raises(ValueError, match="positive"):
            tm.lead_pose(np.eye(4), np.eye(4), np.eye(4), np.eye(3), bad)


def test_gripper_for_jaw_inverts_the_jaw_mapping():
    s, o = tm.jaw_mapping(math.radians(80.0), math.radians(-5.0), math.radians(60.0))
    for jaw in (-0.35, 0.0, 0.8, 1.3):
        assert tm.gripper_for_jaw(jaw, s, o) * s + o == pytest.approx(jaw, abs=1e-15)


def test_follow_twist_scales_the_linear_part_and_respects_locks():
    tw = np.array([0.1, 0.2, 0.3, 1.0, 2.0, 3.0])
    np.testing.assert_allclose(tm.follow_twist(tw, 0.2), [0.02, 0.04, 0.06, 0, 0, 0])
    np.testing.assert_allclose(tm.follow_twist(tw, 0.2, use_angular=True)[3:], tw[3:])
    assert not tm.follow_twist(tw, 0.2, translation_locked=True).any()


def test_jaw_mapping_of_the_large_needle_driver():
    s, o = tm.jaw_mapping(math.radians(80), 0.0, math.radians(60))
    assert s == pytest.approx(4 / 3) and o == 0.0  # dvrk.md 4.2
    s, o = tm.jaw_mapping(1.0, 0.2, 0.7)
    assert s * 0.2 + o == pytest.approx(0.0) and s * 0.7 + o == pytest.approx(1.0)


def _jaw(ghost, gripper, catching_up, **kw):
    args = dict(rate=1.0, rate_after_clutch=0.1, dt=0.1, jaw_scale=2.0, jaw_offset=0.0)
    args.update({"jaw_min": -10.0, "jaw_max": 10.0, **kw})
    return tm.follow_jaw(ghost, gripper, catching_up, **args)


def test_follow_jaw_moves_the_ghost_within_the_rate_and_maps_it_to_the_jaw():
    g, c, jaw = _jaw(0.0, 1.0, False)
    assert (g, bool(c), jaw) == (0.1, False, 0.2)  # rate·dt = 0.1, jaw = 2·ghost
    g, _, _ = _jaw(0.0, -1.0, False)
    assert g == -0.1
    g, _, jaw = _jaw(0.0, 0.05, False)
    assert g == 0.05 and jaw == 0.1
    _, _, jaw = _jaw(0.0, 0.05, False, jaw_max=0.08)
    assert jaw == 0.08  # within the jaw's limits


def test_follow_jaw_catches_up_slowly_after_a_clutch_until_within_two_degrees():
    g, c, _ = _jaw(0.0, 1.0, True)
    assert g == pytest.approx(0.01) and c  # rate_after_clutch·dt
    near = 1.0 - math.radians(1.0)
    g, c, _ = _jaw(near, 1.0, True)
    assert g == pytest.approx(near + 0.01) and not c  # within 2°: normal rate from now on
    # a batch: each row its own state, the same numbers as one at a time
    G, C, J = _jaw(
        np.array([0.0, 0.0, near]), np.array([1.0, 1.0, 1.0]), np.array([False, True, True])
    )
    for i, (g0, c0) in enumerate(((0.0, False), (0.0, True), (near, True))):
        assert (G[i], C[i], J[i]) == tuple(_jaw(g0, 1.0, c0))


def test_operator_activity_rule():
    g, r = math.radians(40), math.radians(4)
    assert not tm.operator_active(0.0, 0.0, g, r)
    assert tm.operator_active(g, 0.0, g, r)
    assert tm.operator_active(0.0, r, g, r)
    assert tm.operator_active(0.7 * g, 0.7 * r + 0.1 * g, g, r)  # the 80% sum rule
    assert tm.operator_active(0.0, 0.0, 0.0, r)  # threshold 0: always (simulated system)


def test_hands_geometry_and_camera_motion():
    left, right = np.array([0.18, 0.02, 0.4]), np.array([-0.18, 0.02, 0.4])
    g0 = cc.hands_geometry(left, right)
    np.testing.assert_allclose(g0.center, [0.0, 0.02, 0.4])
    assert g0.half_width == pytest.approx(0.18, abs=1e-3)
    assert cc.camera_motion(g0, g0, 0.2) == pytest.approx((0.0, 0.0, 0.0, 0.0))
    # Hands towards the eyes: insertion = scale x distance change, no turn.
    g = cc.hands_geometry(left - [0, 0, 0.05], right - [0, 0, 0.05])
    motion = cc.camera_motion(g0, g, 0.2)
    assert motion[2] == pytest.approx(0.2 * (np.linalg.norm(g0.center) - np.linalg.norm(g.center)))
    assert motion[0] == pytest.approx(0.0, abs=1e-12)
    # Hands to the right: yaw by the angle of the midpoint seen from the eyes.
    g = cc.hands_geometry(left - [0.05, 0, 0], right - [0.05, 0, 0])
    assert cc.camera_motion(g0, g, 0.2)[0] == pytest.approx(math.atan2(0.05, 0.4))
    # A turn of the hands about the view axis rolls the camera.
    R = rotation_about([0, 0, 1], 0.2)
    g = cc.hands_geometry(R @ left, R @ right)
    assert cc.camera_motion(g0, g, 0.2)[3] == pytest.approx(-0.2, abs=1e-6)
    q = cc.ecm_joint_goal(np.array([0.0, 0.0, 0.1, 0.0]), (0.1, 0.0, 0.01, 0.0))
    np.testing.assert_allclose(q, [0.1, 0.0, 0.11, 0.0])
    # With the camera rolled 90°, an image left/right turn is a pitch of the ECM.
    q = cc.ecm_joint_goal(np.array([0.0, 0.0, 0.1, math.pi / 2]), (0.1, 0.0, 0.0, 0.0))
    np.testing.assert_allclose(q[:2], [0.0, 0.1], atol=1e-12)
    goal_left, goal_right = cc.hands_goals(g0, g0)
    np.testing.assert_allclose(goal_left, left, atol=1e-12)
    np.testing.assert_allclose(goal_right, right, atol=1e-12)
    with pytest.raises(ValueError, match="zero vector"):
        cc.hands_geometry(left, left)
