"""``servo_cp``'s joint setpoint for one PSM, compiled (numba only: imported where
:data:`davinci_sim.kinematics.jit.ENABLED`): the goal in the arm's base, its closed-form IK
seeded with the measured joints, and the twist feed-forward ``J⁻¹·twist`` in the base axes.

:func:`cartesian_setpoint_row` is the one per-row form of that law. The live arm calls it
through :func:`servo_cp_row` for the common answer of every ``servo_cp`` (the teleoperation's
at 1 kHz, and ROS/web clients'), and the study's compiled tick and the environments' control
period call it for each row (``study/tick_kernel.py``, ``sim/chunk_kernel.py``). What it has
no compiled form of (an IK answer to polish, a singular Jacobian's least squares), and the
messages of a refusal, stay with the Python path (:meth:`~davinci_sim.sim.arm.Arm.servo_cp`),
which is also the tests' oracle.
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.kinematics.psm_closed_form import POLISH, SOLVED, closed_form_rows
from davinci_sim.kinematics.scratch import local, local_bool, local_int, local_within
from davinci_sim.sim.arm_laws import other_branch, solve_square_into

_ik_rows = closed_form_rows.dispatcher  # (the compiled kernel itself, callable from here)

#: :func:`cartesian_setpoint_row`'s answers: ``q`` and ``qd`` computed; the IK answer must be
#: polished by the reference iteration (nothing else computed); the Jacobian is singular for
#: the square solve (the IK answer computed, ``qd`` not).
OK, NEEDS_POLISH, SINGULAR = 0, 1, 2


@numba.njit(cache=True, nogil=True)
def pose_in_reference_into(T_ref_base, T_base_tip, out):
    """``out = T_ref_base · T_base_tip`` (4, 4) (``arm_laws.pose_in_reference`` of one
    row), each entry summed in index order."""
    for i in range(4):
        for m in range(4):
            t = 0.0
            for h in range(4):
                t = t + T_ref_base[i, h] * T_base_tip[h, m]
            out[i, m] = t


@numba.njit(cache=True, nogil=True)
def ik_scratch(dof):
    """The arrays of one goal for ``closed_form_rows`` called on a single row from a kernel:
    goal (1, 4, 4), seed, answer (1, dof), success, status, info."""
    return (np.empty((1, 4, 4)), np.empty((1, dof)), np.empty((1, dof)),
            np.empty(1, dtype=np.bool_), np.empty(1, dtype=np.int64), np.empty((1, 5)))  # fmt: skip


@numba.njit(cache=True, nogil=True)
def cartesian_setpoint_row(
    ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, fk_links, fk_modified, fk_tool,
    fk_identity, ik_tolerance, T_goal, seed, J, twist_base, A, q_ik, success, status, info, qd,
):  # fmt: skip
    """The IK of ``T_goal`` (1, 4, 4: the goal in the RCM frame, m) seeded with ``seed``
    (1, dof) into ``q_ik``, ``success``, ``status``, ``info`` (``closed_form_rows`` of one
    row), then ``qd = J⁻¹·twist_base`` (``J`` (dof, dof) the spatial Jacobian at the measured
    joints, ``twist_base`` (6,) m/s and rad/s in the base axes; ``joint_velocity``'s square
    solve, ``A`` scratch). Returns :data:`OK`, :data:`NEEDS_POLISH` or :data:`SINGULAR`."""
    _ik_rows(ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, fk_links, fk_modified, fk_tool,
             fk_identity, T_goal, seed, ik_tolerance, q_ik, success, status, info)  # fmt: skip
    if status[0] == POLISH:
        return NEEDS_POLISH
    if not solve_square_into(J, twist_base, A, qd):
        return SINGULAR
    return OK


@numba.njit(cache=True, nogil=True)
def servo_cp_row(
    ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, fk_links, fk_modified, fk_tool,
    fk_identity, ik_tolerance, T_base_ref, T_ref_goal, q, J, feedforward, twist_ref, qmin, qmax,
    qd_bound, q_out, qd_out,
):  # fmt: skip
    """``Arm.servo_cp``'s common answer, compiled: True with the clipped joint goal in
    ``q_out`` and the feed-forward in ``qd_out`` when the goal ``T_ref_goal`` (4, 4, in the
    arm's reference frame, m) is solved exactly as ``psm_ik_closed_form``'s first branch
    accepts it (solved, within the limits, no insertion or roll adjustment), the Jacobian
    ``J`` at the measured joints ``q`` is regular and the feed-forward of ``twist_ref`` (6,
    m/s and rad/s in the reference axes; zero without ``feedforward``) is within
    ``qd_bound``; False otherwise (the caller runs the Python path, which has the rarer
    answers and the messages). ``T_base_ref``: the reference frame in the arm's base."""
    dof = q.shape[0]
    # (in the frame: this runs every tick; ik_scratch's arrays would be 6 allocations)
    T_goal, seed, q_ik = local(1, 4, 4), local_within(16, 1, dof), local_within(16, 1, dof)
    success, status, info = local_bool(1), local_int(1), local(1, 5)
    # T_base_ref · T_ref_goal (IK works in the base frame, dvrk.md 1.8)
    pose_in_reference_into(T_base_ref, T_ref_goal, T_goal[0])
    for i in range(dof):
        seed[0, i] = q[i]
    twist_base = local(6)
    for h in range(2):  # rotate_pairs(R_ref_base.T, twist): R_base_ref on both halves
        x, y, z = twist_ref[3 * h], twist_ref[3 * h + 1], twist_ref[3 * h + 2]
        for i in range(3):
            twist_base[3 * h + i] = (
                x * T_base_ref[i, 0] + y * T_base_ref[i, 1] + z * T_base_ref[i, 2]
            )
    code = cartesian_setpoint_row(
        ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, fk_links, fk_modified, fk_tool,
        fk_identity, ik_tolerance, T_goal, seed, J, twist_base, local_within(64, dof, dof), q_ik,
        success, status, info, qd_out,
    )  # fmt: skip
    if code == NEEDS_POLISH or not success[0] or status[0] != SOLVED or info[0, 4] != 0.0:
        return False
    if other_branch(q_ik[0], q):  # (refused by the Python path, with its message)
        return False
    if not feedforward:  # servo_cp without a twist: no feed-forward, no solve to fail
        for i in range(dof):
            qd_out[i] = 0.0
    elif code == SINGULAR:
        return False
    for i in range(dof):
        if not abs(qd_out[i]) <= qd_bound[i]:
            return False
        q_out[i] = min(max(q_ik[0, i], qmin[i]), qmax[i])  # clip_goal (dvrk.md 1.1)
    return True


def servo_cp_constants(chain) -> tuple:
    """The PSM ``chain``'s constant arguments of :func:`servo_cp_row` (IK, FK, tolerance)."""
    from davinci_sim.kinematics.psm_ik import _DEFAULT_TOLERANCE, _packed

    p = _packed(chain)
    return (p.geometry, p.tool, p.revolute, p.lim_lo, p.lim_hi, *p.fk, _DEFAULT_TOLERANCE)


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the live arm's one signature:
    measured joints and Jacobian read-only (``Arm._measured_kinematics``), everything else
    writable and C-ordered (the arm copies a goal that is not)."""
    from davinci_sim.kinematics.arms import load_arm

    chain = load_arm("PSM1").chain
    T = np.eye(4)
    T[2, 3] = -0.1
    args = (*servo_cp_constants(chain), np.eye(4), T, _readonly(np.zeros(6)),
            _readonly(np.eye(6)), True, np.zeros(6), chain.qmin, chain.qmax, np.ones(6),
            np.empty(6), np.empty(6))  # fmt: skip
    servo_cp_row(*args)
