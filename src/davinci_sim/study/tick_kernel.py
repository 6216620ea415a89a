"""The compiled tick of :class:`~davinci_sim.study.batch.TrialBatch` (numba only: imported by
:mod:`davinci_sim.study.batch` when :data:`davinci_sim.sim.rows_step.COMPILED`, MuJoCo's
library then being loaded into LLVM's symbols).

Two calls per tick, over every row of the batch, between the trainee's hand (Python: the
trainee's plan and noise) and the task's sample (Python: the task's state machine):

* :func:`teleop_rows` — the teleoperation's following tick (``TrialBatch._teleop``): the
  PSM goal (``teleop_math.follow_pose``), its closed-form IK and limits, the twist
  feed-forward (``follow_twist``, ``joint_velocity``), the jaw (``follow_jaw``,
  ``finger_setpoints``); the following laws are the live teleoperation's compiled rows
  (``console/teleop_row.py``). It first solves every row and writes nothing if any row needs
  what it has no compiled form of (an IK answer to polish, a singular Jacobian's least
  squares): it returns True and the caller runs the Python tick's teleoperation instead.
* :func:`physics_rows` — the PSM's tracking watch, the joint servo, ``mj_step`` of the rows
  still running, the servo's bias forces, both arms' kinematics (``TrialBatch._kinematics``)
  and the haptic loop (``TrialBatch._haptics``: the velocity filter, the fixture of
  each row's condition in the task's frame, the safety clamp, Jᵀw on the MTM).

Each law is the per-row compiled form of the batch law the Python tick calls (listed at each
step); the Python tick stays as the fallback and the tests' oracle.
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.console.teleop_row import follow_jaw_row as _follow_jaw
from davinci_sim.console.teleop_row import follow_pose_row as _follow_pose
from davinci_sim.console.teleop_row import follow_twist_row as _follow_twist
from davinci_sim.devices.safety import _clamp_rows
from davinci_sim.haptics.fixture_row import fixture_law_row
from davinci_sim.kinematics.fk_compiled import tip_pose_row
from davinci_sim.sim.arm_laws import (
    LIMIT_SLACK,
    tracking_fault_scalar,
    twist_row,
    wrench_effort_row,
)
from davinci_sim.sim.cartesian_kernel import (
    OK,
    cartesian_setpoint_row,
    ik_scratch,
    pose_in_reference_into,
)
from davinci_sim.sim.chunk_kernel import servo_step_row

_clamp = _clamp_rows.dispatcher
_twist = twist_row.dispatcher
_effort = wrench_effort_row.dispatcher


#: :func:`teleop_rows`' arguments (``tp``), in order: the anchors, the MTM's pose and
#: twist, the scale and the twist's parts; the RCM in the camera, the joints, the PSM's
#: Jacobian and the servo's references; the IK's and FK's constants; the jaw's mapping and
#: state; scratch rows for the IK's answers.
TELEOP_ARGS = (
    "T_camera_psm0", "T_hrsv_mtm0", "T_mtm", "R_offset", "scale", "use_linear", "use_angular",
    "twist_mtm", "T_rcm_camera", "Q", "psm_q", "J_psm", "q_ref", "qd_ref", "psm_act", "qmin",
    "qmax", "ik_geometry", "ik_tool", "ik_revolute", "ik_lo", "ik_hi", "fk_links",
    "fk_modified", "fk_tool", "fk_identity", "ik_tolerance", "gripper_q", "jaw_act", "ghost",
    "catching_up", "jaw_sent", "rate", "rate_after_clutch", "dt", "jaw_s", "jaw_o", "jaw_min",
    "jaw_max", "catch_up_tolerance", "q_ik", "ok", "qd",
)  # fmt: skip

#: :func:`physics_rows`' arguments after its time (``pp``), in order: the simulations
#: (``rows_step``'s pointers), the trials' state, the tracking watch and the servo, the
#: rows' state, both arms' kinematics, the velocity filter, the fixture and its path, the
#: clamp and Jᵀw.
PHYSICS_ARGS = (
    "model", "data", "address", "body", "active", "fault", "bad_since", "psm_act", "psm_q",
    "tolerance", "qposadr", "dofadr", "minus_gravcomp", "kp", "kv", "effort", "gravity", "Q",
    "V", "QB", "QG", "XI", "bias", "q_ref", "qd_ref", "tau_ff", "xfrc", "psm_links",
    "psm_modified", "psm_tool", "psm_identity", "T_camera_rcm", "T_psm", "J_psm", "mtm_links",
    "mtm_modified", "mtm_tool", "mtm_identity", "T_hrsv_mtmbase", "mtm_q", "mtm_v", "T_mtm",
    "J_mtm", "twist_mtm", "vf_p", "vf_v", "vf_started", "vf_dt", "vf_alpha", "T_task_camera",
    "cond", "B", "G_max", "transition", "law", "law_params", "centre", "basis", "AE", "AA", "EE",
    "starts", "edges", "cumulative", "lengths", "requested", "wrench_sent", "max_force",
    "max_torque", "max_force_step", "max_torque_step", "mtm_act", "ftmax",
)  # fmt: skip

# Where the kernels read one argument by name: its position in the tuple (numba takes a
# module's integers as constants, so each item keeps its own type). The kernels that unpack
# a whole tuple name every item in order (``tests/study/test_tick_kernel.py`` checks those
# names against the tuples').
T_Q, T_PSM_Q = TELEOP_ARGS.index("Q"), TELEOP_ARGS.index("psm_q")
P_ACTIVE, P_FAULT, P_BAD_SINCE = (PHYSICS_ARGS.index(n) for n in ("active", "fault", "bad_since"))
P_PSM_ACT, P_PSM_Q, P_TOLERANCE = (PHYSICS_ARGS.index(n) for n in ("psm_act", "psm_q", "tolerance"))
P_KP, P_EFFORT, P_Q, P_V = (PHYSICS_ARGS.index(n) for n in ("kp", "effort", "Q", "V"))
P_Q_REF, P_TAU_FF, P_XFRC = (PHYSICS_ARGS.index(n) for n in ("q_ref", "tau_ff", "xfrc"))
P_PSM_LINKS, P_T_PSM = PHYSICS_ARGS.index("psm_links"), PHYSICS_ARGS.index("T_psm")
P_T_HRSV_MTMBASE, P_MTM_Q = PHYSICS_ARGS.index("T_hrsv_mtmbase"), PHYSICS_ARGS.index("mtm_q")
P_T_MTM, P_TWIST_MTM = PHYSICS_ARGS.index("T_mtm"), PHYSICS_ARGS.index("twist_mtm")
P_REQUESTED, P_WRENCH_SENT = PHYSICS_ARGS.index("requested"), PHYSICS_ARGS.index("wrench_sent")
P_MTM_ACT = PHYSICS_ARGS.index("mtm_act")


@numba.njit(cache=True, nogil=True)
def teleop_rows(*tp):
    """The following tick of every row (module docstring); False when done, True (nothing
    written) when a row needs the Python tick. ``tp``: :data:`TELEOP_ARGS`."""
    Q, psm_q = tp[T_Q], tp[T_PSM_Q]
    scratch = teleop_scratch(psm_q.shape[0])
    for r in range(Q.shape[0]):
        if teleop_solve_row(r, tp, scratch):
            return True
    for r in range(Q.shape[0]):
        teleop_write_row(r, tp)
    return False


@numba.njit(cache=True, nogil=True)
def teleop_scratch(dof):
    """The scratch arrays of :func:`teleop_solve_row` for a PSM of ``dof`` joints."""
    T_goal, seed, q1, success, status, info = ik_scratch(dof)
    return (T_goal, seed, q1, success, status, info, np.empty((dof, dof)), np.empty(6),
            np.empty(6), np.empty((4, 4)))  # fmt: skip


@numba.njit(cache=True, nogil=True)
def teleop_solve_row(r, tp, scratch):
    """Row ``r``'s goal, IK and feed-forward into ``q_ik[r]``, ``ok[r]``, ``qd[r]`` (``tp``:
    :data:`TELEOP_ARGS`): True (nothing written) when the row needs
    the Python tick."""
    (T_camera_psm0, T_hrsv_mtm0, T_mtm, R_offset, scale, use_linear, use_angular, twist_mtm,
     T_rcm_camera, Q, psm_q, J_psm, _, _, _, qmin, qmax, ik_geometry, ik_tool, ik_revolute,
     ik_lo, ik_hi, fk_links, fk_modified, fk_tool, fk_identity, ik_tolerance, _, _, _, _, _, _,
     _, _, _, _, _, _, _, q_ik, ok, qd) = tp  # fmt: skip
    T_goal, seed, q1, success, status, info, A, local, twist, G = scratch
    dof = psm_q.shape[0]
    # --- follow_pose: p0 + s·(p_mtm − p_mtm0), R_mtm·R_offset (dvrk.md 4.2)
    _follow_pose(T_camera_psm0, T_hrsv_mtm0, T_mtm[r], R_offset, scale, False, False, G)
    pose_in_reference_into(T_rcm_camera, G, T_goal[0])  # the goal in the RCM frame
    for i in range(dof):
        seed[0, i] = Q[r, psm_q[i]]
    # --- follow_twist, then the twist in the RCM axes (rotate_pairs)
    _follow_twist(twist_mtm[r], scale, use_linear, use_angular, False, False, twist)
    for h in range(2):
        x, y, z = twist[3 * h], twist[3 * h + 1], twist[3 * h + 2]
        for i in range(3):
            local[3 * h + i] = (
                x * T_rcm_camera[i, 0] + y * T_rcm_camera[i, 1] + z * T_rcm_camera[i, 2]
            )
    # --- the IK and J⁻¹·twist (servo_cp's law, sim/cartesian_kernel.py)
    if cartesian_setpoint_row(ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, fk_links,
                              fk_modified, fk_tool, fk_identity, ik_tolerance, T_goal, seed,
                              J_psm[r], local, A, q1, success, status, info,
                              qd[r]) != OK:  # fmt: skip
        return True
    good = success[0]
    for i in range(dof):
        q_ik[r, i] = q1[0, i]
        good = good and q1[0, i] >= qmin[i] - LIMIT_SLACK and q1[0, i] <= qmax[i] + LIMIT_SLACK
    ok[r] = good
    return False


@numba.njit(cache=True, nogil=True)
def teleop_write_row(r, tp):
    """Row ``r``'s solved setpoints (:func:`teleop_solve_row`) into the servo's references,
    then the jaw (``tp``: :data:`TELEOP_ARGS`)."""
    (_, _, _, _, _, _, _, _, _, Q, psm_q, _, q_ref, qd_ref, psm_act, _, _, _, _, _, _, _, _, _,
     _, _, _, gripper_q, jaw_act, ghost, catching_up, jaw_sent, rate, rate_after_clutch, dt,
     jaw_s, jaw_o, jaw_min, jaw_max, catch_up_tolerance, q_ik, ok, qd) = tp  # fmt: skip
    if ok[r]:
        for i in range(psm_q.shape[0]):
            q_ref[r, psm_act[i]] = q_ik[r, i]
            qd_ref[r, psm_act[i]] = qd[r, i]
    # --- follow_jaw (dvrk.md 4.2), sent when it changes (finger_setpoints: half each)
    gripper = Q[r, gripper_q[0]]  # (numpy's sum starts from the first element)
    for i in range(1, gripper_q.shape[0]):
        gripper = gripper + Q[r, gripper_q[i]]
    ghost[r], catching_up[r], jaw = _follow_jaw(
        ghost[r], gripper, catching_up[r], rate, rate_after_clutch, dt, jaw_s, jaw_o,
        jaw_min, jaw_max, catch_up_tolerance,
    )  # fmt: skip
    if jaw != jaw_sent[r]:
        jaw_sent[r] = jaw
        for i in range(jaw_act.shape[0]):
            q_ref[r, jaw_act[i]] = 0.5 * jaw
            qd_ref[r, jaw_act[i]] = 0.0


@numba.njit(cache=True, nogil=True)
def physics_rows(t, *pp):
    """Tracking at ``t`` (s), servo, physics, kinematics and haptics of every row (module
    docstring). ``pp``: :data:`PHYSICS_ARGS`; ``active`` and ``fault`` (n,) are updated in
    place (a tracking fault ends the row's trial); only rows still active step."""
    active, Q = pp[P_ACTIVE], pp[P_Q]
    scratch = physics_scratch(pp)
    for r in range(Q.shape[0]):  # the PSM's tracking watch first, for every row
        tracking_row(r, t, pp)
    for r in range(Q.shape[0]):
        if active[r]:
            step_row(r, pp, scratch)
        haptics_row(r, pp, scratch)


@numba.njit(cache=True, nogil=True)
def physics_scratch(pp):
    """The scratch arrays of :func:`step_row` and :func:`haptics_row` (``pp``:
    :data:`PHYSICS_ARGS`)."""
    psm_q, kp, mtm_q, mtm_act = pp[P_PSM_Q], pp[P_KP], pp[P_MTM_Q], pp[P_MTM_ACT]
    T_hrsv_mtmbase = pp[P_T_HRSV_MTMBASE]
    dof, nu = psm_q.shape[0], kp.shape[0]
    Q, V = pp[P_Q], pp[P_V]
    R_base_hrsv = np.empty((3, 3))  # (the wrench's axes in the MTM's base)
    for i in range(3):
        for m in range(3):
            R_base_hrsv[i, m] = T_hrsv_mtmbase[m, i]
    return (np.arange(Q.shape[1]), np.arange(V.shape[1]), np.arange(nu), np.empty(nu),
            np.empty(dof), np.empty(mtm_q.shape[0]), np.empty(mtm_q.shape[0]), np.empty((4, 4)),
            np.empty((max(dof, mtm_q.shape[0]), 12)), np.empty(8), np.empty(3), np.empty(3),
            np.empty(3), np.empty((1, 6)), np.empty((1, 6)), R_base_hrsv,
            np.empty(mtm_act.shape[0]))  # fmt: skip


@numba.njit(cache=True, nogil=True)
def tracking_row(r, t, pp):
    """The PSM's tracking watch of row ``r`` at ``t`` s (``arm_laws.tracking_bad`` /
    ``tracking_fault``): a fault ends the row's trial (``active``, ``fault``)."""
    active, fault, bad_since = pp[P_ACTIVE], pp[P_FAULT], pp[P_BAD_SINCE]
    psm_act, psm_q, tolerance, effort = pp[P_PSM_ACT], pp[P_PSM_Q], pp[P_TOLERANCE], pp[P_EFFORT]
    Q, q_ref = pp[P_Q], pp[P_Q_REF]
    bad = False
    for i in range(psm_q.shape[0]):
        a = psm_act[i]
        bad = bad or (abs(Q[r, psm_q[i]] - q_ref[r, a]) > tolerance[i] and not effort[a])
    since, now = tracking_fault_scalar(bad, bad_since[r], t)
    bad_since[r] = since
    if now and active[r]:
        fault[r] = True
        active[r] = False


@numba.njit(cache=True, nogil=True)
def step_row(r, pp, scratch):
    """Row ``r``'s servo, ``mj_step``, state read back and bias forces."""
    (model, data, address, body, _, _, _, _, _, _, qposadr, dofadr, minus_gravcomp, kp, kv,
     effort, gravity, Q, V, QB, QG, XI, bias, q_ref, qd_ref, tau_ff,
     xfrc) = pp[:P_PSM_LINKS]  # fmt: skip
    qadr, dadr, act, ctrl = scratch[0], scratch[1], scratch[2], scratch[3]
    servo_step_row(
        model[r], data[r], address[r], r, qadr, dadr, act, qposadr, dofadr, True,
        minus_gravcomp, kp, kv, effort, gravity, Q, V, QB, QG, bias, q_ref, qd_ref,
        tau_ff, ctrl, body, xfrc, XI,
    )  # fmt: skip


@numba.njit(cache=True, nogil=True)
def haptics_row(r, pp, scratch):
    """Row ``r``'s kinematics (``tip_kinematics``, ``pose_in_reference``,
    ``twist_in_reference``), velocity filter and fixture in the task's frame (the live
    haptic loop's row, ``haptics/fixture_row.py``), the safety clamp (``clamp_wrenches``)
    and Jᵀw on the MTM (``wrench_effort``): elementwise, as the batch laws."""
    (psm_q, Q, V, tau_ff, psm_links, psm_modified, psm_tool, psm_identity, T_camera_rcm, T_psm,
     J_psm, mtm_links, mtm_modified, mtm_tool, mtm_identity, T_hrsv_mtmbase, mtm_q, mtm_v,
     T_mtm, J_mtm, twist_mtm, vf_p, vf_v, vf_started, vf_dt, vf_alpha, T_task_camera, cond, B,
     G_max, transition, law, law_params, centre, basis, AE, AA, EE, starts, edges, cumulative,
     lengths,
     requested, wrench_sent, max_force, max_torque, max_force_step, max_torque_step, mtm_act,
     ftmax) = (pp[P_PSM_Q], pp[P_Q], pp[P_V], pp[P_TAU_FF], *pp[P_PSM_LINKS:])  # fmt: skip
    _, _, _, _, q, qm, qdm, T, F, cp, pt, vt, f, W, out, R_base_hrsv, tau = scratch
    for i in range(psm_q.shape[0]):
        q[i] = Q[r, psm_q[i]]
    tip_pose_row(psm_links, psm_modified, psm_tool, psm_identity, q, T, J_psm[r], True, F)
    pose_in_reference_into(T_camera_rcm, T, T_psm[r])
    for i in range(qm.shape[0]):
        qm[i] = Q[r, mtm_q[i]]
        qdm[i] = V[r, mtm_v[i]]
    tip_pose_row(mtm_links, mtm_modified, mtm_tool, mtm_identity, qm, T, J_mtm[r], True, F)
    pose_in_reference_into(T_hrsv_mtmbase, T, T_mtm[r])
    _twist(T_hrsv_mtmbase[:3, :3], J_mtm[r], qdm, twist_mtm[r])
    k = cond[r]
    fixture_law_row(
        T_task_camera, T_psm[r, :3, 3], vf_p[r], vf_v[r], vf_started[r], vf_dt, vf_alpha,
        centre, basis, AE, AA, EE, starts, edges, cumulative, lengths,
        B[k], G_max[k], transition[k], True, law[k], 0, law_params[k], cp, pt, vt, f,
        requested[r],
    )  # fmt: skip
    vf_started[r] = True
    for i in range(3):
        W[0, i] = requested[r, i]
        W[0, 3 + i] = 0.0
    _clamp(W, wrench_sent[r : r + 1], max_force, max_torque, max_force_step, max_torque_step,
           out)  # fmt: skip
    for i in range(6):
        wrench_sent[r, i] = out[0, i]
    _effort(J_mtm[r], R_base_hrsv, wrench_sent[r], ftmax, tau)
    for i in range(mtm_act.shape[0]):
        tau_ff[r, mtm_act[i]] = tau[i]
