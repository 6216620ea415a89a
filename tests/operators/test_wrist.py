"""The trainee's wrist turns (operators/wrist.py): the turn at the plan's progress, as a
rotation of the hand, checked against Rodrigues' formula by the geometry package and against
the plan's own arc length; the task's turns taken into the camera's axes."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.operators.test_trainee import PATH, TASK, subjects, trainee

from davinci_sim.geometry.so3 import is_rotation, rotation_from_vector
from davinci_sim.operators.plan import path_plan
from davinci_sim.operators.wrist import WristTurns, hand_rotation_row, plan_fraction_row
from davinci_sim.tasks.carry import CarrySpec

PROGRESS = np.array([0.0, 0.3, 1.0])
TURN = np.array([[0.0, 0.0, 0.0], [0.2, -0.5, 0.1], [0.9, 0.4, -0.7]])
R0 = rotation_from_vector([0.3, -1.1, 2.0])


def _reference(f: float) -> np.ndarray:
    """Rot(w(f)) · R0 by numpy's interpolation and the geometry package's Rodrigues."""
    w = np.array([np.interp(f, PROGRESS, TURN[:, i]) for i in range(3)])
    return rotation_from_vector(w) @ R0


@settings(max_examples=60, deadline=None)
@given(st.floats(min_value=-0.5, max_value=1.5))
def test_the_hand_turns_by_the_interpolated_rotation_vector(f):
    out = np.empty((3, 3))
    hand_rotation_row(PROGRESS, TURN, f, R0, out)
    np.testing.assert_allclose(out, _reference(float(np.clip(f, 0.0, 1.0))), atol=1e-14)
    assert is_rotation(out, 1e-12)


def test_no_turn_keeps_the_orientation_and_the_knots_are_hit_exactly():
    out = np.empty((4, 4))  # (a 4x4 target: its rotation block is written, nothing else)
    out[:] = 7.0
    hand_rotation_row(PROGRESS, TURN, 0.0, R0, out)
    assert np.array_equal(out[:3, :3], R0) and (out[3] == 7.0).all() and (out[:, 3] == 7.0).all()
    for f, w in zip(PROGRESS, TURN, strict=True):
        hand_rotation_row(PROGRESS, TURN, f, R0, out)
        np.testing.assert_allclose(out[:3, :3], rotation_from_vector(w) @ R0, atol=1e-14)


def test_the_fraction_is_the_plans_arc_length_over_the_paths():
    knots = TASK.marker_arc_lengths
    T = np.array([[0.7, 1.3, 0.4, 2.0, 0.9][: len(knots) - 1]])
    total = PATH.length
    for since in np.linspace(0.0, T.sum() + 1.0, 41):
        s = path_plan(PATH, knots, T, np.array([since]))[2][0]
        assert plan_fraction_row(knots, T[0], since, total) == min(max(s / total, 0.0), 1.0)
    assert plan_fraction_row(knots, T[0], -np.inf, total) == 0.0  # not following yet
    assert plan_fraction_row(knots, T[0], T.sum() + 5.0, total) == 1.0


def test_the_tasks_turns_are_taken_into_the_cameras_axes():
    """Turning by w_camera = R_camera_task · w_task is turning by w_task in the task's
    frame, seen from the camera: Rot(R w) = R Rot(w) Rᵀ."""
    carry = CarrySpec(0.0064, 0.0007, progress=tuple(PROGRESS), turn=TURN)
    T_task_camera = np.eye(4)
    T_task_camera[:3, :3] = rotation_from_vector([0.4, 1.2, -0.3])
    T_task_camera[:3, 3] = [0.1, 1.2, 0.8]
    wrist = WristTurns.of(carry, T_task_camera)
    R_ct = T_task_camera[:3, :3].T
    for w_camera, w_task in zip(wrist.turn, TURN, strict=True):
        expected = R_ct @ rotation_from_vector(w_task) @ R_ct.T
        np.testing.assert_allclose(rotation_from_vector(w_camera), expected, atol=1e-14)
    assert WristTurns.of(None, T_task_camera) is None


def test_a_trainee_turns_its_hand_as_its_plan_goes():
    params = subjects(2)
    wrist = WristTurns(PROGRESS, TURN)
    tr = trainee(params, wrist=wrist)
    R = np.stack([R0, R0.T])
    # Before following: the first knot's turn (none).
    np.testing.assert_array_equal(tr.hand_rotations(0.0, R), R)
    tr.t_follow[:] = [1.0, 2.0]
    total = PATH.length
    t = 2.5
    got = tr.hand_rotations(t, R)
    for i in range(2):
        s = path_plan(PATH, tr.knots, tr.durations[i : i + 1], np.array([t - tr.t_follow[i]]))
        f = s[2][0] / total
        w = np.array([np.interp(f, PROGRESS, TURN[:, j]) for j in range(3)])
        np.testing.assert_allclose(got[i], rotation_from_vector(w) @ R[i], atol=1e-14)
    # each row at its own progress: different turns
    assert not np.allclose(got[0] @ R[0].T, got[1] @ R[1].T, atol=1e-3)
    # Without a wrist the hand keeps the orientation it took.
    np.testing.assert_array_equal(trainee(params).hand_rotations(t, R), R)
