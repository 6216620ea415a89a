"""The PSM teleoperation's following tick as compiled rows (numba only: imported where
:data:`davinci_sim.kinematics.jit.ENABLED`).

The per-row forms of :mod:`~davinci_sim.console.teleop_math`'s following laws (dvrk.md 4.2):

* :func:`follow_pose_row` — ``follow_pose``: the PSM goal in the camera frame;
* :func:`follow_twist_row` — ``follow_twist``: the velocity feed-forward, camera axes;
* :func:`follow_jaw_row` — ``follow_jaw`` on one teleoperation.

The study's compiled tick calls them for each of its rows (``study/tick_kernel.py``), and the
live teleoperation calls :func:`follow_tick` once per tick while it follows: the three laws
and ``servo_cp``'s common answer (:func:`~davinci_sim.sim.cartesian_kernel.servo_cp_row`)
in one compiled call, the PSM's joint setpoint written as ``servo_cp`` writes it. What has no
compiled form (a refusal and its message, an IK answer to polish) stays with the Python path
(``TeleopPSM._run_enabled``), which is also the tests' oracle. Operation by operation as
the Python laws, without fused multiply-adds; the goal's rotation ``R_mtm·R_offset`` is
summed in index order, which numpy's matrix product need not do (the two agree to an ulp).
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.kinematics.scratch import local
from davinci_sim.sim.cartesian_kernel import servo_cp_row

_servo_cp = servo_cp_row  # (a compiled kernel: callable from the kernels below)


@numba.njit(cache=True, nogil=True)
def _py_max(a, b):
    """Python's ``max(a, b)`` (the first unless the second is greater: NaN as Python)."""
    return b if b > a else a


@numba.njit(cache=True, nogil=True)
def _py_min(a, b):
    """Python's ``min(a, b)``."""
    return b if b < a else a


@numba.njit(cache=True, nogil=True)
def follow_pose_row(
    T_camera_psm0, T_hrsv_mtm0, T_hrsv_mtm, R_offset, scale, translation_locked,
    rotation_locked, T_camera_goal,
):  # fmt: skip
    """``follow_pose`` of one teleoperation into ``T_camera_goal`` (4, 4): translation
    ``p_psm0 + scale·(p_mtm − p_mtm0)`` (or ``p_psm0``), rotation ``R_mtm·R_offset`` (or
    ``R_psm0``); poses in the camera (PSM) and HRSV (MTM) frames, m."""
    for i in range(3):
        if translation_locked:
            T_camera_goal[i, 3] = T_camera_psm0[i, 3]
        else:
            T_camera_goal[i, 3] = T_camera_psm0[i, 3] + scale * (
                T_hrsv_mtm[i, 3] - T_hrsv_mtm0[i, 3]
            )
        for m in range(3):
            if rotation_locked:
                T_camera_goal[i, m] = T_camera_psm0[i, m]
            else:
                t = 0.0
                for h in range(3):
                    t = t + T_hrsv_mtm[i, h] * R_offset[h, m]
                T_camera_goal[i, m] = t
    T_camera_goal[3, 0] = 0.0
    T_camera_goal[3, 1] = 0.0
    T_camera_goal[3, 2] = 0.0
    T_camera_goal[3, 3] = 1.0


@numba.njit(cache=True, nogil=True)
def follow_twist_row(
    twist_hrsv_mtm, scale, use_linear, use_angular, translation_locked, rotation_locked,
    twist_camera,
):  # fmt: skip
    """``follow_twist`` of one teleoperation into ``twist_camera`` (6,): the scaled MTM
    linear velocity (m/s) and, if asked, its angular velocity (rad/s); zero where locked."""
    for i in range(3):
        twist_camera[i] = (
            scale * twist_hrsv_mtm[i] if use_linear and not translation_locked else 0.0
        )
        twist_camera[3 + i] = twist_hrsv_mtm[3 + i] if use_angular and not rotation_locked else 0.0


@numba.njit(cache=True, nogil=True)
def follow_jaw_row(
    ghost, gripper, catching_up, rate, rate_after_clutch, dt, jaw_scale, jaw_offset, jaw_min,
    jaw_max, catch_up_tolerance,
):  # fmt: skip
    """``follow_jaw`` of one teleoperation: ``(ghost, catching_up, jaw)`` (rad), the same
    comparisons as the Python scalar form (NaN included)."""
    step = (rate_after_clutch if catching_up else rate) * dt
    ghost = ghost + _py_min(_py_max(gripper - ghost, -step), step)
    catching_up = catching_up and abs(ghost - gripper) > catch_up_tolerance
    return ghost, catching_up, _py_min(_py_max(jaw_scale * ghost + jaw_offset, jaw_min), jaw_max)


@numba.njit(cache=True, nogil=True)
def follow_tick(
    ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, fk_links, fk_modified, fk_tool,
    fk_identity, ik_tolerance, T_base_camera, T_camera_psm0, T_hrsv_mtm0, T_hrsv_mtm, R_offset,
    twist_hrsv_mtm, flags, q, J, qmin, qmax, qd_bound, q_out, qd_out, jaw,
):  # fmt: skip
    """One following tick of a live teleoperation (``TeleopPSM._run_enabled``), compiled.

    The goal (:func:`follow_pose_row`) and feed-forward (:func:`follow_twist_row`) through
    ``servo_cp``'s common answer (``servo_cp_row``: the PSM's joint goal into ``q_out``,
    ``qd_out``; ``T_base_camera`` the camera frame in the PSM's base, ``q``/``J`` the
    measured joints and spatial Jacobian), then the jaw (:func:`follow_jaw_row`).

    ``flags`` (5,) float: scale, use_linear, use_angular, translation_locked,
    rotation_locked. ``jaw`` (12,) float, read and updated: ghost, gripper, catching_up,
    rate, rate_after_clutch, dt, jaw_scale, jaw_offset, jaw_min, jaw_max,
    catch_up_tolerance, and the jaw angle out (rad).

    Returns False with nothing computed into ``jaw`` when ``servo_cp`` has no compiled answer
    (the caller runs the Python tick then); True otherwise.
    """
    goal, twist = local(4, 4), local(6)  # (in the frame: every tick)
    scale = flags[0]
    t_locked, r_locked = flags[3] != 0.0, flags[4] != 0.0
    follow_pose_row(T_camera_psm0, T_hrsv_mtm0, T_hrsv_mtm, R_offset, scale, t_locked,
                    r_locked, goal)  # fmt: skip
    follow_twist_row(twist_hrsv_mtm, scale, flags[1] != 0.0, flags[2] != 0.0, t_locked,
                     r_locked, twist)  # fmt: skip
    if not _servo_cp(ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, fk_links, fk_modified,
                     fk_tool, fk_identity, ik_tolerance, T_base_camera, goal, q, J, True, twist,
                     qmin, qmax, qd_bound, q_out, qd_out):  # fmt: skip
        return False
    ghost, catching_up, angle = follow_jaw_row(
        jaw[0],
        jaw[1],
        jaw[2] != 0.0,
        jaw[3],
        jaw[4],
        jaw[5],
        jaw[6],
        jaw[7],
        jaw[8],
        jaw[9],
        jaw[10],
    )
    jaw[0] = ghost
    jaw[2] = 1.0 if catching_up else 0.0
    jaw[11] = angle
    return True


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the live teleoperation's one
    signature: the measured joints and Jacobian read-only (``Arm._measured_kinematics``),
    the MTM's pose and twist read-only (the device's input), the rest writable."""
    from davinci_sim.kinematics.arms import load_arm
    from davinci_sim.sim.cartesian_kernel import servo_cp_constants

    def readonly(a: np.ndarray) -> np.ndarray:
        a.setflags(write=False)
        return a

    chain = load_arm("PSM1").chain
    T = np.eye(4)
    T[2, 3] = -0.1
    args = (*servo_cp_constants(chain), np.eye(4), T, np.eye(4), readonly(np.eye(4)),
            np.eye(3), readonly(np.zeros(6)), np.zeros(5), readonly(np.zeros(6)),
            readonly(np.eye(6)), chain.qmin, chain.qmax, np.ones(6), np.empty(6),
            np.empty(6), np.zeros(12))  # fmt: skip
    follow_tick(*args)
