"""The trainee's wrist: turning the hand along the path as a task with a carried object asks.

A task's ``carry`` (:mod:`davinci_sim.tasks.carry`) gives the tool's turn from its start
orientation at knots of progress along the path (task frame). A trainee who follows the
path turns the MTM's handle by that turn as the plan goes: the hand's target orientation
at time t is ``Rot(w(f)) · R₀``, with R₀ the handle's orientation when the hand took it,
f the planned fraction of the path's length at t (0 before following starts), and w(f)
the turn interpolated linearly between the knots, in the HRSV axes. The dVRK aligns HRSV
with the camera and the teleoperation maps the MTM's orientation to the tool's as
``R_mtm · R_offset`` (dvrk.md 4.2), so turning the handle by a rotation in HRSV turns the
tool by the same rotation in the camera frame: the turns are the task's, taken into the
camera's axes (:meth:`WristTurns.of`).

The turn is planned, not corrected: the trainee does not look at the tool's orientation
(Rota's metric, the tip's distance to the path, does not score it either). Its effect on
the tip comes through the MTM's and the PSM's dynamics: the handle turning under the
hand's rotational spring, the tool's wrist turning with it.

:func:`hand_rotation_row` is written on floats: the study's compiled chunk, its numpy tick
and the live trainee's hand all call it, so that they turn the hand by the same bits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from davinci_sim.kinematics.jit import helper
from davinci_sim.operators.trainee_row import plan_arc_row


@dataclass(frozen=True, eq=False)
class WristTurns:
    """The hand's turns along the path: ``progress`` (K,) knots (fractions of the path's
    length, 0 to 1) and ``turn`` (K, 3) rotation vectors in the HRSV (camera) axes, rad."""

    progress: np.ndarray
    turn: np.ndarray

    @classmethod
    def of(cls, carry, T_task_camera) -> WristTurns | None:
        """The turns of a task's ``carry`` (None: none) for a trainee looking through the
        camera at ``T_task_camera`` (4x4, the camera in the task's frame)."""
        if carry is None:
            return None
        R_camera_task = np.asarray(T_task_camera, dtype=float)[:3, :3].T
        return cls(
            np.ascontiguousarray(carry.progress, dtype=float),
            np.ascontiguousarray(np.asarray(carry.turn, dtype=float) @ R_camera_task.T),
        )


@helper
def plan_fraction_row(knots, T, since, total):
    """The planned fraction of the path's length ``total`` (m) ``since`` s into the
    strokes (``since`` < 0: not following yet, 0), in [0, 1]."""
    if since < 0.0:
        return 0.0
    s, _ = plan_arc_row(knots, T, since)
    f = s / total
    if f < 0.0:
        return 0.0
    if f > 1.0:
        return 1.0
    return f


@helper
def hand_rotation_row(progress, turn, f, R0, out):
    """``Rot(w(f)) · R0`` into ``out`` (3, 3): ``w`` the turn (K, 3) at fraction ``f``,
    linear between the knots ``progress`` (K,) (held beyond them), by Rodrigues' formula."""
    K = progress.shape[0]
    i = 0
    while i < K - 2 and f >= progress[i + 1]:
        i += 1
    span = progress[i + 1] - progress[i]
    a = (f - progress[i]) / span
    if a < 0.0:
        a = 0.0
    elif a > 1.0:
        a = 1.0
    w0 = turn[i, 0] + a * (turn[i + 1, 0] - turn[i, 0])
    w1 = turn[i, 1] + a * (turn[i + 1, 1] - turn[i, 1])
    w2 = turn[i, 2] + a * (turn[i + 1, 2] - turn[i, 2])
    angle = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if angle < 1e-12:
        for r in range(3):
            for c in range(3):
                out[r, c] = R0[r, c]
        return
    k0, k1, k2 = w0 / angle, w1 / angle, w2 / angle
    s, v = math.sin(angle), 1.0 - math.cos(angle)
    # Q = I + s·K + v·K², K the cross-product matrix of the unit axis k
    q00, q01, q02 = 1.0 - v * (k1 * k1 + k2 * k2), -s * k2 + v * k0 * k1, s * k1 + v * k0 * k2
    q10, q11, q12 = s * k2 + v * k0 * k1, 1.0 - v * (k0 * k0 + k2 * k2), -s * k0 + v * k1 * k2
    q20, q21, q22 = -s * k1 + v * k0 * k2, s * k0 + v * k1 * k2, 1.0 - v * (k0 * k0 + k1 * k1)
    for c in range(3):
        x, y, z = R0[0, c], R0[1, c], R0[2, c]
        out[0, c] = q00 * x + q01 * y + q02 * z
        out[1, c] = q10 * x + q11 * y + q12 * z
        out[2, c] = q20 * x + q21 * y + q22 * z
