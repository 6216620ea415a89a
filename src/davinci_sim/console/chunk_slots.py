"""One slot's laws in the console's compiled ticks (numba only, as
:mod:`davinci_sim.console.chunk_kernel`, which calls them).

:func:`~davinci_sim.console.chunk_kernel.console_chunk` gets each simulated MTM and each
following teleoperation as a tuple of arrays (its *row*, :mod:`davinci_sim.console.chunk_rows`)
and binds every array of every row to a name once, before its ticks: a tuple's member read
inside the loop costs numba a reference count (and a runtime index a copy of the whole row),
which over the ~500 reads a tick made cost about 9 µs a tick, a third of ``mj_step``. The
functions here take those arrays one by one and do what one slot's part of a tick did in
the loop: an MTM's read (:func:`device_read`), its wrist's lock (:func:`wrist_lock`), a
teleoperation's following tick (:func:`teleop_follow`), its fixture's force
(:func:`fixture_force`), and what a rewound tick puts back (:func:`keep_device`,
:func:`keep_teleop`); and the tick's other parts: the camera teleoperation's outputs kept
once a tick has run (:func:`ecm_kept`), the instrument's contacts and the kind's objects
read after the step (:func:`tool_contacts`, :func:`objects_read`).
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.console.haptic_row import NOT_FINITE, fixture_render
from davinci_sim.console.teleop_row import follow_tick
from davinci_sim.devices.device_row import hand_read_row
from davinci_sim.devices.hand_input_row import hand_rate_row
from davinci_sim.kinematics.fk_compiled import tip_pose_row
from davinci_sim.kinematics.scratch import local, local_within
from davinci_sim.kinematics.suj import invert_rigid_row
from davinci_sim.sim.arm_laws import wrist_lock_step as _wrist_lock_step
from davinci_sim.sim.rows_kernel import f64_at, i32_at, mj_contact_force

#: Why a call stopped before its K ticks (``times[2]``).
(STOP_NONE, STOP_CANNULA, STOP_GOAL, STOP_JAW, STOP_WRIST, STOP_FAULT, STOP_DIVERGED,
 STOP_CONTACT, STOP_FORCE, STOP_TURN, STOP_CAMERA) = range(11)  # fmt: skip

wrist_lock_step = getattr(_wrist_lock_step, "dispatcher", _wrist_lock_step)


@numba.njit(cache=True, nogil=True)
def kinematics(links, modified, tool, identity, adr, qp, q, T, J, F):
    """An arm's measured kinematics (``Arm._measured_kinematics``): its joints ``q`` read
    from ``qp`` at ``adr``, the tip in its base ``T`` and the spatial Jacobian ``J``."""
    for i in range(adr.shape[0]):
        q[i] = qp[adr[i]]
    tip_pose_row(links, modified, tool, identity, q, T, J, True, F)


@numba.njit(cache=True, nogil=True)
def keep_device(d, applied, wrench, lock_traj, lock_goal, lock_flags, hand_state, keep_applied,
                keep_wrench, keep_lock, keep_goal, keep_hand):  # fmt: skip
    """Row ``d`` of the ``keep_*`` arrays: the hand's, the lock's and the rate input's state
    of device ``d`` at the tick's start (what :func:`~davinci_sim.console.chunk_kernel.
    _undo` puts back)."""
    m = lock_goal.shape[0]
    keep_applied[d] = applied[0]
    for i in range(6):
        keep_wrench[d, i] = wrench[i]
    for i in range(2 * m):
        keep_lock[d, i] = lock_traj[i]
    for i in range(m):
        keep_lock[d, 2 * m + i] = lock_goal[i]
    keep_goal[d] = lock_flags[1]
    for i in range(3):
        keep_hand[d, i] = hand_state[i]
    for i in range(9):
        keep_hand[d, 3 + i] = hand_state[12 + i]


@numba.njit(cache=True, nogil=True)
def keep_teleop(t, jaw, jaw_state, keep_jaw):
    """Row ``t`` of ``keep_jaw``: teleoperation ``t``'s jaw state at the tick's start."""
    for i in range(12):
        keep_jaw[t, i] = jaw[i]
    keep_jaw[t, 12] = jaw_state[0]


@numba.njit(cache=True, nogil=True)
def undo_device(d, on, applied, wrench, lock_traj, lock_goal, lock_flags, hand_on, hand_state,
                hand_params, target, keep_applied, keep_wrench, keep_lock, keep_goal,
                keep_hand):  # fmt: skip
    """Device ``d``'s state put back from row ``d`` of the ``keep_*`` arrays
    (:func:`keep_device`'s), the hand's target included where the rate input holds it; a
    slot's filler (``on[0]`` False) shares its arrays with a real row: left alone."""
    if not on[0]:
        return
    m = lock_goal.shape[0]
    applied[0] = keep_applied[d]
    for i in range(6):
        wrench[i] = keep_wrench[d, i]
    for i in range(2 * m):
        lock_traj[i] = keep_lock[d, i]
    for i in range(m):
        lock_goal[i] = keep_lock[d, 2 * m + i]
    lock_flags[1] = keep_goal[d]
    for i in range(3):  # (the hand's target: HandInput._target and the device's)
        hand_state[i] = keep_hand[d, i]
        if hand_on[0]:
            target[i, 3] = keep_hand[d, i]
    for i in range(9):  # (and the wrist's, when it holds one)
        hand_state[12 + i] = keep_hand[d, 3 + i]
        if hand_on[0] and hand_params[4] != 0.0:
            target[i // 3, i % 3] = keep_hand[d, 3 + i]


@numba.njit(cache=True, nogil=True)
def undo_teleop(t, on, jaw, jaw_state, keep_jaw):
    """Teleoperation ``t``'s jaw state put back from row ``t`` of ``keep_jaw``
    (:func:`keep_teleop`'s); a slot's filler left alone."""
    if not on[0]:
        return
    for i in range(12):
        jaw[i] = keep_jaw[t, i]
    jaw_state[0] = keep_jaw[t, 12]


@numba.njit(cache=True, nogil=True)
def device_read(hand_on, hand_state, hand_params, t_pre, dt, links, modified, tool, identity,
                adr, vadr, grip_adr, T_ref_base, R_hrsv_base, flags, target, impedance, push,
                R_world_hrsv, p_world_hrsv, body, applied, wrench, q, T, J, F, T_hrsv, twist,
                xfrc, gripper, qp, qv, xipos, xfrc_all) -> bool:  # fmt: skip
    """A simulated MTM's read (``SimulatedMTM._read``): the rate input moves the hand's
    target first where it holds the handle and its velocities hold (``HandInput.pre_step``),
    then the handle's pose ``T_hrsv`` and twist, the hand's wrench on it (into ``xfrc_all``
    at its body) and the gripper. False (nothing read) where the rate input's turn is
    Python's (:func:`~davinci_sim.devices.hand_input_row.hand_rate_row`)."""
    if hand_on[0] and t_pre < hand_params[2]:
        if not hand_rate_row((hand_on, hand_state, hand_params), T_hrsv, target, dt):
            return False
    kinematics(links, modified, tool, identity, adr, qp, q, T, J, F)
    np.dot(T_ref_base, T, T_hrsv)  # (Arm._measured_T: numpy's product, the same gemm as @)
    qd = local_within(16, vadr.shape[0])  # (in the frame, as the other scratch arrays)
    for i in range(vadr.shape[0]):
        qd[i] = qv[vadr[i]]
    b = body[0]
    com = xipos[3 * b : 3 * b + 3]
    out_w = local(6)
    if hand_read_row(
        T_hrsv, R_hrsv_base, J, qd, flags[0], target, hand_state[21:27], flags[1], flags[2],
        applied[0],
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
    return True


@numba.njit(cache=True, nogil=True)
def teleop_follow(ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, fk_links, fk_modified,
                  fk_tool, fk_identity, ik_tolerance, adr, idx, frame_row, T_base_ref, shaft,
                  T_camera_psm0, T_hrsv_mtm0, R_offset, flags, jaw, jaw_state, qmin, qmax,
                  qd_bound, q, T, J, F, q_out, qd_out, jaw_idx, gripper, T_hrsv_mtm,
                  twist_mtm, qp, frames_out, q_ref, qd_ref, tau_ff, effort) -> int:  # fmt: skip
    """A following teleoperation's tick (``TeleopPSM._run_enabled`` through
    :func:`~davinci_sim.console.teleop_row.follow_tick`): the PSM's joint references from
    its MTM's read (``gripper``, ``T_hrsv_mtm``, ``twist_mtm``) and the jaw's when it
    changes. Returns :data:`STOP_NONE`, or why the tick is Python's (nothing written but
    scratch): the tool in the cannula, a goal with no compiled answer, a jaw angle to
    refuse."""
    if abs(qp[int(shaft[0])] + shaft[1]) < shaft[2]:
        return STOP_CANNULA
    invert_rigid_row(frames_out[frame_row], T_base_ref)  # (Arm._T_base_reference)
    kinematics(fk_links, fk_modified, fk_tool, fk_identity, adr, qp, q, T, J, F)
    jaw_now = local_within(16, jaw.shape[0])
    for i in range(jaw.shape[0]):
        jaw_now[i] = jaw[i]
    jaw_now[1] = gripper[0]  # the MTM's gripper
    if not follow_tick(
        ik_geometry, ik_tool, ik_revolute, ik_lo, ik_hi, fk_links, fk_modified, fk_tool,
        fk_identity, ik_tolerance, T_base_ref, T_camera_psm0, T_hrsv_mtm0, T_hrsv_mtm, R_offset,
        twist_mtm, flags, q, J, qmin, qmax, qd_bound, q_out, qd_out, jaw_now,
    ):  # fmt: skip
        return STOP_GOAL
    if jaw_state[1] == 0.0:  # (the jaw followed: TeleopPSM._ignore_jaw off)
        angle = jaw_now[11]
        if angle != jaw_state[0]:  # sent when it changes (Jaw._servo_jp_checked)
            if not np.isfinite(angle):  # (refused, with the jaw's message)
                return STOP_JAW
            jaw_state[0] = angle
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
    return STOP_NONE


@numba.njit(cache=True, nogil=True)
def wrist_lock(links, modified, tool, identity, first, R_base_goal, steps, damping, lo, hi, Tl,
               Jl, Fl, A, x, v_max, a_max, ratio, adr, lock_flags, lock_traj, lock_goal,
               wrist_idx, qp, dt, q_ref, qd_ref, effort) -> bool:  # fmt: skip
    """An MTM's orientation lock (``MTM._pre_step``): the wrist's goal solved from its
    joints (seeded with the last solution: it leads the wrist), one step of its trajectory,
    the wrist's references. False (nothing written) where the solve fails."""
    n = adr.shape[0]
    q_seed = local_within(16, n)
    for i in range(n):
        q_seed[i] = qp[adr[i]]
    if lock_flags[1]:
        for i in range(n - first):
            q_seed[first + i] = lock_goal[i]
    m = n - first
    goal = local_within(16, m)
    q_l, qd_l = local_within(16, m), local_within(16, m)
    if not wrist_lock_step(
        links, modified, tool, identity, q_seed, first, R_base_goal, steps, damping, lo, hi, Tl,
        Jl, Fl, A, x, goal, lock_traj[:m], lock_traj[m : 2 * m], v_max, a_max, ratio, dt, q_l,
        qd_l,
    ):  # fmt: skip
        return False
    for i in range(m):
        lock_goal[i] = goal[i]
        lock_traj[i] = q_l[i]
        lock_traj[m + i] = qd_l[i]
        effort[wrist_idx[i]] = False
        q_ref[wrist_idx[i]] = q_l[i]
        qd_ref[wrist_idx[i]] = qd_l[i]
    lock_flags[1] = True
    return True


@numba.njit(cache=True, nogil=True)
def fixture_force(m, keep_fx, vf_p, vf_v, started, T_world_camera, frame_row, frames_out,
                  fk_links, fk_modified, fk_tool, fk_identity, adr, q, T, J, F, d_links,
                  d_modified, d_tool, d_identity, d_adr, d_q, d_T, d_J, d_F, d_T_ref_base,
                  qp, centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, B, G_max,
                  transition, summed, law, law_fn, params, vf_dt, vf_alpha, steps, ftmax, previous,
                  requested, limited, tau, out_flags) -> int:  # fmt: skip
    """Teleoperation ``m``'s fixture after the step (``HapticLoop._fixture_render``): its
    MTM's and its PSM's kinematics, the force on the tip in the camera frame
    (:func:`~davinci_sim.console.haptic_row.fixture_render`) with the velocity filter's
    state kept first in row ``m`` of ``keep_fx``; returns the render's result (its flag
    in ``out_flags`` where the force is finite)."""
    kinematics(d_links, d_modified, d_tool, d_identity, d_adr, qp, d_q, d_T, d_J, d_F)
    kinematics(fk_links, fk_modified, fk_tool, fk_identity, adr, qp, q, T, J, F)
    T_camera_tip = local(4, 4)
    np.dot(frames_out[frame_row], T, T_camera_tip)  # (Arm._measured_T: @'s gemm)
    for i in range(3):
        keep_fx[m, i] = vf_p[i]
        keep_fx[m, 3 + i] = vf_v[i]
    result = fixture_render(
        T_world_camera, T_camera_tip, vf_p, vf_v, started, vf_dt, vf_alpha, centre, basis, AE,
        AA, EE, starts, edges, cumulative, lengths, B, G_max, transition, summed, law, law_fn,
        params, previous, steps, d_T_ref_base, d_J, ftmax, requested, limited, tau,
    )  # fmt: skip
    if result != NOT_FINITE:  # (else the caller puts the filters back: Python's tick)
        out_flags[0] = result == 1
    return result


@numba.njit(cache=True, nogil=True)
def ecm_kept(previous, limited, tau_l, tau_sl, tau_r, tau_sr, active, active_s, R_lock,
              R_lock_s):  # fmt: skip
    """A run tick's camera outputs into what the next tick reads and the chunk writes back:
    the clamps' last wrenches, the efforts, whether each clamp acted, the locks."""
    previous[:, :] = limited
    tau_l[:] = tau_sl
    tau_r[:] = tau_sr
    active[:] = active_s
    R_lock[:, :, :] = R_lock_s


@numba.njit(cache=True, nogil=True)
def tool_contacts(address, stride, watch, tool_geom, other_geom) -> bool:
    """Whether a contact of the state now involves an instrument and something it may
    collide with (``InstrumentContacts.measure`` may count it: the tables are a superset):
    the contacts' geom pairs read from ``mjData.contact`` (``address[9]``, ``stride`` bytes
    apart; a flex's side is geom −1, the tables' last entry: neither)."""
    ncon = numba.carray(i32_at(address[6]), (1,))[0]
    if ncon == 0 or not watch[0]:
        return False
    for i in range(ncon):
        g = numba.carray(i32_at(address[9] + i * stride), (2,))
        a, b = g[0], g[1]
        if (tool_geom[a] and other_geom[b]) or (tool_geom[b] and other_geom[a]):
            return True
    return False


@numba.njit(cache=True, nogil=True)
def contacts_measure(model, data, address, stride, tool_of, arm_of, counts, flex, f6, k,
                     out_count, out_force, out_flex):  # fmt: skip
    """What the session measures of the contacts after a step, as Python measures them:
    ``InstrumentContacts.measure``'s number of the instruments' contacts that count and
    their total normal force (N; its tables ``tool_of``, ``arm_of``, ``counts``, per geom,
    the last entry a flex's side) into ``out_count[k]`` and ``out_force[k]``, and
    ``ObjectsProbe.read``'s normal force of the contacts with the flex ``flex`` (N; none if
    negative) into ``out_flex[k]``. The contacts' geoms and flexes are read from
    ``mjData.contact`` (``address[9]`` and ``address[13]``, ``stride`` bytes apart), their
    forces with MuJoCo's ``mj_contactForce`` (into the scratch ``f6``), summed in the
    contacts' order (Python's sums, the same bits)."""
    ncon = numba.carray(i32_at(address[6]), (1,))[0]
    count, force, on_flex = 0, 0.0, 0.0
    for i in range(ncon):
        g = numba.carray(i32_at(address[9] + i * stride), (2,))
        a, b = g[0], g[1]
        ta, tb = tool_of[a], tool_of[b]
        hit = (ta >= 0 and arm_of[b] != ta and counts[b]) or (
            tb >= 0 and arm_of[a] != tb and counts[a]
        )
        touched = False
        if flex >= 0:
            fx = numba.carray(i32_at(address[13] + i * stride), (2,))
            touched = fx[0] == flex or fx[1] == flex
        if hit or touched:
            mj_contact_force(model, data, i, f6.ctypes.data)
            if hit:
                count += 1
                force += abs(f6[0])
            if touched:
                on_flex += abs(f6[0])
    out_count[k] = count
    out_force[k] = force
    out_flex[k] = on_flex


@numba.njit(cache=True, nogil=True)
def objects_read(address, stride, bodies, object_of, jaw_bit, tips, xpos, xmat, grasp,
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
