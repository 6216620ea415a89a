"""The console's ticks in one compiled call (numba only: imported by
:mod:`davinci_sim.console.chunk` once MuJoCo's library is loaded into LLVM's symbols, as
:mod:`davinci_sim.sim.live_kernel`).

One call runs ticks ``1 … K`` of :meth:`Simulation.tick
<davinci_sim.sim.simulation.Simulation.tick>` for a console in its steady state: every
simulated MTM read (``SimulatedMTM._read``: the handle's pose and twist, the hand's wrench on
it, :func:`~davinci_sim.devices.device_row.hand_read_row`), every following teleoperation's
tick (:func:`~davinci_sim.console.teleop_row.follow_tick`, with the PSM's in-cannula check),
the MTMs' orientation locks (:func:`~davinci_sim.sim.arm_laws.wrist_lock_step`), the tracking
watch, the joint servo, the divergence guard's save and ``mj_step``; after the step, the
setup-joint frames, the haptic loop's fixture on each following MTM
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
something: the session measures its contacts; a guidance force that is not finite),
``2·k + 1``: the caller runs tick k's post-steps in Python. :data:`DONE` when all K ran.

Module-level functions, so that numba's on-disk cache keeps them between processes.
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.console.haptic_row import NOT_FINITE, fixture_render
from davinci_sim.console.teleop_row import follow_tick
from davinci_sim.devices.device_row import hand_read_row
from davinci_sim.devices.hand_input_row import hand_rate_row
from davinci_sim.kinematics.fk_compiled import tip_pose_row
from davinci_sim.kinematics.suj import invert_rigid_row
from davinci_sim.sim.arm_laws import wrist_lock_step as _wrist_lock_step
from davinci_sim.sim.live_kernel import frames_at, servo_and_step, step_scratch, watch_passes
from davinci_sim.sim.rows_kernel import f64_at, i32_at, mj_get_state

#: Why a call stopped before its K ticks (``times[2]``).
(STOP_NONE, STOP_CANNULA, STOP_GOAL, STOP_JAW, STOP_WRIST, STOP_FAULT, STOP_DIVERGED,
 STOP_CONTACT, STOP_FORCE, STOP_TURN) = range(10)  # fmt: skip
STOP_REASONS = (
    "", "the tool in the cannula", "a goal servo_cp has no compiled answer for",
    "a jaw angle to send", "a failed wrist solve", "a tracking fault", "a diverged step",
    "an instrument contact", "a guidance force not finite", "a turned wrist target off",
)  # fmt: skip

wrist_lock_step = getattr(_wrist_lock_step, "dispatcher", _wrist_lock_step)

#: What a call returns when it ran every tick.
DONE = -1

# The physics tuple (see :func:`console_chunk`), by position.
(P_MODEL, P_DATA, P_ADDRESS, P_SIZES, P_STATE, P_SIG, P_WARNINGS, P_QPOSADR, P_DOFADR,
 P_GRAVCOMP, P_KP, P_KV, P_EFFORT, P_GRAVITY, P_Q_REF, P_QD_REF, P_TAU_FF, P_DT,
 P_TIMES) = range(19)  # fmt: skip


@numba.njit(cache=True, nogil=True)
def _frames_at(qp, fr, Q_suj, q_frame_ref, T1, J_none, F_suj):
    """``Simulation._frames`` at the joints ``qp`` (:func:`frames_at` with ``fr``'s plan,
    key, tolerance and ``frames_out``; then ``computed[0]`` set); returns whether the frames
    were recomputed."""
    plan = (fr[0], fr[1], fr[2], fr[3], fr[4], fr[5], fr[6], fr[7], fr[8], fr[9])
    if not frames_at(qp, fr[10], fr[11], fr[12], plan, fr[13], Q_suj, q_frame_ref, T1, J_none,
                     F_suj):  # fmt: skip
        return False
    fr[14][0] = True
    return True


@numba.njit(cache=True, nogil=True)
def _kinematics(fk, adr, qp, q, T, J, F):
    """An arm's measured kinematics (``Arm._measured_kinematics``): its joints ``q`` read
    from ``qp`` at ``adr``, the tip in its base ``T`` and the spatial Jacobian ``J``."""
    for i in range(adr.shape[0]):
        q[i] = qp[adr[i]]
    tip_pose_row(fk[0], fk[1], fk[2], fk[3], q, T, J, True, F)


@numba.njit(cache=True, nogil=True)
def console_chunk(phys, watch, fr, devices, teleops, rec, K):
    """Ticks ``1 … K`` (see the module docstring); returns :data:`DONE`, ``2·k`` (tick k
    not run) or ``2·k + 1`` (tick k's post-steps to run in Python).

    ``phys``: the C pointers of the model and data, the buffers' addresses (``ctrl``,
    ``qpos``, ``qvel``, ``qfrc_bias``, ``qfrc_gravcomp``, the warning statistics, ``ncon``,
    ``xfrc_applied``, ``xipos``, the first contact's geoms), the sizes (nu, nq, nv, number
    of warnings, the contacts' stride in bytes), the guard's state scratch and signature,
    the warnings it watches, then the servo's arrays (updated in place) and the time step.
    ``watch``: the tracking watch's arrays. ``fr``: the setup-joint frame plan, its key
    (the joints of the frames held), tolerance, ``frames_out`` and ``computed``.

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
    xpos, xmat, grasp, tip_out)``: the task session's samples of each tick (after its
    step), with its kind's objects (``ObjectsProbe.read``) where ``objects_flags[0]``; a
    contact with a flex ends a call before the tick's post-steps where
    ``objects_flags[1]``."""
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
    # the frames' scratch (Simulation._frames)
    plan_links, ref_links, frame_adr = fr[0], fr[6], fr[10]
    frames_out = fr[13]
    n_suj, n_ref = plan_links.shape[0], ref_links.shape[1]
    n_joints = (frame_adr.shape[0] - n_ref) // n_suj
    Q_suj = np.empty((n_suj, n_joints))
    q_frame_ref = np.empty(n_ref)
    T1 = np.empty((4, 4))
    F_suj = np.empty((max(n_joints, 8), 12))
    J_none = np.empty((6, 0))
    # what a rewound tick puts back: the hands', the jaws' and the locks' state
    nd, nt = len(devices), len(teleops)
    keep_applied = np.empty(nd, dtype=np.bool_)
    keep_wrench = np.empty((nd, 6))
    keep_lock = np.empty((nd, 3 * devices[0][26].shape[0]))
    keep_goal = np.empty(nd, dtype=np.bool_)
    keep_jaw = np.empty((nt, 13))
    keep_hand = np.empty((nd, 12))
    t_pre = times[3]  # (the tick's time before its step: the state's, then + dt per step)
    keep_fx = np.empty((nt, 6))
    m_lock = devices[0][26].shape[0]
    xfrc_all = numba.carray(f64_at(address[7]), (6 * (sizes[5]),))
    xipos = numba.carray(f64_at(address[8]), (3 * (sizes[5]),))
    for k in range(1, K + 1):
        qp = numba.carray(f64_at(address[1]), (nq,))
        qv = numba.carray(f64_at(address[2]), (nv,))
        qb = numba.carray(f64_at(address[3]), (nv,))
        qg = numba.carray(f64_at(address[4]), (nv,))
        w = numba.carray(i32_at(address[5]), (2 * nw,))
        _frames_at(qp, fr, Q_suj, q_frame_ref, T1, J_none, F_suj)
        # --- the devices' reads (SimulatedMTM._read): pose, twist, the hand's wrench
        d = 0
        for dev in devices:
            (fk, adr, vadr, grip_adr, T_ref_base, R_hrsv_base, flags, target, impedance,
             push, R_world_hrsv, p_world_hrsv, body, applied, wrench, q, T, J, F, T_hrsv,
             twist, xfrc, gripper, lock, lock_flags, lock_traj, lock_goal, wrist_idx, idx,
             hand, on) = dev  # fmt: skip
            keep_applied[d] = applied[0]
            for i in range(6):
                keep_wrench[d, i] = wrench[i]
            for i in range(2 * m_lock):
                keep_lock[d, i] = lock_traj[i]
            for i in range(m_lock):
                keep_lock[d, 2 * m_lock + i] = lock_goal[i]
            keep_goal[d] = lock_flags[1]
            for i in range(3):
                keep_hand[d, i] = hand[1][i]
            for i in range(9):
                keep_hand[d, 3 + i] = hand[1][12 + i]
            d += 1
            if not on[0]:
                continue
            if hand[0][0] and t_pre < hand[2][2]:  # the hand moves (HandInput.pre_step)
                if not hand_rate_row(hand, T_hrsv, target, dt):
                    times[2] = STOP_TURN
                    return _undo(2 * k, devices, teleops, keep_applied, keep_wrench, keep_lock,
                                 keep_goal, keep_jaw, keep_hand)  # fmt: skip
            _kinematics(fk, adr, qp, q, T, J, F)
            T_hrsv[:, :] = T_ref_base @ T  # (Arm._measured_T: numpy's product)
            qd = np.empty(vadr.shape[0])
            for i in range(vadr.shape[0]):
                qd[i] = qv[vadr[i]]
            b = body[0]
            com = xipos[3 * b : 3 * b + 3]
            out_w = np.empty(6)
            if hand_read_row(
                T_hrsv, R_hrsv_base, J, qd, flags[0], target, flags[1], flags[2], applied[0],
                impedance, push, R_world_hrsv, p_world_hrsv, com, twist, out_w, xfrc,
            ):  # fmt: skip
                applied[0] = False
                for i in range(6):
                    wrench[i] = out_w[i]
                    applied[0] = applied[0] or out_w[i] != 0.0
                    xfrc_all[6 * b + i] = xfrc[i]
            g = 0.0  # (Jaw._angle: numpy's sum of a few, in order)
            for i in range(grip_adr.shape[0]):
                g += qp[grip_adr[i]]
            gripper[0] = g
        # --- the teleoperations (TeleopPSM._run_enabled through follow_tick)
        t_i = 0
        for tel in teleops:
            (cp, adr, idx, row, T_base_ref, shaft, anchors, flags, jaw, jaw_state, limits,
             device, q, T, J, F, q_out, qd_out, fixture, fx_state, fx_out, _,
             on) = tel  # fmt: skip
            for i in range(12):
                keep_jaw[t_i, i] = jaw[i]
            keep_jaw[t_i, 12] = tel[9][0]
            t_i += 1
            if not on[0]:
                continue
            if abs(qp[int(shaft[0])] + shaft[1]) < shaft[2]:
                times[2] = STOP_CANNULA
                return _undo(2 * k, devices, teleops, keep_applied, keep_wrench, keep_lock,
                             keep_goal, keep_jaw, keep_hand)  # fmt: skip
            invert_rigid_row(frames_out[row[0]], T_base_ref)  # (Arm._T_base_reference)
            _kinematics((cp[5], cp[6], cp[7], cp[8]), adr, qp, q, T, J, F)
            dv = devices[device[0]]
            jaw_now = jaw.copy()
            jaw_now[1] = dv[22][0]  # the MTM's gripper
            if not follow_tick(
                cp[0], cp[1], cp[2], cp[3], cp[4], cp[5], cp[6], cp[7], cp[8], cp[9],
                T_base_ref, anchors[0], anchors[1], dv[19], anchors[2], dv[20], flags, q, J,
                limits[0], limits[1], limits[2], q_out, qd_out, jaw_now,
            ):  # fmt: skip
                times[2] = STOP_GOAL
                return _undo(2 * k, devices, teleops, keep_applied, keep_wrench, keep_lock,
                             keep_goal, keep_jaw, keep_hand)  # fmt: skip
            if jaw_state[1] == 0.0:  # (the jaw followed: TeleopPSM._ignore_jaw off)
                angle = jaw_now[11]
                if angle != jaw_state[0]:  # sent when it changes (Jaw._servo_jp_checked)
                    if not np.isfinite(angle):  # (refused, with the jaw's message)
                        times[2] = STOP_JAW
                        return _undo(2 * k, devices, teleops, keep_applied, keep_wrench,
                                     keep_lock, keep_goal, keep_jaw, keep_hand)  # fmt: skip
                    jaw_state[0] = angle
                    jaw_idx = tel[21]
                    for i in range(jaw_idx.shape[0]):  # (Jaw._set: finger_setpoints)
                        effort[jaw_idx[i]] = False
                        tau_ff[jaw_idx[i]] = 0.0
                        q_ref[jaw_idx[i]] = 0.5 * angle
                        qd_ref[jaw_idx[i]] = 0.5 * 0.0
                for i in range(12):
                    jaw[i] = jaw_now[i]
            for i in range(idx.shape[0]):  # (PSM._servo_position)
                q_ref[idx[i]] = q_out[i]
                qd_ref[idx[i]] = qd_out[i]
        # --- the MTMs' orientation locks (MTM._pre_step)
        for dev in devices:
            fk, adr, lock, lock_flags, lock_traj = dev[0], dev[1], dev[23], dev[24], dev[25]
            lock_goal, wrist_idx = dev[26], dev[27]
            if not (dev[30][0] and lock_flags[0]):
                continue
            (links, modified, tool, identity, first, R_base_goal, steps, damping, lo, hi, Tl,
             Jl, Fl, A, x, v_max, a_max, ratio) = lock  # fmt: skip
            n = adr.shape[0]
            q_seed = np.empty(n)
            for i in range(n):
                q_seed[i] = qp[adr[i]]
            if lock_flags[1]:  # (the last solution seeds the solve: it leads the wrist)
                for i in range(n - first):
                    q_seed[first + i] = lock_goal[i]
            m = n - first
            goal = np.empty(m)
            q_l, qd_l = np.empty(m), np.empty(m)
            if not wrist_lock_step(
                links, modified, tool, identity, q_seed, first, R_base_goal, steps, damping,
                lo, hi, Tl, Jl, Fl, A, x, goal, lock_traj[:m], lock_traj[m : 2 * m], v_max,
                a_max, ratio, dt, q_l, qd_l,
            ):  # fmt: skip
                times[2] = STOP_WRIST
                return _undo(2 * k, devices, teleops, keep_applied, keep_wrench, keep_lock,
                             keep_goal, keep_jaw, keep_hand)  # fmt: skip
            for i in range(m):
                lock_goal[i] = goal[i]
                lock_traj[i] = q_l[i]
                lock_traj[m + i] = qd_l[i]
                effort[wrist_idx[i]] = False
                q_ref[wrist_idx[i]] = q_l[i]
                qd_ref[wrist_idx[i]] = qd_l[i]
            lock_flags[1] = True
        # --- the guard's save; the tick's time is the state's first entry
        mj_get_state(model, data, sp, sig)
        t = state[0]
        times[0] = t
        # --- the tracking watch of every arm
        if not watch_passes(qp, w_adr, q_ref, w_idx, w_tol, effort, w_starts, w_watched,
                            w_since, t, w_first_bad, w_fault, since):  # fmt: skip
            times[2] = STOP_FAULT
            return _undo(2 * k, devices, teleops, keep_applied, keep_wrench, keep_lock,
                         keep_goal, keep_jaw, keep_hand)  # fmt: skip
        # --- the servo (the bias forces of the last step) and the step
        if not servo_and_step(
            model, data, address, qp, qv, qb, qg, qposadr, dofadr, minus_gravcomp, q_ref,
            qd_ref, tau_ff, effort, gravity, kp, kv, w, warnings, sp, sig, since, w_since, ctrl,
            bias_before, gravcomp_before, counts, counts_after,
        ):  # fmt: skip
            times[2] = STOP_DIVERGED  # (undone, for the Python tick's guard)
            return _undo(2 * k, devices, teleops, keep_applied, keep_wrench, keep_lock,
                         keep_goal, keep_jaw, keep_hand)  # fmt: skip
        # --- after the step: the frames, the haptic loop, the session's sample
        t_after = t + dt  # (mj_step's time += timestep)
        times[1] = t_after
        t_pre = t_after
        qp = numba.carray(f64_at(address[1]), (nq,))
        if rec[0][0] and _tool_contacts(address, stride, rec[3], rec[4], rec[5],
                                        rec[16][1]):  # fmt: skip
            times[2] = STOP_CONTACT
            return 2 * k + 1  # the instrument touches something: the session measures it
        _frames_at(qp, fr, Q_suj, q_frame_ref, T1, J_none, F_suj)
        for m in range(nt):  # the fixtures' forces (nothing kept until all are finite)
            tel = teleops[m]
            fixture, fx_state, fx_out = tel[18], tel[19], tel[20]
            on, vf_p, vf_v, previous = fx_state[0], fx_state[1], fx_state[2], fx_state[3]
            if not (tel[22][0] and on[0]):
                continue
            dv = devices[tel[11][0]]
            _kinematics(dv[0], dv[1], qp, dv[15], dv[16], dv[17], dv[18])  # the MTM's
            _kinematics((tel[0][5], tel[0][6], tel[0][7], tel[0][8]), tel[1], qp, tel[12],
                        tel[13], tel[14], tel[15])  # fmt: skip
            T_camera_tip = frames_out[tel[3][0]] @ tel[13]  # (Arm._measured_T)
            for i in range(3):
                keep_fx[m, i] = vf_p[i]
                keep_fx[m, 3 + i] = vf_v[i]
            (centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, B, G_max,
             transition, summed, vf_dt, vf_alpha, steps, ftmax) = fixture  # fmt: skip
            requested, limited, tau, flags = fx_out[0], fx_out[1], fx_out[2], fx_out[3]
            result = fixture_render(
                frames_out[fr[15][0]], T_camera_tip, vf_p, vf_v, on[1], vf_dt, vf_alpha,
                centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, B, G_max,
                transition, summed, previous, steps, dv[4], dv[17], ftmax, requested, limited,
                tau,
            )  # fmt: skip
            if result == NOT_FINITE:  # (the Python path's error and zero sum)
                for j in range(m + 1):
                    fs = teleops[j][19]
                    if teleops[j][22][0] and fs[0][0]:
                        for i in range(3):
                            fs[1][i] = keep_fx[j, i]
                            fs[2][i] = keep_fx[j, 3 + i]
                times[2] = STOP_FORCE
                return 2 * k + 1
            flags[0] = result == 1
        for tel in teleops:  # (HapticLoop._fixture_render: the device's rendered)
            fx_state, fx_out = tel[19], tel[20]
            on, previous, limited, tau = fx_state[0], fx_state[3], fx_out[1], fx_out[2]
            if not (tel[22][0] and on[0]):
                continue
            on[1] = True  # (the filter has started)
            for i in range(6):
                previous[i] = limited[i]
            idx = devices[tel[11][0]][28]
            for i in range(idx.shape[0]):
                tau_ff[idx[i]] = tau[i]
        # the session's sample of this tick
        if rec[0][0]:
            tel = teleops[rec[1][0]]
            _kinematics((tel[0][5], tel[0][6], tel[0][7], tel[0][8]), tel[1], qp, tel[12],
                        tel[13], tel[14], tel[15])  # fmt: skip
            rec[6][k - 1] = t_after
            rec[7][k - 1] = frames_out[tel[3][0]] @ tel[13]
            rec[8][k - 1] = frames_out[fr[15][0]]
            f = rec[2][0]
            if f >= 0:
                for i in range(3):
                    rec[11][i] = teleops[f][20][0][i]
            for i in range(3):
                rec[9][k - 1, i] = rec[11][i]
                rec[10][k - 1, i] = devices[tel[11][0]][19][i, 3]
            if rec[16][0]:
                _objects_read(
                    address,
                    stride,
                    rec[12],
                    rec[13],
                    rec[14],
                    rec[15],
                    rec[17][k - 1],
                    rec[18][k - 1],
                    rec[19][k - 1],
                    rec[20][k - 1],
                )
    return DONE


@numba.njit(cache=True, nogil=True)
def _tool_contacts(address, stride, watch, tool_geom, other_geom, flex) -> bool:
    """Whether a contact of the state now involves an instrument and something it may
    collide with (``InstrumentContacts.measure`` may count it: the tables are a superset),
    or, where ``flex``, a flex (the session measures the force on it): the contacts' geom
    pairs read from ``mjData.contact`` (``address[9]``, ``stride`` bytes apart; a flex's
    side is geom −1, the tables' last entry)."""
    ncon = numba.carray(i32_at(address[6]), (1,))[0]
    if ncon == 0 or not watch[0]:
        return False
    for i in range(ncon):
        g = numba.carray(i32_at(address[9] + i * stride), (2,))
        a, b = g[0], g[1]
        if flex and (a < 0 or b < 0):
            return True
        if (tool_geom[a] and other_geom[b]) or (tool_geom[b] and other_geom[a]):
            return True
    return False


@numba.njit(cache=True, nogil=True)
def _objects_read(address, stride, bodies, object_of, jaw_bit, tips, xpos, xmat, grasp,
                  tip_out):  # fmt: skip
    """``ObjectsProbe.read`` after a step: each object body's ``xpos`` and ``xmat``
    (``address[10]``, ``address[11]``), the jaw bits of the contacts between an object's
    geom and a jaw (``object_of``, ``jaw_bit``: per geom, the last entry a flex's side)
    and the tip sites' ``site_xpos`` (``address[12]``)."""
    for i in range(bodies.shape[0]):
        p = numba.carray(f64_at(address[10] + 24 * bodies[i]), (3,))
        R = numba.carray(f64_at(address[11] + 72 * bodies[i]), (9,))
        for c in range(3):
            xpos[i, c] = p[c]
        for c in range(9):
            xmat[i, c] = R[c]
        grasp[i] = 0
    for i in range(tips.shape[0]):
        p = numba.carray(f64_at(address[12] + 24 * tips[i]), (3,))
        for c in range(3):
            tip_out[i, c] = p[c]
    ncon = numba.carray(i32_at(address[6]), (1,))[0]
    for i in range(ncon):
        g = numba.carray(i32_at(address[9] + i * stride), (2,))
        for a, b in ((g[0], g[1]), (g[1], g[0])):
            o, bit = object_of[a], jaw_bit[b]
            if o >= 0 and bit > 0:
                grasp[o] |= bit


@numba.njit(cache=True, nogil=True)
def _undo(code, devices, teleops, keep_applied, keep_wrench, keep_lock, keep_goal, keep_jaw,
          keep_hand):  # fmt: skip
    """Put the hands', the locks' and the jaws' state back as they were at the tick's start
    (for the Python tick to run it); returns ``code``."""
    d = 0
    for dev in devices:
        applied, wrench, lock_flags = dev[13], dev[14], dev[24]
        lock_traj, lock_goal = dev[25], dev[26]
        if not dev[30][0]:  # (a slot's filler shares its arrays with a real row)
            d += 1
            continue
        applied[0] = keep_applied[d]
        for i in range(6):
            wrench[i] = keep_wrench[d, i]
        for i in range(lock_traj.shape[0]):
            lock_traj[i] = keep_lock[d, i]
        for i in range(lock_goal.shape[0]):
            lock_goal[i] = keep_lock[d, lock_traj.shape[0] + i]
        lock_flags[1] = keep_goal[d]
        hand, target = dev[29], dev[7]
        for i in range(3):  # (the hand's target: HandInput._target and the device's)
            hand[1][i] = keep_hand[d, i]
            if hand[0][0]:
                target[i, 3] = keep_hand[d, i]
        for i in range(9):  # (and the wrist's, when it holds one)
            hand[1][12 + i] = keep_hand[d, 3 + i]
            if hand[0][0] and hand[2][4] != 0.0:
                target[i // 3, i % 3] = keep_hand[d, 3 + i]
        d += 1
    t_i = 0
    for tel in teleops:
        jaw = tel[8]
        if not tel[22][0]:
            t_i += 1
            continue
        for i in range(12):
            jaw[i] = keep_jaw[t_i, i]
        tel[9][0] = keep_jaw[t_i, 12]
        t_i += 1
    return code
