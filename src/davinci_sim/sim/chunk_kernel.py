"""The compiled control period of :class:`~davinci_sim.sim.rows_chunk.ArmChunk` (numba only:
imported by :mod:`davinci_sim.sim.rows_chunk` once MuJoCo's library is loaded into LLVM's
symbols, as :mod:`davinci_sim.sim.rows_kernel`).

One call runs up to K ticks of each given row without returning to Python: the setpoint's
ramp (joint goal, or tip goal through the closed-form PSM IK with the twist feed-forward),
the tracking watch, the joint servo, ``mj_step``, the servo's bias forces and the tip's
kinematics. Every law is the per-row compiled form of the batch law the Python path calls
(the module docstring of :mod:`~davinci_sim.sim.rows_chunk` lists them); nothing here
states a formula of its own beyond the index bookkeeping.

Module-level functions, so that numba's on-disk cache keeps them between processes.
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.kinematics.fk_compiled import tip_pose_row
from davinci_sim.sim.arm_laws import LIMIT_SLACK, other_branch, tracking_fault_scalar
from davinci_sim.sim.cartesian_kernel import (
    OK,
    cartesian_setpoint_row,
    ik_scratch,
    pose_in_reference_into,
)
from davinci_sim.sim.rows_kernel import f64_at, mj_step
from davinci_sim.sim.servo import servo_ctrl_scalar

#: ``stop`` codes a row ends a call with (besides the tick a Python tick must run).
DONE = -1
FAULT = -2


@numba.njit(cache=True, nogil=True)
def period_rows(
    model, data, address, rows, first, K, stop,
    qadr, dadr, act, qposadr, dofadr, copy_gravcomp, minus_gravcomp, timestep,
    kp, kv, effort, gravity,
    Q, V, QB, QG, bias, q_ref, qd_ref, tau_ff, time, bad_since,
    arm_act, arm_q, tolerance, qmin, qmax, fk_links, fk_modified, fk_tool, fk_identity,
    T_ref_base, cartesian, start, delta, velocity, R_base_goal, T_base_ref, twist_base,
    ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, ik_tolerance,
    T_tip, J_tip, record, T_hist, t_hist, ran,
):  # fmt: skip
    """Ticks ``first[r]`` … ``K`` of each row ``r`` of ``rows``; see
    :meth:`~davinci_sim.sim.rows_chunk.ArmChunk.run` for the arguments. ``stop[r]`` ends as
    :data:`DONE` (all K ticks run), :data:`FAULT` (the tracking watch faulted the arm at a
    tick; that tick's setpoint written, no step) or the tick k whose setpoint needs the
    Python path (an IK answer to polish, a singular Jacobian): nothing of tick k done."""
    nu = kp.shape[0]
    dof = arm_act.shape[0]
    ctrl = np.empty(nu)
    q_arm = np.empty(dof)
    F = np.empty((dof, 12))
    T_base_tip = np.empty((4, 4))
    A = np.empty((dof, dof))
    qd = np.empty(dof)
    T_goal, seed, q_ik, success, status, info = ik_scratch(dof)
    for j in range(rows.shape[0]):
        r = rows[j]
        a = address[r]
        stop[r] = DONE
        for k in range(first[r], K + 1):
            # --- the setpoint of tick k: the ramp's goal (envs.control.ramp)
            s = k / K
            if cartesian:
                g0 = start[r, 0] + s * delta[r, 0]
                g1 = start[r, 1] + s * delta[r, 1]
                g2 = start[r, 2] + s * delta[r, 2]
                # the goal in the arm's base: T_base_ref · (R_goal, g)
                for i in range(3):
                    T_goal[0, i, 0] = R_base_goal[r, i, 0]
                    T_goal[0, i, 1] = R_base_goal[r, i, 1]
                    T_goal[0, i, 2] = R_base_goal[r, i, 2]
                    T_goal[0, i, 3] = (
                        T_base_ref[i, 0] * g0 + T_base_ref[i, 1] * g1 + T_base_ref[i, 2] * g2
                    ) + T_base_ref[i, 3]
                T_goal[0, 3, 0], T_goal[0, 3, 1], T_goal[0, 3, 2], T_goal[0, 3, 3] = (
                    0.0, 0.0, 0.0, 1.0,
                )  # fmt: skip
                for i in range(dof):
                    seed[0, i] = Q[r, arm_q[i]]
                code = cartesian_setpoint_row(
                    ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, fk_links, fk_modified,
                    fk_tool, fk_identity, ik_tolerance, T_goal, seed, J_tip[r], twist_base[r], A,
                    q_ik, success, status, info, qd,
                )  # fmt: skip
                if code != OK:  # servo_cp's law (cartesian_kernel): polish or least squares
                    stop[r] = k
                    break
                ok = success[0] and not other_branch(q_ik[0], seed[0])  # (else held)
                for i in range(dof):
                    qi = q_ik[0, i]
                    ok = ok and (qi >= qmin[i] - LIMIT_SLACK) and (qi <= qmax[i] + LIMIT_SLACK)
                if ok:
                    for i in range(dof):
                        q_ref[r, arm_act[i]] = q_ik[0, i]
                        qd_ref[r, arm_act[i]] = qd[i]
            else:
                for i in range(dof):
                    q_ref[r, arm_act[i]] = start[r, i] + s * delta[r, i]
                    qd_ref[r, arm_act[i]] = velocity[r, i]
            # --- the tracking watch (arm_laws.tracking_bad / tracking_fault)
            bad = False
            for i in range(dof):
                m = arm_act[i]
                bad = bad or (abs(Q[r, arm_q[i]] - q_ref[r, m]) > tolerance[i] and not effort[m])
            since, fault = tracking_fault_scalar(bad, bad_since[r], time[r])
            bad_since[r] = since
            if fault:
                stop[r] = FAULT
                break
            # --- the servo, mj_step, the state read back, the bias forces
            servo_step_row(
                model[r], data[r], a, r, qadr, dadr, act, qposadr, dofadr, copy_gravcomp,
                minus_gravcomp, kp, kv, effort, gravity, Q, V, QB, QG, bias, q_ref, qd_ref,
                tau_ff, ctrl, -1, Q, Q,
            )  # fmt: skip
            time[r] = time[r] + timestep
            # --- the tip's pose and Jacobian (arm_laws.tip_kinematics, pose_in_reference)
            for i in range(dof):
                q_arm[i] = Q[r, arm_q[i]]
            tip_pose_row(fk_links, fk_modified, fk_tool, fk_identity, q_arm, T_base_tip,
                         J_tip[r], True, F)  # fmt: skip
            pose_in_reference_into(T_ref_base, T_base_tip, T_tip[r])
            if record:
                for i in range(4):
                    for m in range(4):
                        T_hist[r, k - 1, i, m] = T_tip[r, i, m]
                t_hist[r, k - 1] = time[r]
                ran[r, k - 1] = True


@numba.njit(cache=True, nogil=True)
def servo_step_row(
    model, data, a, r, qadr, dadr, act, qposadr, dofadr, copy_gravcomp, minus_gravcomp,
    kp, kv, effort, gravity, Q, V, QB, QG, bias, q_ref, qd_ref, tau_ff, ctrl, body, xfrc, XI,
):  # fmt: skip
    """One simulation's tick after its setpoints: the joint servo of every actuator
    (``servo.servo_ctrl``) written to ``ctrl`` (``a``: its buffer addresses, as
    :mod:`~davinci_sim.sim.rows_kernel`), the ``body``'s ``xfrc_applied`` from ``xfrc[r]``
    (none if negative), ``mj_step``, the state read back into row ``r`` (``qadr``,
    ``dadr``, ``act``: the stepped model's addresses in the rows' layout; ``qfrc_gravcomp``
    if ``copy_gravcomp``; the body's ``xipos`` into ``XI``) and the servo's bias forces
    (``JointServo.bias_of``). ``ctrl`` (nu,) is scratch."""
    nu, nu_r, nq_r, nv_r = kp.shape[0], act.shape[0], qadr.shape[0], dadr.shape[0]
    for i in range(nu):
        ctrl[i] = servo_ctrl_scalar(
            Q[r, qposadr[i]], V[r, dofadr[i]], bias[r, i], q_ref[r, i], qd_ref[r, i],
            tau_ff[r, i], effort[i], gravity[i], kp[i], kv[i],
        )  # fmt: skip
    c = numba.carray(f64_at(a[0]), (nu_r,))
    for i in range(nu_r):
        c[i] = ctrl[act[i]]
    if body >= 0:
        x = numba.carray(f64_at(a[1]), (6 * (body + 1),))
        for k in range(6):
            x[6 * body + k] = xfrc[r, k]
    mj_step(model, data)
    qp = numba.carray(f64_at(a[2]), (nq_r,))
    for i in range(nq_r):
        Q[r, qadr[i]] = qp[i]
    qv = numba.carray(f64_at(a[3]), (nv_r,))
    qb = numba.carray(f64_at(a[4]), (nv_r,))
    for i in range(nv_r):
        V[r, dadr[i]] = qv[i]
        QB[r, dadr[i]] = qb[i]
    if copy_gravcomp:
        qg = numba.carray(f64_at(a[5]), (nv_r,))
        for i in range(nv_r):
            QG[r, dadr[i]] = qg[i]
    if body >= 0:
        xi = numba.carray(f64_at(a[6]), (3 * (body + 1),))
        for k in range(3):
            XI[r, k] = xi[3 * body + k]
    for i in range(nu):
        if minus_gravcomp:
            bias[r, i] = QB[r, dofadr[i]] - QG[r, dofadr[i]]
        else:
            bias[r, i] = QB[r, dofadr[i]]
