"""The camera teleoperation's following tick as one compiled row (numba only: the console's
compiled ticks, :mod:`davinci_sim.console.chunk_kernel`, call it).

:meth:`TeleopECM._run_following <davinci_sim.console.teleop_ecm.TeleopECM._run_following>`
with the laws of :mod:`~davinci_sim.console.camera_control` on the same numbers: the hands'
geometry from the two handles' reads, the camera's motion since the anchor, the ECM's joint
goal clipped as the teleoperation and ``servo_jp`` clip it and sent as ``servo_jp`` sends it,
the spring and friction on each hand rendered by its device (the limiter's clamp and Jᵀw,
:func:`~davinci_sim.devices.device_row.render_row`), and each MTM's locked orientation turned
with the camera, as the goal its wrist lock solves for (``MTM._lock_seed``). numpy's cross
products are each component's difference of two products; its norms and dot products are
BLAS's ``ddot`` through ``np.dot``, and its matrix products BLAS's through ``@``, as numpy's
are: the same bits (``tests/console/test_chunk.py`` runs a camera move both ways).

Returns False (nothing written) where the Python tick does something else: hands in a
degenerate placement, a goal that is not a rotation or is out of every joint's range.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from davinci_sim.devices.device_row import render_row
from davinci_sim.geometry.floats import cross3, det3, np_maximum, np_minimum
from davinci_sim.kinematics import jit
from davinci_sim.kinematics.fk_compiled import tip_pose_row
from davinci_sim.sim.validation import MAX_JOINT_VALUE

_max = jit.helper(np_maximum)
_min = jit.helper(np_minimum)
_cross3 = jit.helper(cross3)
_det3 = jit.helper(det3)


@numba.njit(cache=True, nogil=True)
def _cross(a, b) -> np.ndarray:
    out = np.empty(3)
    out[0], out[1], out[2] = _cross3(a[0], a[1], a[2], b[0], b[1], b[2])
    return out


@numba.njit(cache=True, nogil=True)
def _unit(v) -> tuple[bool, np.ndarray]:
    """``camera_control._unit``: ``(False, …)`` where it raises (a norm under 1e-12)."""
    n = math.sqrt(np.dot(v, v))
    return not n < 1e-12, v / n


@numba.njit(cache=True, nogil=True)
def _masked(v, m0: float, m1: float, m2: float) -> np.ndarray:
    """``v * (m0, m1, m2)`` (numpy's product by an integer tuple)."""
    out = np.empty(3)
    out[0], out[1], out[2] = v[0] * m0, v[1] * m1, v[2] * m2
    return out


@numba.njit(cache=True, nogil=True)
def _signed_angle(a, b, axis) -> float:
    return math.atan2(np.dot(_cross(a, b), axis), np.dot(a, b))


@numba.njit(cache=True, nogil=True)
def _is_rotation(R) -> bool:
    """``so3.is_rotation`` of a finite 3x3."""
    for i in range(3):
        for j in range(3):
            if not np.isfinite(R[i, j]):
                return False
    E = R.T @ R
    worst = 0.0
    for i in range(3):
        for j in range(3):
            e = abs(E[i, j] - (1.0 if i == j else 0.0))
            if e > worst or e != e:
                worst = e
    if not worst <= 1e-6:
        return False
    return (
        _det3(R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2], R[2, 0], R[2, 1], R[2, 2]) > 0
    )


@numba.njit(cache=True, nogil=True)
def ecm_follow(geo0, consts, friction, q0, q_lim, fk_links, fk_modified, fk_tool, fk_identity,
               T_e, J_e, F_e, R_cam0, R_mtm0, ecm_idx, T_l, tw_l, T_r, tw_r, Rb_l, Rb_r, Tb_l,
               Tb_r, J_l, J_r, dev_idx_l, dev_idx_r, previous, steps, ftmax_l, ftmax_r,
               limited, tau_l, tau_r, active, R_lock, R_goal_l, R_goal_r, q_ref, qd_ref,
               tau_ff, effort) -> bool:  # fmt: skip
    """One following tick of the camera teleoperation (see the module docstring).

    ``geo0``: the anchor's hands geometry (centre (3), up (3), half width, half depth);
    ``consts``: scale, camera roll offset, hands' stiffness, haptic feedback ratio;
    ``friction`` (3,); ``q0`` (4,) the ECM's joints at the anchor; ``q_lim`` (4, 4): the
    chain's limits (min, max) the teleoperation clips to, then the arm's ``servo_jp`` clips
    to; the ECM chain's FK constants and scratch; ``R_cam0`` the camera's orientation at the
    anchor; ``R_mtm0`` (2, 3, 3) the handles' then; ``ecm_idx`` the ECM's servo rows. Per
    MTM (left, right): its read (``T``, ``tw``), its base's rotation and frame in HRSV, its
    Jacobian, its servo rows, the clamp's ``previous`` (2, 6) and ``steps`` (2, 4) and its
    ``ftmax``. Out: ``limited`` (2, 6) (the clamp's next ``previous``: the caller keeps it
    once the tick has run), ``tau_*``, ``active`` (2,), ``R_lock`` (2, 3, 3) the locked
    orientations in HRSV, ``R_goal_*`` the locks' goals in each MTM's base, and the servo's
    references and efforts (written: the Python tick writes the same)."""
    p_l, p_r = np.ascontiguousarray(T_l[:3, 3]), np.ascontiguousarray(T_r[:3, 3])
    # hands_geometry(left, right)
    lr = p_r - p_l
    c = 0.5 * (p_l + p_r)
    ok1, up = _unit(_cross(lr, c))
    ok2, side = _unit(_cross(c, up))
    ok3, c_unit = _unit(c)
    if not (ok1 and ok2 and ok3):  # (the placement's half sizes: the anchor's are used)
        return False
    # camera_motion(initial, current, scale)
    c0, up0 = np.ascontiguousarray(geo0[:3]), np.ascontiguousarray(geo0[3:6])
    X, Y, Z = np.zeros(3), np.zeros(3), np.zeros(3)
    X[0], Y[1], Z[2] = 1.0, 1.0, 1.0
    oks = np.empty(6, dtype=np.bool_)
    oks[0], a = _unit(_masked(c0, 1.0, 0.0, 1.0))
    oks[1], b = _unit(_masked(c, 1.0, 0.0, 1.0))
    d_yaw = -_signed_angle(a, b, Y)
    oks[2], a = _unit(_masked(c0, 0.0, 1.0, 1.0))
    oks[3], b = _unit(_masked(c, 0.0, 1.0, 1.0))
    d_pitch = _signed_angle(a, b, X)
    d_insertion = consts[0] * (math.sqrt(np.dot(c0, c0)) - math.sqrt(np.dot(c, c)))
    oks[4], a = _unit(_masked(up0, 1.0, 1.0, 0.0))
    oks[5], b = _unit(_masked(up, 1.0, 1.0, 0.0))
    d_roll = -_signed_angle(a, b, Z)
    if not oks.all():
        return False
    # ecm_joint_goal(q0, motion, offset), clipped by the teleoperation, then by servo_jp
    r = d_roll + q0[3] + consts[1]
    cr, sr = math.cos(r), math.sin(r)
    q = q0.copy()
    q[0] += d_yaw * cr - d_pitch * sr
    q[1] += d_pitch * cr + d_yaw * sr
    q[2] += d_insertion
    q[3] += d_roll
    for i in range(4):
        q[i] = _min(_max(q[i], q_lim[0, i]), q_lim[1, i])
        if not abs(q[i]) <= MAX_JOINT_VALUE:
            return False
    goal = np.empty(4)
    for i in range(4):
        goal[i] = _min(_max(q[i], q_lim[2, i]), q_lim[3, i])
    # the hands' goals, forces and rendered wrenches (hands_goals, hands_force, servo_cf)
    offset = np.empty(3)
    for i in range(3):
        offset[i] = geo0[6] * side[i] + geo0[7] * c_unit[i]
    W = np.zeros((2, 6))  # (each hand's wrench: the force, then no torque)
    for hand in range(2):
        p = p_l if hand == 0 else p_r
        tw = tw_l if hand == 0 else tw_r
        for i in range(3):
            g = c[i] - offset[i] if hand == 0 else c[i] + offset[i]
            W[hand, i] = consts[3] * (consts[2] * (g - p[i]) - friction[i] * tw[i])
            if not np.isfinite(W[hand, i]):
                return False
    # the camera's turn and the locks' goals (before anything is written)
    tip_pose_row(fk_links, fk_modified, fk_tool, fk_identity, q, T_e, J_e, False, F_e)
    dR = R_cam0.T @ np.ascontiguousarray(T_e[:3, :3])
    R_l = dR.T @ R_mtm0[0]
    R_r = dR.T @ R_mtm0[1]
    if not (_is_rotation(R_l) and _is_rotation(R_r)):
        return False
    # written: the ECM's servo_jp, each hand's render and lock
    for i in range(4):
        j = ecm_idx[i]
        effort[j] = False
        tau_ff[j] = 0.0
        q_ref[j] = goal[i]
        qd_ref[j] = 0.0
    active[0] = render_row(W[0], previous[0], steps[0], Tb_l, J_l, ftmax_l, limited[0], tau_l)
    active[1] = render_row(W[1], previous[1], steps[1], Tb_r, J_r, ftmax_r, limited[1], tau_r)
    for i in range(dev_idx_l.shape[0]):
        tau_ff[dev_idx_l[i]] = tau_l[i]
    for i in range(dev_idx_r.shape[0]):
        tau_ff[dev_idx_r[i]] = tau_r[i]
    R_lock[0], R_lock[1] = R_l, R_r
    R_goal_l[:, :] = Rb_l.T @ R_l
    R_goal_r[:, :] = Rb_r.T @ R_r
    return True
