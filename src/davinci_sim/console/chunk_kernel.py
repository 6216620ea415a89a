"""The console's ticks in one compiled call (numba only: imported by
:mod:`davinci_sim.console.chunk` once MuJoCo's library is loaded into LLVM's symbols, as
:mod:`davinci_sim.sim.live_kernel`).

One call runs ticks ``1 … K`` of :meth:`Simulation.tick
<davinci_sim.sim.simulation.Simulation.tick>` for a console in its steady state: every
simulated MTM read (``SimulatedMTM._read``: the handle's pose and twist, the hand's wrench
on it, :func:`~davinci_sim.devices.device_row.hand_read_row`), every following
teleoperation's tick (:func:`~davinci_sim.console.teleop_row.follow_tick`, with the PSM's
in-cannula check), the camera teleoperation's while the camera pedal moves the endoscope
(:func:`~davinci_sim.console.camera_row.ecm_follow`), the MTMs' orientation locks
(:func:`~davinci_sim.sim.arm_laws.wrist_lock_step`), the tracking watch, the joint servo,
the divergence guard's save and ``mj_step``; after the step, the setup-joint frames, the
haptic loop's fixture on each following MTM
(:func:`~davinci_sim.console.haptic_row.fixture_render`) and what a task session samples
(the tip in the camera frame, the camera, the guidance force, the master's position), kept
per tick for the session to take afterwards. Every other component is idle in that state
(:mod:`davinci_sim.console.chunk` checks it before the call).

Each law is the live objects' own compiled row on the same numbers, so the ticks are the
Python ticks' bit for bit (``tests/console/test_chunk.py``); products numpy computes with
``@`` are computed with ``@`` here (the same BLAS, the same bits).

Where a tick would do something the kernel has no form of — a teleoperation goal
``servo_cp`` has no compiled answer for, a jaw angle to send, the tool in the cannula, a
failed wrist solve, a tracking fault, a step that raises one of the divergence guard's
warnings, a turned wrist target the device would refuse — the call returns ``2·k`` with
tick k not run (its pre-step's writes are the Python tick's own, equal, or put back);
where the tick's step ran but a post-step has no compiled form (the instrument touches
something and the session, the path kind's, measures its contacts in Python; a guidance
force that is not finite), ``2·k + 1``: the caller runs tick k's post-steps in Python.
:data:`DONE` when all K ran. The other kinds' sessions have the kernel measure the contacts
after each step (the instruments' and the suture pad's skin's), so a tool working on the
skin stays in the compiled ticks.

Module-level functions, so that numba's on-disk cache keeps them between processes. What
the compile costs (the longest of the warm-up's, ``davinci_sim.warm_up``) grows with the
arrays a call passes: the helpers take a few arrays each, never a slot's whole tuple
(:func:`_undo`: 13 s of compile when it took the devices' and teleoperations' tuples).
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.console.camera_row import ecm_follow
from davinci_sim.console.chunk_slots import (
    STOP_CAMERA,
    STOP_CONTACT,
    STOP_DIVERGED,
    STOP_FAULT,
    STOP_FORCE,
    STOP_NONE,
    STOP_TURN,
    STOP_WRIST,
    contacts_measure,
    device_read,
    ecm_kept,
    fixture_force,
    keep_device,
    keep_teleop,
    kinematics,
    objects_read,
    teleop_follow,
    tool_contacts,
    undo_device,
    undo_teleop,
    wrist_lock,
)
from davinci_sim.console.haptic_row import NOT_FINITE
from davinci_sim.sim.live_kernel import frames_at, servo_and_step, step_scratch, watch_passes
from davinci_sim.sim.rows_kernel import f64_at, i32_at, mj_get_state

#: Why a call stopped (``times[2]``: the codes of :mod:`~davinci_sim.console.chunk_slots`).
STOP_REASONS = (
    "", "the tool in the cannula", "a goal servo_cp has no compiled answer for",
    "a jaw angle to send", "a failed wrist solve", "a tracking fault", "a diverged step",
    "an instrument contact", "a guidance force not finite", "a turned wrist target off",
    "a camera goal the compiled law has no answer for",
)  # fmt: skip

#: What a call returns when it ran every tick.
DONE = -1

# The physics tuple (see :func:`console_chunk`), by position.
(P_MODEL, P_DATA, P_ADDRESS, P_SIZES, P_STATE, P_SIG, P_WARNINGS, P_QPOSADR, P_DOFADR,
 P_GRAVCOMP, P_KP, P_KV, P_EFFORT, P_GRAVITY, P_Q_REF, P_QD_REF, P_TAU_FF, P_DT,
 P_TIMES) = range(19)  # fmt: skip


@numba.njit(cache=True, nogil=True)
def console_chunk(bound, K):
    """Ticks ``1 … K`` (see the module docstring); returns :data:`DONE`, ``2·k`` (tick k
    not run) or ``2·k + 1`` (tick k's post-steps to run in Python).

    ``bound``: the plan's arguments bound once (:func:`~davinci_sim.kinematics.bound.bind`:
    a call unboxes one object, not the rows' ~280 arrays), ``bound.args`` ``(phys, watch,
    fr, devices, teleops, rec, ecm)``. (One compiled function, not a wrapper around a kernel
    taking the seven: numba optimizes a caller's whole module again, its callees' code
    included, and generates its machine code; such a wrapper cost the warm-up ~10 s.)

    ``phys``: the C pointers of the model and data, the buffers' addresses (``ctrl``,
    ``qpos``, ``qvel``, ``qfrc_bias``, ``qfrc_gravcomp``, the warning statistics, ``ncon``,
    ``xfrc_applied``, ``xipos``, the first contact's geoms, the bodies' ``xpos`` and
    ``xmat``, ``site_xpos``, the first contact's flexes), the sizes (nu, nq, nv, number
    of warnings, the contacts' stride in bytes), the guard's state scratch and signature,
    the warnings it watches, then the servo's arrays (updated in place) and the time step.
    ``watch``: the tracking watch's arrays. ``fr``: the setup-joint frame plan, its key
    (the joints of the frames held), tolerance, ``frames_out``, ``computed`` and the
    camera's row of ``frames_out``.

    ``devices``: per simulated MTM, ``(fk, adr, vadr, grip_adr, T_ref_base, R_hrsv_base,
    flags, target, impedance, push, R_world_hrsv, p_world_hrsv, body, applied, wrench, q,
    T, J, F, T_hrsv, twist, xfrc, gripper, lock, lock_flags, lock_traj, lock_goal,
    wrist_idx, idx, hand, on)``: its constants, the hand's state (updated), the last read
    (``T_hrsv``, ``twist``, ``gripper``), the orientation lock, the web console's rate input
    on its hand (``hand``: ``(on, state, params)``, see
    :mod:`~davinci_sim.devices.hand_input_row`: its target, origin, velocities and the
    wrist's target orientation, its leads, workspace and the time its velocities hold until)
    and whether the row is a device (``on[0]``) or a filler of its slot (the kernel has two:
    one compiled signature).

    ``teleops``: per following teleoperation, ``(cp, adr, idx, row, T_base_ref, shaft,
    anchors, flags, jaw, jaw_state, limits, device, q, T, J, F, q_out, qd_out, fixture,
    fx_state, fx_out, jaw_idx, on)``, two slots as the devices'.

    ``rec``: ``(on, teleop, fixture_teleop, ncon_watch, tool_geom, other_geom, t, T_tip,
    T_camera, requested, master, req_now, bodies, object_of, jaw_bit, tips, objects_flags,
    xpos, xmat, grasp, tip_out, flex, flex_out, tool_of, arm_of, counts, f6, count_out,
    force_out)``: the task session's samples of each tick (after its step), with its kind's
    objects (``ObjectsProbe.read``) where ``objects_flags[0]``, and, where
    ``objects_flags[1]``, the instruments' contacts and the force on the flex measured
    (:func:`~davinci_sim.console.chunk_slots.contacts_measure`); else an instrument's
    contact ends a call before the tick's post-steps.

    ``ecm``: the camera teleoperation's row (:func:`~davinci_sim.console.chunk_rows.
    ecm_row`): on where it follows, its anchors and constants, the ECM's, the slots of its
    left and right MTMs, their clamps, then what it writes back and one tick's outputs
    (:func:`~davinci_sim.console.camera_row.ecm_follow`, after the devices' reads and
    before the wrist locks, which then lock to its goals).

    Every array of every tuple is bound to a name here, before the ticks
    (:mod:`~davinci_sim.console.chunk_slots` says why); the ticks call the slots' laws
    with them, slot A's then slot B's."""
    phys, watch, fr, devices, teleops, rec, ecm = bound.args
    model, data, address, sizes = phys[P_MODEL], phys[P_DATA], phys[P_ADDRESS], phys[P_SIZES]
    state, sig, warnings = phys[P_STATE], phys[P_SIG], phys[P_WARNINGS]
    qposadr, dofadr, minus_gravcomp = phys[P_QPOSADR], phys[P_DOFADR], phys[P_GRAVCOMP]
    kp, kv, effort, gravity = phys[P_KP], phys[P_KV], phys[P_EFFORT], phys[P_GRAVITY]
    q_ref, qd_ref, tau_ff, dt = phys[P_Q_REF], phys[P_QD_REF], phys[P_TAU_FF], phys[P_DT]
    times = phys[P_TIMES]
    times[2] = STOP_NONE
    w_adr, w_idx, w_tol, w_starts, w_watched, w_since, w_first_bad, w_fault = watch
    nu, nq, nv, nw, stride = sizes[0], sizes[1], sizes[2], sizes[3], sizes[4]
    ctrl, since, bias_before, gravcomp_before, counts, counts_after = step_scratch(
        nu, nv, warnings.shape[0], w_since.shape[0]
    )
    sp = state.ctypes.data
    # the frames (Simulation._frames): the plan, its key and tolerance, the output
    plan = (fr[0], fr[1], fr[2], fr[3], fr[4], fr[5], fr[6], fr[7], fr[8], fr[9])
    frame_adr, key, tol, frames_out, computed = fr[10], fr[11], fr[12], fr[13], fr[14]
    camera_row = fr[15][0]
    n_suj, n_ref = fr[0].shape[0], fr[6].shape[1]
    n_joints = (frame_adr.shape[0] - n_ref) // n_suj
    Q_suj = np.empty((n_suj, n_joints))
    q_frame_ref = np.empty(n_ref)
    T1 = np.empty((4, 4))
    F_suj = np.empty((max(n_joints, 8), 12))
    J_none = np.empty((6, 0))
    # the slots' arrays: devices A and B, teleoperations A and B and each one's device
    (fk_a, adr_a, vadr_a, grip_a, Tb_a, Rb_a, flags_a, target_a, imp_a, push_a, Rw_a, pw_a,
     body_a, applied_a, wrench_a, q_a, T_a, J_a, F_a, Th_a, tw_a, xfrc_a, grip_v_a, lock_a,
     lflags_a, ltraj_a, lgoal_a, widx_a, idx_a, hand_a, on_a) = devices[0]  # fmt: skip
    (fk_b, adr_b, vadr_b, grip_b, Tb_b, Rb_b, flags_b, target_b, imp_b, push_b, Rw_b, pw_b,
     body_b, applied_b, wrench_b, q_b, T_b, J_b, F_b, Th_b, tw_b, xfrc_b, grip_v_b, lock_b,
     lflags_b, ltraj_b, lgoal_b, widx_b, idx_b, hand_b, on_b) = devices[1]  # fmt: skip
    lk_a0, lk_a1, lk_a2, lk_a3 = fk_a
    lk_b0, lk_b1, lk_b2, lk_b3 = fk_b
    hon_a, hst_a, hpr_a = hand_a
    hon_b, hst_b, hpr_b = hand_b
    (wl_a0, wl_a1, wl_a2, wl_a3, wfirst_a, wR_a, wsteps_a, wdamp_a, wlo_a, whi_a, wT_a, wJ_a,
     wF_a, wA_a, wx_a, wv_a, wacc_a, wratio_a) = lock_a  # fmt: skip
    (wl_b0, wl_b1, wl_b2, wl_b3, wfirst_b, wR_b, wsteps_b, wdamp_b, wlo_b, whi_b, wT_b, wJ_b,
     wF_b, wA_b, wx_b, wv_b, wacc_b, wratio_b) = lock_b  # fmt: skip
    (cp_a, tadr_a, tidx_a, trow_a, Tbr_a, shaft_a, anchors_a, tflags_a, jaw_a, jst_a, lim_a,
     dev_a, tq_a, tT_a, tJ_a, tF_a, qo_a, qdo_a, fix_a, fst_a, fout_a, jidx_a,
     ton_a) = teleops[0]  # fmt: skip
    (cp_b, tadr_b, tidx_b, trow_b, Tbr_b, shaft_b, anchors_b, tflags_b, jaw_b, jst_b, lim_b,
     dev_b, tq_b, tT_b, tJ_b, tF_b, qo_b, qdo_b, fix_b, fst_b, fout_b, jidx_b,
     ton_b) = teleops[1]  # fmt: skip
    c_a0, c_a1, c_a2, c_a3, c_a4, c_a5, c_a6, c_a7, c_a8, c_a9 = cp_a
    c_b0, c_b1, c_b2, c_b3, c_b4, c_b5, c_b6, c_b7, c_b8, c_b9 = cp_b
    P0_a, M0_a, Ro_a = anchors_a
    P0_b, M0_b, Ro_b = anchors_b
    qmin_a, qmax_a, bound_a = lim_a
    qmin_b, qmax_b, bound_b = lim_b
    fon_a, vp_a, vv_a, prev_a = fst_a
    fon_b, vp_b, vv_b, prev_b = fst_b
    req_a, limd_a, tau_a, ff_a = fout_a
    req_b, limd_b, tau_b, ff_b = fout_b
    (ce_a, ba_a, AE_a, AA_a, EE_a, st_a, ed_a, cu_a, le_a, B_a, G_a, tr_a, su_a, law_a, lf_a, lp_a,
     vdt_a, val_a, fsteps_a, ftmax_a) = fix_a  # fmt: skip
    (ce_b, ba_b, AE_b, AA_b, EE_b, st_b, ed_b, cu_b, le_b, B_b, G_b, tr_b, su_b, law_b, lf_b, lp_b,
     vdt_b, val_b, fsteps_b, ftmax_b) = fix_b  # fmt: skip
    # Each teleoperation's MTM: device A's arrays or B's, chosen array by array (a tuple
    # chosen at run time would be one value the pruning of reference counts cannot follow:
    # kinematics/jit_refcounts.py).
    on_a0, on_b0 = dev_a[0] == 0, dev_b[0] == 0
    dl_a0, dl_a1 = (lk_a0 if on_a0 else lk_b0), (lk_a1 if on_a0 else lk_b1)
    dl_a2, dl_a3 = (lk_a2 if on_a0 else lk_b2), (lk_a3 if on_a0 else lk_b3)
    dl_b0, dl_b1 = (lk_a0 if on_b0 else lk_b0), (lk_a1 if on_b0 else lk_b1)
    dl_b2, dl_b3 = (lk_a2 if on_b0 else lk_b2), (lk_a3 if on_b0 else lk_b3)
    dadr_a, dTb_a = (adr_a if on_a0 else adr_b), (Tb_a if on_a0 else Tb_b)
    dq_a, dT_a, dJ_a = (q_a if on_a0 else q_b), (T_a if on_a0 else T_b), (J_a if on_a0 else J_b)
    dF_a, dTh_a, dtw_a = (
        (F_a if on_a0 else F_b),
        (Th_a if on_a0 else Th_b),
        (tw_a if on_a0 else tw_b),
    )
    dgrip_a, didx_a = (grip_v_a if on_a0 else grip_v_b), (idx_a if on_a0 else idx_b)
    dadr_b, dTb_b = (adr_a if on_b0 else adr_b), (Tb_a if on_b0 else Tb_b)
    dq_b, dT_b, dJ_b = (q_a if on_b0 else q_b), (T_a if on_b0 else T_b), (J_a if on_b0 else J_b)
    dF_b, dTh_b, dtw_b = (
        (F_a if on_b0 else F_b),
        (Th_a if on_b0 else Th_b),
        (tw_a if on_b0 else tw_b),
    )
    dgrip_b, didx_b = (grip_v_a if on_b0 else grip_v_b), (idx_a if on_b0 else idx_b)
    # the session's sample: its teleoperation, the fixture's and the objects' arrays
    rec_on, rec_ncon, tool_geom, other_geom = rec[0], rec[3], rec[4], rec[5]
    r_t, r_tip, r_cam, r_req, r_master, r_now = rec[6], rec[7], rec[8], rec[9], rec[10], rec[11]
    bodies, object_of, jaw_bit, tips, o_flags = rec[12], rec[13], rec[14], rec[15], rec[16]
    o_xpos, o_xmat, o_grasp, o_tips = rec[17], rec[18], rec[19], rec[20]
    o_flex, o_flex_out, c_tool, c_arm, c_counts = rec[21], rec[22], rec[23], rec[24], rec[25]
    c_f6, c_count, c_force = rec[26], rec[27], rec[28]
    ra = rec[1][0] == 0  # (the session's teleoperation: A or B, array by array as above)
    rl0, rl1, rl2, rl3 = (
        (c_a5 if ra else c_b5),
        (c_a6 if ra else c_b6),
        (c_a7 if ra else c_b7),
        (c_a8 if ra else c_b8),
    )
    radr, rq, rT = (tadr_a if ra else tadr_b), (tq_a if ra else tq_b), (tT_a if ra else tT_b)
    rJ, rF, r_row = (tJ_a if ra else tJ_b), (tF_a if ra else tF_b), (trow_a[0] if ra else trow_b[0])
    r_Th = Th_a if (dev_a[0] if ra else dev_b[0]) == 0 else Th_b
    f_rec = rec[2][0]
    r_req_src = req_a if max(f_rec, 0) == 0 else req_b
    # the camera teleoperation's row; its MTMs' arrays chosen array by array (as above)
    (e_on, e_geo, e_consts, e_fric, e_q0, e_qlim, e_l0, e_l1, e_l2, e_l3, e_T, e_J, e_F,
     e_Rc0, e_Rm0, e_idx, e_dev, e_prev, e_steps, e_ftl, e_ftr, e_tau_l, e_tau_r, e_active,
     e_Rlock, e_lim_s, e_tau_sl, e_tau_sr, e_act_s, e_Rlock_s, e_Rgoal_s) = ecm  # fmt: skip
    el_a = e_dev[0] == 0  # (the left MTM in slot A)
    eT_l, eT_r = (Th_a if el_a else Th_b), (Th_b if el_a else Th_a)
    etw_l, etw_r = (tw_a if el_a else tw_b), (tw_b if el_a else tw_a)
    eRb_l, eRb_r = (Rb_a if el_a else Rb_b), (Rb_b if el_a else Rb_a)
    eTb_l, eTb_r = (Tb_a if el_a else Tb_b), (Tb_b if el_a else Tb_a)
    eJ_l, eJ_r = (J_a if el_a else J_b), (J_b if el_a else J_a)
    eidx_l, eidx_r = (idx_a if el_a else idx_b), (idx_b if el_a else idx_a)
    eg_l, eg_r = e_Rgoal_s[0], e_Rgoal_s[1]
    eg_a, eg_b = (eg_l if el_a else eg_r), (eg_r if el_a else eg_l)
    # what a rewound tick puts back: the hands', the jaws' and the locks' state
    m_lock = lgoal_a.shape[0]
    keep_applied = np.empty(2, dtype=np.bool_)
    keep_wrench = np.empty((2, 6))
    keep_lock = np.empty((2, 3 * m_lock))
    keep_goal = np.empty(2, dtype=np.bool_)
    keep_jaw = np.empty((2, 13))
    keep_hand = np.empty((2, 12))
    keep_fx = np.empty((2, 6))
    undo_a = (on_a, applied_a, wrench_a, ltraj_a, lgoal_a, lflags_a, hon_a, hst_a, hpr_a, target_a)
    undo_b = (on_b, applied_b, wrench_b, ltraj_b, lgoal_b, lflags_b, hon_b, hst_b, hpr_b, target_b)
    ujaw_a, ujaw_b = (ton_a, jaw_a, jst_a), (ton_b, jaw_b, jst_b)
    t_pre = times[3]  # (the tick's time before its step: the state's, then + dt per step)
    xfrc_all = numba.carray(f64_at(address[7]), (6 * (sizes[5]),))
    xipos = numba.carray(f64_at(address[8]), (3 * (sizes[5]),))
    for k in range(1, K + 1):
        qp = numba.carray(f64_at(address[1]), (nq,))
        qv = numba.carray(f64_at(address[2]), (nv,))
        qb = numba.carray(f64_at(address[3]), (nv,))
        qg = numba.carray(f64_at(address[4]), (nv,))
        w = numba.carray(i32_at(address[5]), (2 * nw,))
        if frames_at(qp, frame_adr, key, tol, plan, frames_out, Q_suj, q_frame_ref, T1, J_none,
                     F_suj):  # fmt: skip
            computed[0] = True
        # --- what a rewound tick puts back, then the devices' reads (SimulatedMTM._read)
        keep_device(0, applied_a, wrench_a, ltraj_a, lgoal_a, lflags_a, hst_a, keep_applied,
                    keep_wrench, keep_lock, keep_goal, keep_hand)  # fmt: skip
        keep_device(1, applied_b, wrench_b, ltraj_b, lgoal_b, lflags_b, hst_b, keep_applied,
                    keep_wrench, keep_lock, keep_goal, keep_hand)  # fmt: skip
        keep_teleop(0, jaw_a, jst_a, keep_jaw)
        keep_teleop(1, jaw_b, jst_b, keep_jaw)
        stop = STOP_NONE
        if on_a[0] and not device_read(
            hon_a, hst_a, hpr_a, t_pre, dt, lk_a0, lk_a1, lk_a2, lk_a3, adr_a, vadr_a, grip_a,
            Tb_a, Rb_a, flags_a, target_a, imp_a, push_a, Rw_a, pw_a, body_a, applied_a,
            wrench_a, q_a, T_a, J_a, F_a, Th_a, tw_a, xfrc_a, grip_v_a, qp, qv, xipos, xfrc_all,
        ):  # fmt: skip
            stop = STOP_TURN
        elif on_b[0] and not device_read(
            hon_b, hst_b, hpr_b, t_pre, dt, lk_b0, lk_b1, lk_b2, lk_b3, adr_b, vadr_b, grip_b,
            Tb_b, Rb_b, flags_b, target_b, imp_b, push_b, Rw_b, pw_b, body_b, applied_b,
            wrench_b, q_b, T_b, J_b, F_b, Th_b, tw_b, xfrc_b, grip_v_b, qp, qv, xipos, xfrc_all,
        ):  # fmt: skip
            stop = STOP_TURN
        # --- the teleoperations (TeleopPSM._run_enabled through follow_tick)
        if stop == STOP_NONE and ton_a[0]:
            stop = teleop_follow(
                c_a0, c_a1, c_a2, c_a3, c_a4, c_a5, c_a6, c_a7, c_a8, c_a9, tadr_a, tidx_a,
                trow_a[0], Tbr_a, shaft_a, P0_a, M0_a, Ro_a, tflags_a, jaw_a, jst_a, qmin_a,
                qmax_a, bound_a, tq_a, tT_a, tJ_a, tF_a, qo_a, qdo_a, jidx_a, dgrip_a, dTh_a,
                dtw_a, qp, frames_out, q_ref, qd_ref, tau_ff, effort,
            )  # fmt: skip
        if stop == STOP_NONE and ton_b[0]:
            stop = teleop_follow(
                c_b0, c_b1, c_b2, c_b3, c_b4, c_b5, c_b6, c_b7, c_b8, c_b9, tadr_b, tidx_b,
                trow_b[0], Tbr_b, shaft_b, P0_b, M0_b, Ro_b, tflags_b, jaw_b, jst_b, qmin_b,
                qmax_b, bound_b, tq_b, tT_b, tJ_b, tF_b, qo_b, qdo_b, jidx_b, dgrip_b, dTh_b,
                dtw_b, qp, frames_out, q_ref, qd_ref, tau_ff, effort,
            )  # fmt: skip
        # --- the camera teleoperation (TeleopECM._run_following)
        ecm_ran = False
        if stop == STOP_NONE and e_on[0]:
            if not ecm_follow(
                e_geo, e_consts, e_fric, e_q0, e_qlim, e_l0, e_l1, e_l2, e_l3, e_T, e_J, e_F,
                e_Rc0, e_Rm0, e_idx, eT_l, etw_l, eT_r, etw_r, eRb_l, eRb_r, eTb_l, eTb_r, eJ_l,
                eJ_r, eidx_l, eidx_r, e_prev, e_steps, e_ftl, e_ftr, e_lim_s, e_tau_sl,
                e_tau_sr, e_act_s, e_Rlock_s, eg_l, eg_r, q_ref, qd_ref, tau_ff, effort,
            ):  # fmt: skip
                stop = STOP_CAMERA
            ecm_ran = stop == STOP_NONE
        # --- the MTMs' orientation locks (MTM._pre_step), to the camera's goals if it ran
        gR_a = eg_a if ecm_ran else wR_a
        gR_b = eg_b if ecm_ran else wR_b
        if stop == STOP_NONE and on_a[0] and lflags_a[0] and not wrist_lock(
            wl_a0, wl_a1, wl_a2, wl_a3, wfirst_a, gR_a, wsteps_a, wdamp_a, wlo_a, whi_a, wT_a,
            wJ_a, wF_a, wA_a, wx_a, wv_a, wacc_a, wratio_a, adr_a, lflags_a, ltraj_a, lgoal_a,
            widx_a, qp, dt, q_ref, qd_ref, effort,
        ):  # fmt: skip
            stop = STOP_WRIST
        if stop == STOP_NONE and on_b[0] and lflags_b[0] and not wrist_lock(
            wl_b0, wl_b1, wl_b2, wl_b3, wfirst_b, gR_b, wsteps_b, wdamp_b, wlo_b, whi_b, wT_b,
            wJ_b, wF_b, wA_b, wx_b, wv_b, wacc_b, wratio_b, adr_b, lflags_b, ltraj_b, lgoal_b,
            widx_b, qp, dt, q_ref, qd_ref, effort,
        ):  # fmt: skip
            stop = STOP_WRIST
        if stop != STOP_NONE:
            times[2] = stop
            return _undo(2 * k, undo_a, undo_b, ujaw_a, ujaw_b, keep_applied, keep_wrench,
                         keep_lock, keep_goal, keep_jaw, keep_hand)  # fmt: skip
        # --- the guard's save; the tick's time is the state's first entry
        mj_get_state(model, data, sp, sig)
        t = state[0]
        times[0] = t
        # --- the tracking watch of every arm
        if not watch_passes(qp, w_adr, q_ref, w_idx, w_tol, effort, w_starts, w_watched,
                            w_since, t, w_first_bad, w_fault, since):  # fmt: skip
            times[2] = STOP_FAULT
            return _undo(2 * k, undo_a, undo_b, ujaw_a, ujaw_b, keep_applied, keep_wrench,
                         keep_lock, keep_goal, keep_jaw, keep_hand)  # fmt: skip
        # --- the servo (the bias forces of the last step) and the step
        if not servo_and_step(
            model, data, address, qp, qv, qb, qg, qposadr, dofadr, minus_gravcomp, q_ref,
            qd_ref, tau_ff, effort, gravity, kp, kv, w, warnings, sp, sig, since, w_since, ctrl,
            bias_before, gravcomp_before, counts, counts_after,
        ):  # fmt: skip
            times[2] = STOP_DIVERGED  # (undone, for the Python tick's guard)
            return _undo(2 * k, undo_a, undo_b, ujaw_a, ujaw_b, keep_applied, keep_wrench,
                         keep_lock, keep_goal, keep_jaw, keep_hand)  # fmt: skip
        if ecm_ran:  # (the tick ran: the camera's outputs are the objects' now)
            ecm_kept(e_prev, e_lim_s, e_tau_l, e_tau_sl, e_tau_r, e_tau_sr, e_active,
                      e_act_s, e_Rlock, e_Rlock_s)  # fmt: skip
        # --- after the step: the frames, the haptic loop, the session's sample
        t_after = t + dt  # (mj_step's time += timestep)
        times[1] = t_after
        t_pre = t_after
        qp = numba.carray(f64_at(address[1]), (nq,))
        if rec_on[0] and o_flags[1]:  # (the contacts measured for the session)
            contacts_measure(model, data, address, stride, c_tool, c_arm, c_counts, o_flex[0],
                             c_f6, k - 1, c_count, c_force, o_flex_out)  # fmt: skip
        elif rec_on[0] and tool_contacts(address, stride, rec_ncon, tool_geom, other_geom):
            times[2] = STOP_CONTACT
            return 2 * k + 1  # the instrument touches something: the session measures it
        if frames_at(qp, frame_adr, key, tol, plan, frames_out, Q_suj, q_frame_ref, T1, J_none,
                     F_suj):  # fmt: skip
            computed[0] = True
        # the fixtures' forces (nothing kept until all are finite)
        T_world_camera = frames_out[camera_row]
        result, ran_a, ran_b = 0, False, False
        if ton_a[0] and fon_a[0]:
            ran_a = True
            result = fixture_force(
                0, keep_fx, vp_a, vv_a, fon_a[1], T_world_camera, trow_a[0], frames_out, c_a5,
                c_a6, c_a7, c_a8, tadr_a, tq_a, tT_a, tJ_a, tF_a, dl_a0, dl_a1, dl_a2, dl_a3,
                dadr_a, dq_a, dT_a, dJ_a, dF_a, dTb_a, qp, ce_a, ba_a, AE_a, AA_a, EE_a, st_a,
                ed_a, cu_a, le_a, B_a, G_a, tr_a, su_a, law_a, lf_a, lp_a, vdt_a, val_a, fsteps_a,
                ftmax_a, prev_a, req_a, limd_a, tau_a, ff_a,
            )  # fmt: skip
        if result != NOT_FINITE and ton_b[0] and fon_b[0]:
            ran_b = True
            result = fixture_force(
                1, keep_fx, vp_b, vv_b, fon_b[1], T_world_camera, trow_b[0], frames_out, c_b5,
                c_b6, c_b7, c_b8, tadr_b, tq_b, tT_b, tJ_b, tF_b, dl_b0, dl_b1, dl_b2, dl_b3,
                dadr_b, dq_b, dT_b, dJ_b, dF_b, dTb_b, qp, ce_b, ba_b, AE_b, AA_b, EE_b, st_b,
                ed_b, cu_b, le_b, B_b, G_b, tr_b, su_b, law_b, lf_b, lp_b, vdt_b, val_b, fsteps_b,
                ftmax_b, prev_b, req_b, limd_b, tau_b, ff_b,
            )  # fmt: skip
        if result == NOT_FINITE:  # (the Python path's error and zero sum)
            _fixtures_back(ran_a, vp_a, vv_a, ran_b, vp_b, vv_b, keep_fx)
            times[2] = STOP_FORCE
            return 2 * k + 1
        # (HapticLoop._fixture_render: the device's rendered)
        if ton_a[0] and fon_a[0]:
            _rendered(fon_a, prev_a, limd_a, tau_a, didx_a, tau_ff)
        if ton_b[0] and fon_b[0]:
            _rendered(fon_b, prev_b, limd_b, tau_b, didx_b, tau_ff)
        # the session's sample of this tick
        if rec_on[0]:
            kinematics(rl0, rl1, rl2, rl3, radr, qp, rq, rT, rJ, rF)
            r_t[k - 1] = t_after
            np.dot(frames_out[r_row], rT, r_tip[k - 1])  # (@'s gemm, into the record)
            r_cam[k - 1] = frames_out[camera_row]
            if f_rec >= 0:
                for i in range(3):
                    r_now[i] = r_req_src[i]
            for i in range(3):
                r_req[k - 1, i] = r_now[i]
                r_master[k - 1, i] = r_Th[i, 3]
            if o_flags[0]:
                objects_read(address, stride, bodies, object_of, jaw_bit, tips, o_xpos[k - 1],
                              o_xmat[k - 1], o_grasp[k - 1], o_tips[k - 1])  # fmt: skip
    return DONE


@numba.njit(cache=True, nogil=True)
def _fixtures_back(ran_a, vp_a, vv_a, ran_b, vp_b, vv_b, keep_fx):
    """The velocity filters of the fixtures this tick ran (``ran_a``, ``ran_b``) as they
    were before (a force not finite: the Python tick renders them all again)."""
    if ran_a:
        for i in range(3):
            vp_a[i] = keep_fx[0, i]
            vv_a[i] = keep_fx[0, 3 + i]
    if ran_b:
        for i in range(3):
            vp_b[i] = keep_fx[1, i]
            vv_b[i] = keep_fx[1, 3 + i]


@numba.njit(cache=True, nogil=True)
def _rendered(fon, previous, limited, tau, idx, tau_ff):
    """A fixture's wrench rendered on its MTM: the filter has started, the limited wrench
    is the next tick's previous, the joint torques are the MTM's feed-forward."""
    fon[1] = True
    for i in range(6):
        previous[i] = limited[i]
    for i in range(idx.shape[0]):
        tau_ff[idx[i]] = tau[i]


@numba.njit(cache=True, nogil=True)
def _undo(code, undo_a, undo_b, jaw_a, jaw_b, keep_applied, keep_wrench, keep_lock, keep_goal,
          keep_jaw, keep_hand):  # fmt: skip
    """Put the hands', the locks' and the jaws' state back as they were at the tick's start
    (for the Python tick to run it); returns ``code``. ``undo_a``, ``undo_b``: devices A's
    and B's arrays :func:`~davinci_sim.console.chunk_slots.undo_device` takes; ``jaw_a``,
    ``jaw_b``: teleoperations A's and B's for :func:`~davinci_sim.console.chunk_slots.
    undo_teleop` (a few arrays each, not the slots' whole tuples: smaller code to compile)."""
    undo_device(0, *undo_a, keep_applied, keep_wrench, keep_lock, keep_goal, keep_hand)
    undo_device(1, *undo_b, keep_applied, keep_wrench, keep_lock, keep_goal, keep_hand)
    undo_teleop(0, *jaw_a, keep_jaw)
    undo_teleop(1, *jaw_b, keep_jaw)
    return code
