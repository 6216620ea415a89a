"""The pure laws of PSM teleoperation (dvrk.md 4.2): goal pose, jaw mapping, operator activity.

Frames: the MTM pose is in the display frame HRSV, the PSM pose in the camera (ECM tip)
frame. The two frames have the same axes by construction (x left, y up, z into the scene),
so the MTM displacement in HRSV *is* the tool displacement in the camera frame, scaled:
moving the camera keeps the mapping intuitive.
"""

from __future__ import annotations

import math

import numpy as np

#: dvrk.md 4.2: after a clutch, the jaw catches up slowly until within 2° of the gripper.
JAW_CATCH_UP_TOLERANCE = math.radians(2.0)
#: dvrk.md 4.2: sum rule of the operator-activity detection.
ACTIVITY_SUM_RATIO = 0.8


def as_scale(value) -> float:
    """A scale command's value as a float (nan when it is not a number: the caller refuses)."""
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):  # OverflowError: a 400-digit integer
        return math.nan


def alignment_offset(R_hrsv_mtm: np.ndarray, R_camera_psm: np.ndarray) -> np.ndarray:
    """``R_mtmᵀ·R_psm``: the constant rotation from MTM to PSM orientation (dvrk.md 4.2)."""
    return R_hrsv_mtm.T @ R_camera_psm


def follow_pose(
    T_camera_psm0: np.ndarray,
    T_hrsv_mtm0: np.ndarray,
    T_hrsv_mtm: np.ndarray,
    R_offset: np.ndarray,
    scale,
    *,
    translation_locked: bool = False,
    rotation_locked: bool = False,
) -> np.ndarray:
    """PSM goal in the camera frame while following (dvrk.md 4.2); poses ``(..., 4, 4)``,
    ``R_offset`` ``(..., 3, 3)`` and ``scale`` ``(...)`` broadcast over a batch of
    teleoperations (the study steps many at once).

    Translation: ``p_psm0 + scale·(p_mtm − p_mtm0)`` (or ``p_psm0`` if locked).
    Rotation: ``R_mtm·R_offset`` (or ``R_psm0`` if locked).
    """
    shape = np.broadcast_shapes(np.shape(T_camera_psm0), np.shape(T_hrsv_mtm))
    T = np.zeros(shape)
    T[..., 3, 3] = 1.0
    p0 = T_camera_psm0[..., :3, 3]
    if translation_locked:
        T[..., :3, 3] = p0
    else:
        s = np.asarray(scale, dtype=float)[..., None]
        T[..., :3, 3] = p0 + s * (T_hrsv_mtm[..., :3, 3] - T_hrsv_mtm0[..., :3, 3])
    if rotation_locked:
        T[..., :3, :3] = T_camera_psm0[..., :3, :3]
    else:
        T[..., :3, :3] = T_hrsv_mtm[..., :3, :3] @ R_offset
    return T


def lead_pose(
    T_camera_psm0: np.ndarray,
    T_hrsv_mtm0: np.ndarray,
    T_camera_psm: np.ndarray,
    R_offset: np.ndarray,
    scale: float,
) -> np.ndarray:
    """The MTM pose (HRSV, 4x4) that :func:`follow_pose` (unlocked) maps to the PSM goal
    ``T_camera_psm``: what a hand on the MTM aims at to put the tool there.

    Translation ``p_mtm0 + (p_psm − p_psm0)/scale``; rotation ``R_psm·R_offsetᵀ``.

    Raises:
        ValueError: a scale that is not a positive finite number.
    """
    s = float(scale)
    if not (math.isfinite(s) and s > 0.0):
        raise ValueError(f"the motion scale must be a positive number, got {scale!r}")
    T = np.eye(4)
    T[:3, 3] = T_hrsv_mtm0[:3, 3] + (T_camera_psm[:3, 3] - T_camera_psm0[:3, 3]) / s
    T[:3, :3] = T_camera_psm[:3, :3] @ R_offset.T
    return T


def follow_twist(
    twist_hrsv_mtm: np.ndarray,
    scale,
    *,
    use_linear: bool = True,
    use_angular: bool = False,
    translation_locked: bool = False,
    rotation_locked: bool = False,
) -> np.ndarray:
    """Velocity feed-forward sent with ``servo_cp`` (camera axes): the scaled MTM linear
    velocity and, if asked, the MTM angular velocity (dvrk.md 4.2); zero where locked.
    ``twist_hrsv_mtm`` ``(..., 6)`` and ``scale`` ``(...)`` broadcast over a batch."""
    twist = np.asarray(twist_hrsv_mtm, dtype=float)
    out = np.zeros(twist.shape)
    if use_linear and not translation_locked:
        out[..., :3] = np.asarray(scale, dtype=float)[..., None] * twist[..., :3]
    if use_angular and not rotation_locked:
        out[..., 3:] = twist[..., 3:]
    return out


def jaw_mapping(jaw_qmax: float, gripper_zero: float, gripper_max: float) -> tuple[float, float]:
    """``(s, o)`` with ``jaw = s·gripper + o``: gripper_zero -> 0, gripper_max -> jaw_qmax
    (dvrk.md 4.2; 80°/60° ≈ 1.333 for the large needle driver)."""
    s = jaw_qmax / (gripper_max - gripper_zero)
    return s, -gripper_zero * s


def gripper_for_jaw(jaw: float, jaw_scale: float, jaw_offset: float) -> float:
    """The gripper opening (rad) whose jaw angle is ``jaw`` under :func:`jaw_mapping`'s
    ``jaw = jaw_scale·gripper + jaw_offset`` (before the jaw's limits)."""
    return (float(jaw) - jaw_offset) / jaw_scale


def follow_jaw(
    ghost,
    gripper,
    catching_up,
    *,
    rate: float,
    rate_after_clutch: float,
    dt: float,
    jaw_scale: float,
    jaw_offset: float,
    jaw_min: float,
    jaw_max: float,
):
    """One tick of the jaw following the gripper (dvrk.md 4.2), any batch shape.

    The *ghost* (a gripper value, rad) moves towards the ``gripper`` by at most ``rate·dt``
    (``rate_after_clutch`` while ``catching_up`` after a clutch, until within
    ``JAW_CATCH_UP_TOLERANCE``); the jaw angle is ``jaw_scale·ghost + jaw_offset`` within
    [``jaw_min``, ``jaw_max``]. Returns ``(ghost, catching_up, jaw)``.
    """
    if isinstance(ghost, float) and isinstance(gripper, float) and np.ndim(catching_up) == 0:
        # One teleoperation: the same operations on floats (ufuncs on scalars cost µs each).
        step = (rate_after_clutch if catching_up else rate) * dt
        ghost = ghost + min(max(gripper - ghost, -step), step)
        catching_up = bool(catching_up) and abs(ghost - gripper) > JAW_CATCH_UP_TOLERANCE
        return ghost, catching_up, min(max(jaw_scale * ghost + jaw_offset, jaw_min), jaw_max)
    step = np.where(catching_up, rate_after_clutch, rate) * dt
    ghost = ghost + np.minimum(np.maximum(gripper - ghost, -step), step)
    catching_up = catching_up & (np.abs(ghost - gripper) > JAW_CATCH_UP_TOLERANCE)
    jaw = np.minimum(np.maximum(jaw_scale * ghost + jaw_offset, jaw_min), jaw_max)
    return ghost, catching_up, jaw


def roll_angle(R_camera_psm: np.ndarray, R_hrsv_mtm: np.ndarray) -> float:
    """Angle (rad) between the y axes of the PSM and MTM orientations: the "roll" the
    operator-activity detection tracks (dvrk.md 4.2)."""
    c = float(R_camera_psm[:, 1] @ R_hrsv_mtm[:, 1])
    return math.acos(max(-1.0, min(1.0, c)))


def operator_active(
    gripper_range: float, roll_range: float, gripper_threshold: float, roll_threshold: float
) -> bool:
    """The dVRK rule (dvrk.md 4.2): the operator is active once the gripper moved over its
    threshold, or the roll over its threshold, or both together over 80% of the sum."""
    return (
        gripper_range >= gripper_threshold
        or roll_range >= roll_threshold
        or gripper_range + roll_range > ACTIVITY_SUM_RATIO * (gripper_threshold + roll_threshold)
    )
