"""The compiled control period of one arm of the live simulation (numba only: imported by
:mod:`davinci_sim.sim.live_period` once MuJoCo's library is loaded into LLVM's symbols, as
:mod:`davinci_sim.sim.rows_kernel`).

One call runs ticks ``first`` … ``K`` of :meth:`Simulation.tick
<davinci_sim.sim.simulation.Simulation.tick>` for a simulation in which one arm follows a
ramp of setpoints and nothing else runs Python between two steps: per tick, the arm's
``servo_cp`` (:func:`~davinci_sim.sim.cartesian_kernel.servo_cp_row`, with the PSM's
in-cannula check) or ``servo_jp`` (the goal clipped to the limits, the feed-forward bound),
the tracking watch over every arm (:func:`~davinci_sim.sim.arm_laws.tracking_watch_row`),
the joint servo of every actuator (:func:`~davinci_sim.sim.servo.servo_ctrl_scalar`), the
divergence guard's save (``mj_getState``) and ``mj_step``; the arm's base frame follows the
setup and ECM joints as ``Simulation._frames`` computes it.

Where the Python tick would do something the kernel has no form of — a refusal and its
message, an IK answer to polish, a tracking fault, a step that raises one of the divergence
guard's warnings (:mod:`davinci_sim.sim.divergence`: MuJoCo's own counters are read) — the
call returns that tick's number with nothing of it done that the Python tick would not do
the same way (at most the tick's setpoints, which the Python tick writes again, equal): the
step is rewound (``mj_setState``, and the bias forces the servo reads), the watch's state
put back. The caller runs that tick in Python and calls again from the next one.

Module-level functions, so that numba's on-disk cache keeps them between processes.
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.kinematics.fk_compiled import tip_pose_row
from davinci_sim.kinematics.suj import frames_row, invert_rigid_row
from davinci_sim.sim.arm_laws import tracking_watch_row
from davinci_sim.sim.cartesian_kernel import servo_cp_row
from davinci_sim.sim.rows_kernel import f64_at, i32_at, mj_get_state, mj_set_state, mj_step
from davinci_sim.sim.servo import servo_ctrl_scalar
from davinci_sim.sim.validation import MAX_JOINT_VALUE

#: What a call returns when it ran every tick up to K.
DONE = -1


@numba.njit(cache=True, nogil=True)
def _warning_counts(w, watched, out):
    for i in range(watched.shape[0]):
        out[i] = w[2 * watched[i] + 1]  # mjWarningStat: (lastinfo, number)


@numba.njit(cache=True, nogil=True)
def live_period(args, first, K, cartesian, feedforward, frames, tol, record, camera_row):
    """Ticks ``first`` … ``K`` (see the module docstring); returns :data:`DONE` or the
    tick the caller must run in Python.

    ``args``: an :class:`~davinci_sim.sim.live_period.ArmPeriod`'s arguments bound once
    (:func:`~davinci_sim.kinematics.bound.bind`: a call unboxes one object and the ticks'
    flags, not ~90 arguments; one function, not a wrapper around a kernel taking them, whose
    module numba would optimize and generate again). ``args.args``: the physics (``model``
    … ``warnings``), the servo's, the watch's, the arm's (``arm_act`` … ``fk_identity``),
    the IK's constants, the goal's buffers (``T_base_ref``, ``R_ref_goal``, ``start``,
    ``delta``, ``velocity``, ``twist_ref``, then ``qmin``, ``qmax``, ``bound``), the frame
    plan's (``plan_links`` … ``frame_adr``, ``key``, ``frames_out``, ``arm_row``,
    ``computed``), the samples' (``rec_t``, ``rec_q``, ``rec_frames``) and the final
    kinematics' (``T_final``, ``J_final``) tuples.

    ``model``, ``data``: the C pointers; ``address``: the buffers of ``ctrl``, ``qpos``,
    ``qvel``, ``qfrc_bias``, ``qfrc_gravcomp`` and the warning statistics; ``sizes``:
    (nu, nq, nv, number of warnings); ``state`` scratch of ``mj_stateSize(state_sig)``;
    ``warnings``: the indices of the guard's warnings. The servo's arrays (actuator order)
    and the watch's (``TrackingWatch``: per arm, its entries and state) are the live
    objects' own, updated in place. The arm: its actuators ``arm_act`` and ``qpos``
    addresses ``arm_q``, the PSM's insertion ``qpos`` address ``shaft_q`` (-1: no
    in-cannula check) with the shaft's offset and least distance (m), its FK constants.
    ``cartesian``: tick k's goal is ``(R_ref_goal, start + (k/K)·delta)`` in the arm's
    reference, solved with ``T_base_ref`` (the base frame's inverse, updated in place when
    ``frames`` recomputes it, else held) and the twist ``twist_ref``
    (if ``feedforward``); else the joint goal ``start + (k/K)·delta`` with ``velocity``.
    ``qmin``, ``qmax``: the arm's limits; ``bound``: the feed-forward bound per joint.

    ``frames``: the arm's base frame follows the setup and ECM joints (``frame_adr``: their
    ``qpos`` addresses, the SUJ arms' then the ECM's), as ``Simulation._frames`` computes
    it: recomputed (``suj.frames_row`` with the plan's constants into ``frames_out``, row
    ``arm_row`` the arm's; ``T_base_ref`` its inverse) when the joints differ from ``key``
    (the joints of the last frames, updated) by more than ``tol``, or at all with ``tol``
    0; ``computed[0]`` then True.

    ``record`` (with ``frames``): each tick k after ``first`` keeps what a sample of the
    state after tick k − 1 reads, taken at tick k's start (nothing has moved since that
    step): the time (``rec_t[k - 1]``, s), the arm's joints (``rec_q[k - 1]``) and the
    frames (``rec_frames[k - 1]``: the camera, row ``camera_row`` of ``frames_out``, then
    the arm's base frame); tick k stops there (returns k) if that step left contacts
    (``address[6]``: ``mjData.ncon``), whose forces only the state itself can tell.

    After the last tick (:data:`DONE`), what the first reader of the state asks for next,
    at the joints the last step left: the frames (as above: ``computed[0]`` True when
    recomputed) and the arm's measured kinematics, ``T_final`` (4, 4), the tip in its base
    frame, and ``J_final`` (6, dof), the spatial Jacobian (``Arm._measured_kinematics``)."""
    (model, data, address, sizes, state, state_sig, warnings), sv, wt, am, ik, g, pl, rc, fin = (
        args.args
    )
    qposadr, dofadr, minus_gravcomp, kp, kv, effort, gravity, q_ref, qd_ref, tau_ff = sv
    w_adr, w_idx, w_tol, w_starts, w_watched, w_since, w_first_bad, w_fault = wt
    (arm_act, arm_q, shaft_q, shaft_offset, shaft_min, fk_links, fk_modified, fk_tool,
     fk_identity) = am  # fmt: skip
    ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, ik_tolerance = ik
    T_base_ref, R_ref_goal, start, delta, velocity, twist_ref, qmin, qmax, bound = g
    (plan_links, plan_modified, plan_tools, plan_tools_identity, plan_T_cart_sujbase,
     plan_reference, ref_links, ref_modified, ref_tool, ref_tool_identity, frame_adr, key,
     frames_out, arm_row, computed) = pl  # fmt: skip
    rec_t, rec_q, rec_frames = rc
    T_final, J_final = fin
    nu, nq, nv, nw = sizes[0], sizes[1], sizes[2], sizes[3]
    dof = arm_act.shape[0]
    q_arm = np.empty(dof)
    q_out = np.empty(dof)
    qd_out = np.empty(dof)
    T_base_tip = np.empty((4, 4))
    J = np.empty((6, dof))
    F = np.empty((dof, 12))
    T_goal = np.eye(4)
    ctrl, since, bias_before, gravcomp_before, counts, counts_after = step_scratch(
        nu, nv, warnings.shape[0], w_since.shape[0]
    )
    sp = state.ctypes.data
    n_suj = plan_links.shape[0]
    n_ref = ref_links.shape[1]
    n_joints = (frame_adr.shape[0] - n_ref) // n_suj if frames else 0
    Q_suj = np.empty((n_suj, n_joints))
    q_frame_ref = np.empty(n_ref)
    T1 = np.empty((4, 4))
    F_suj = np.empty((max(n_joints, 8), 12))
    J_none = np.empty((6, 0))
    plan = (plan_links, plan_modified, plan_tools, plan_tools_identity, plan_T_cart_sujbase,
            plan_reference, ref_links, ref_modified, ref_tool, ref_tool_identity)  # fmt: skip
    for k in range(first, K + 1):
        qp = numba.carray(f64_at(address[1]), (nq,))
        qv = numba.carray(f64_at(address[2]), (nv,))
        qb = numba.carray(f64_at(address[3]), (nv,))
        qg = numba.carray(f64_at(address[4]), (nv,))
        w = numba.carray(i32_at(address[5]), (2 * nw,))
        s = k / K  # (envs.control.ramp's arithmetic)
        # --- the arm's setpoint: servo_cp or servo_jp, as the Python path accepts it
        if frames and frames_at(  # the base frame at the joints now (Simulation._frames)
            qp, frame_adr, key, tol, plan, frames_out, Q_suj, q_frame_ref, T1, J_none, F_suj,
        ):  # fmt: skip
            invert_rigid_row(frames_out[arm_row], T_base_ref)  # (Arm._T_base_reference)
            computed[0] = True
        if cartesian:
            if shaft_q >= 0 and abs(qp[shaft_q] + shaft_offset) < shaft_min:
                return k  # in the cannula: servo_cp refuses, with its message
            for i in range(3):
                for m in range(3):
                    T_goal[i, m] = R_ref_goal[i, m]
                T_goal[i, 3] = start[i] + s * delta[i]
            for i in range(dof):
                q_arm[i] = qp[arm_q[i]]
            # the measured kinematics (Arm._measured_kinematics: the Jacobian of the twist)
            tip_pose_row(fk_links, fk_modified, fk_tool, fk_identity, q_arm, T_base_tip, J,
                         True, F)  # fmt: skip
            if not servo_cp_row(
                ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, fk_links, fk_modified,
                fk_tool, fk_identity, ik_tolerance, T_base_ref, T_goal, q_arm, J, feedforward,
                twist_ref, qmin, qmax, bound, q_out, qd_out,
            ):  # fmt: skip
                return k
        else:
            for i in range(dof):
                g = start[i] + s * delta[i]
                if not abs(g) <= MAX_JOINT_VALUE or not abs(velocity[i]) <= bound[i]:
                    return k  # servo_jp refuses, with its message
                q_out[i] = min(max(g, qmin[i]), qmax[i])  # (clip_goal)
                qd_out[i] = velocity[i]
        for i in range(dof):
            q_ref[arm_act[i]] = q_out[i]
            qd_ref[arm_act[i]] = qd_out[i]
        # --- the guard's save; the time of the tick is the state's first entry
        mj_get_state(model, data, sp, state_sig)
        t = state[0]
        if record and k > first:  # (a sample of the state after tick k - 1: as it is now)
            if numba.carray(i32_at(address[6]), (1,))[0] != 0:
                return k  # contacts: the caller samples them from the state itself
            rec_t[k - 1] = t
            for i in range(dof):
                rec_q[k - 1, i] = qp[arm_q[i]]
            for i in range(4):
                for m in range(4):
                    rec_frames[k - 1, 0, i, m] = frames_out[camera_row, i, m]
                    rec_frames[k - 1, 1, i, m] = frames_out[arm_row, i, m]
        # --- the tracking watch of every arm
        if not watch_passes(qp, w_adr, q_ref, w_idx, w_tol, effort, w_starts, w_watched,
                            w_since, t, w_first_bad, w_fault, since):  # fmt: skip
            return k  # an arm faults: the Python tick faults it, with the reason
        # --- the servo (the bias forces of the last step) and the step
        if not servo_and_step(
            model, data, address, qp, qv, qb, qg, qposadr, dofadr, minus_gravcomp, q_ref,
            qd_ref, tau_ff, effort, gravity, kp, kv, w, warnings, sp, state_sig, since, w_since,
            ctrl, bias_before, gravcomp_before, counts, counts_after,
        ):  # fmt: skip
            return k  # diverged: undone, for the Python tick's guard
    qp = numba.carray(f64_at(address[1]), (nq,))
    if frames and frames_at(
        qp, frame_adr, key, tol, plan, frames_out, Q_suj, q_frame_ref, T1, J_none, F_suj
    ):
        computed[0] = True
    for i in range(dof):
        q_arm[i] = qp[arm_q[i]]
    tip_pose_row(fk_links, fk_modified, fk_tool, fk_identity, q_arm, T_final, J_final, True, F)
    return DONE


@numba.njit(cache=True, nogil=True)
def frames_at(qp, frame_adr, key, tol, plan, frames_out, Q_suj, q_frame_ref, T1, J_none, F_suj):
    """``Simulation._frames`` at the joints ``qp``: the setup-joint frames recomputed into
    ``frames_out`` (``suj.frames_row`` with the plan's constants ``plan``: its ``args``, its
    reference, its ``ref_args``) when a setup or ECM joint (``qpos`` addresses ``frame_adr``)
    differs from ``key`` (the joints of the frames held, updated) by more than ``tol``, or
    at all with ``tol`` 0; returns whether they were. ``Q_suj`` (k, n), ``q_frame_ref``,
    ``T1``, ``J_none``, ``F_suj``: scratch."""
    same, close = True, tol > 0
    for i in range(frame_adr.shape[0]):
        v = qp[frame_adr[i]]
        same = same and v == key[i]
        close = close and abs(v - key[i]) <= tol
    if same or close:
        return False
    n_suj, n_joints, n_ref = Q_suj.shape[0], Q_suj.shape[1], q_frame_ref.shape[0]
    for i in range(frame_adr.shape[0]):
        key[i] = qp[frame_adr[i]]
    for i in range(n_suj):
        for m in range(n_joints):
            Q_suj[i, m] = key[i * n_joints + m]
    for m in range(n_ref):
        q_frame_ref[m] = key[n_suj * n_joints + m]
    frames_row(plan[0], plan[1], plan[2], plan[3], plan[4], Q_suj, plan[5], plan[6], plan[7],
               plan[8], plan[9], q_frame_ref, frames_out, T1, J_none, F_suj)  # fmt: skip
    return True


@numba.njit(cache=True, nogil=True)
def watch_passes(qp, w_adr, q_ref, w_idx, w_tol, effort, w_starts, w_watched, w_since, t,
                 w_first_bad, w_fault, since) -> bool:  # fmt: skip
    """The tracking watch of every arm at time ``t`` (``tracking_watch_row``, its state
    ``w_since`` kept in ``since`` first); False where an arm faults, with ``w_since`` put
    back (the Python tick faults it, with the reason)."""
    for i in range(since.shape[0]):
        since[i] = w_since[i]
    if tracking_watch_row(qp, w_adr, q_ref, w_idx, w_tol, effort, w_starts, w_watched,
                          w_since, t, w_first_bad, w_fault):  # fmt: skip
        for i in range(since.shape[0]):
            w_since[i] = since[i]
        return False
    return True


@numba.njit(cache=True, nogil=True)
def step_scratch(nu, nv, n_warnings, n_arms):
    """The scratch of :func:`servo_and_step` and of the watch's undo: ``ctrl`` (nu,),
    ``since`` (n_arms,), ``bias_before``, ``gravcomp_before`` (nv,), ``counts``,
    ``counts_after`` (n_warnings,) int32."""
    return (np.empty(nu), np.empty(n_arms), np.empty(nv), np.empty(nv),
            np.empty(n_warnings, dtype=np.int32), np.empty(n_warnings, dtype=np.int32))  # fmt: skip


@numba.njit(cache=True, nogil=True)
def servo_and_step(
    model, data, address, qp, qv, qb, qg, qposadr, dofadr, minus_gravcomp, q_ref, qd_ref,
    tau_ff, effort, gravity, kp, kv, w, warnings, sp, sig, since, w_since, ctrl, bias_before,
    gravcomp_before, counts, counts_after,
) -> bool:  # fmt: skip
    """The servo's controls (``JointServo.apply``: ``servo_ctrl_scalar`` of each actuator
    with the bias forces ``qb`` less ``qg`` of the last step) into ``mjData.ctrl``
    (``address[0]``), then ``mj_step`` with MuJoCo's warning counters ``w`` read around it.
    A step that raised one of ``warnings`` is undone: the integration state saved at ``sp``
    (signature ``sig``) restored, the bias forces and the watch's ``w_since`` (from
    ``since``) put back; returns False then. ``ctrl``, ``bias_before``, ``gravcomp_before``,
    ``counts``, ``counts_after``: scratch."""
    nu, nv = ctrl.shape[0], qb.shape[0]
    for i in range(nu):
        b = qb[dofadr[i]] - qg[dofadr[i]] if minus_gravcomp else qb[dofadr[i]]
        ctrl[i] = servo_ctrl_scalar(
            qp[qposadr[i]], qv[dofadr[i]], b, q_ref[i], qd_ref[i], tau_ff[i], effort[i],
            gravity[i], kp[i], kv[i],
        )  # fmt: skip
    for i in range(nv):
        bias_before[i] = qb[i]
        gravcomp_before[i] = qg[i]
    c = numba.carray(f64_at(address[0]), (nu,))
    for i in range(nu):
        c[i] = ctrl[i]
    _warning_counts(w, warnings, counts)
    mj_step(model, data)
    _warning_counts(w, warnings, counts_after)
    for i in range(counts.shape[0]):
        if counts_after[i] != counts[i]:
            mj_set_state(model, data, sp, sig)
            for m in range(nv):
                qb[m] = bias_before[m]
                qg[m] = gravcomp_before[m]
            for m in range(since.shape[0]):
                w_since[m] = since[m]
            return False
    return True
