"""The study batch's ticks a chunk at a time, each trial stepped several ticks in a row
(numba only: imported by :mod:`davinci_sim.study.batch_compiled` with the tick's kernels).

Stepping the trials of a batch in turn, one tick each, finds each trial's ``MjData`` cold in
the caches: a step of the study's scene took ~35 µs that way against ~20 µs stepping one
trial again and again (2-core VM, 100 trials). :func:`chunk_rows` runs up to K ticks of one
trial before the next, every law of the tick the compiled tick runs plus the trainee and
the hand (the same per-row kernels: :func:`~davinci_sim.operators.trainee_row.command_row`,
:func:`~davinci_sim.devices.device_row.hand_rows`' laws, the study tick's
:func:`~davinci_sim.study.tick_kernel.teleop_solve_row`, ``teleop_write_row``,
``tracking_row``, ``step_row``, ``haptics_row``), in the tick's order. The trials are
independent, so each one's ticks give the same bits in any order. What each tick leaves for
the task (the tip and the master in their frames, the guidance force, whether the trial
ran) is recorded; the caller runs the task on those samples tick by tick afterwards (the
task only observes: nothing in the loop reads it), which also ends trials that finished.

A tick it has no compiled form of (a goal whose IK needs Python, a step that left contacts
to measure) stops the chunk (its row and tick returned); the caller then restores the
state of the chunk's start and runs the chunk up to that tick, then that tick in Python.
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.devices.device_row import _xfrc_into
from davinci_sim.devices.hand import _hand_rows
from davinci_sim.model.cameras import in_left_image_floats
from davinci_sim.operators.trainee_row import ARGS, command_row
from davinci_sim.operators.wrist import hand_rotation_row, plan_fraction_row
from davinci_sim.sim.rows_kernel import i32_at
from davinci_sim.study.tick_kernel import (
    P_ACTIVE,
    P_PSM_Q,
    P_REQUESTED,
    P_T_MTM,
    P_T_PSM,
    P_TWIST_MTM,
    P_WRENCH_SENT,
    P_XFRC,
    haptics_row,
    physics_scratch,
    step_row,
    teleop_scratch,
    teleop_solve_row,
    teleop_write_row,
    tracking_row,
)
from davinci_sim.tasks.path_row import path_tick_rows
from davinci_sim.tasks.state import _FINISHED as FINISHED

_hand = _hand_rows.dispatcher

# The trainees' arrays the chunk reads by name (:data:`~davinci_sim.operators.trainee_row.ARGS`
# positions, constants to numba).
A_Y, A_FORCE, A_FEEL = ARGS.index("y"), ARGS.index("force"), ARGS.index("feel")
A_CO_CONTRACTION, A_FEEDFORWARD = ARGS.index("co_contraction"), ARGS.index("feedforward")
A_LAST_TREMOR, A_X_EQ, A_V_EQ = ARGS.index("last_tremor"), ARGS.index("x_eq"), ARGS.index("v_eq")
A_KNOTS, A_DURATIONS = ARGS.index("knots"), ARGS.index("durations")
A_T_FOLLOW = ARGS.index("t_follow")


@numba.njit(cache=True, nogil=True)
def chunk_rows(K, t0, dt, t_end, tp, pp, tr_args, k0, tr_dt, white, stiffness, damping, hand,
               ncon_at, tip, force, master, alive):  # fmt: skip
    """Up to ``K`` ticks of every active row, row after row, from the batch's time ``t0``
    (s; ``dt`` the tick), each row until its trial's end time ``t_end`` (n,) or a tracking
    fault (``active``, ``fault`` in ``pp``).

    ``tp``, ``pp``: the tick's teleoperation and physics arguments
    (:data:`~davinci_sim.study.tick_kernel.TELEOP_ARGS`, ``PHYSICS_ARGS``); ``tr_args``:
    the trainees' (:data:`~davinci_sim.operators.trainee_row.ARGS`, the seen tips and felt
    forces there written here each tick), at step ``k0`` (steps of ``tr_dt`` s), ``white``
    (n, ≥ K, 6) their normals from this chunk's first step;
    ``stiffness``, ``damping`` (n,) the limbs' relaxed values; ``hand``: the hands' targets
    (n, 4, 4), impedance (4,), HRSV in the world (3, 3), (3,), the handle bodies' centres
    (n, 3), and the wrist's turns (:mod:`~davinci_sim.operators.wrist`): the handles'
    orientations when taken (n, 3, 3), the knots (K,) and turns (K, 3), whether the hands
    turn at all, the path's length (m). ``ncon_at`` (n,): the address of each row's contact count.

    Records, per tick j and row: ``tip``, ``force``, ``master`` (K, n, 3) (the PSM tip and
    the MTM handle, camera/HRSV, m; the guidance force, N) and ``alive`` (K, n) (the row
    ran the tick's task). Returns (-1, K) when done, or the row and tick a tick needs Python
    at (the state is then partly advanced: the caller restores it)."""
    (T_hand, impedance, R_world_hrsv, p_world_hrsv, xipos, R_hand0, w_progress, w_turn,
     turning, total) = hand  # fmt: skip
    knots, durations, t_follow = tr_args[A_KNOTS], tr_args[A_DURATIONS], tr_args[A_T_FOLLOW]
    active, T_psm, T_mtm, xfrc = pp[P_ACTIVE], pp[P_T_PSM], pp[P_T_MTM], pp[P_XFRC]
    twist_mtm, requested, wrench_sent = pp[P_TWIST_MTM], pp[P_REQUESTED], pp[P_WRENCH_SENT]
    Y, F, feel, co = tr_args[A_Y], tr_args[A_FORCE], tr_args[A_FEEL], tr_args[A_CO_CONTRACTION]
    ff, tremor = tr_args[A_FEEDFORWARD], tr_args[A_LAST_TREMOR]
    x_eq, v_eq = tr_args[A_X_EQ], tr_args[A_V_EQ]
    tsc = teleop_scratch(pp[P_PSM_Q].shape[0])
    psc = physics_scratch(pp)
    trs = np.empty((6, 3))
    Kh, Dh, w = np.empty(1), np.empty(1), np.empty((1, 6))
    n = active.shape[0]
    for r in range(n):
        for j in range(K):
            alive[j, r] = False
        t = t0
        for j in range(K):
            if not active[r]:
                break
            if teleop_solve_row(r, tp, tsc):  # (nothing written yet)
                return r, j
            # --- the trainee's step (SyntheticTrainee.command), then the hand on the handle
            for i in range(3):
                Y[r, i] = T_psm[r, i, 3]
                if feel:
                    F[r, i] = wrench_sent[r, i]
            k = k0 + j
            command_row(r, k, k * tr_dt, white[r, j], tr_args, trs)
            for i in range(3):
                T_hand[r, i, 3] = x_eq[r, i]
            if turning:  # (SyntheticTrainee.hand_rotations)
                f = plan_fraction_row(knots, durations[r], k * tr_dt - t_follow[r], total)
                hand_rotation_row(w_progress, w_turn, f, R_hand0[r], T_hand[r])
            c = 1.0 + co[r]
            Kh[0], Dh[0] = stiffness[r] * c, damping[r] * c
            _hand(T_hand[r : r + 1], True, True, T_mtm[r : r + 1], twist_mtm[r : r + 1], Kh, Dh,
                  impedance[0], impedance[1], impedance[2], impedance[3], w)  # fmt: skip
            for i in range(3):  # (TrainedHand.push_force: D·ẋ_eq + feed-forward + tremor)
                w[0, i] = w[0, i] + (Dh[0] * v_eq[r, i] + ff[r, i] + tremor[r, i])
            _xfrc_into(w[0], T_mtm[r], R_world_hrsv, p_world_hrsv, xipos[r], xfrc[r])
            # --- the teleoperation's setpoints, then tracking, servo, physics, haptics
            teleop_write_row(r, tp)
            tracking_row(r, t, pp)
            if active[r]:
                step_row(r, pp, psc)
                if i32_at(ncon_at[r])[0] != 0:
                    return r, j
            t = t + dt
            if not active[r]:  # (a tracking fault: the row's trial ends unfinished)
                haptics_row(r, pp, psc)
                break
            haptics_row(r, pp, psc)
            alive[j, r] = True
            for i in range(3):
                tip[j, r, i] = T_psm[r, i, 3]
                force[j, r, i] = requested[r, i]
                master[j, r, i] = T_mtm[r, i, 3]
            if t >= t_end[r] - 1e-9:  # (its time is up: the task ends it at this tick)
                break
    return -1, K


@numba.njit(cache=True, nogil=True)
def task_rows(
    K, t, dt, t_end, T_task_camera, camera, constants, has_prev, state, tip, force, master,
    alive, contacts, tool_force, prev, running, prev_in, ended, counted, sample,
):  # fmt: skip
    """The task on a chunk's K recorded ticks, in order, as ``TrialBatch._task`` and
    :func:`~davinci_sim.tasks.state.advance` run it on each tick's sample: the tip into the
    task's frame (``rotate_rows``, then the translation), whether the left image shows it
    (``in_left_image``; ``camera``: focal length px, half baseline m, width, height), then
    :func:`~davinci_sim.tasks.path_row.path_tick_rows` on the rows the tick ran (``alive``)
    and the task has not ended, the previous sample as ``update_previous`` keeps it, and
    the trials' ends (finished, or their time up).

    ``t``: the batch's time before the chunk, s; ``constants``: the path task's
    (``path_row._constants``); ``has_prev``: whether the metrics have a previous sample
    (else the first sample is its own); ``state``: phase, start, finish, progress, (n,);
    ``prev``, ``running``: the previous sample's fields (time, tip, force, clutch, visible,
    master, contacts, tool force) and the metrics' running arrays, updated in place;
    ``ended``, ``counted`` (n,): the trials this chunk ended, and the ticks each ran;
    ``sample``: scratch for one tick's (time, tip, clutch, visible) (n,), (n, 3), (n,), (n,).
    Returns the batch's time after the K ticks."""
    f, half_baseline, width, height = camera[0], camera[1], camera[2], camera[3]
    phase, t_start, t_finish, progress = state
    p_time, p_tip, p_force, p_clutch, p_visible, p_master, p_contacts, p_tool = prev
    s_time, s_tip, s_clutch, s_visible = sample
    n = phase.shape[0]
    mask = np.empty(n, dtype=np.bool_)
    closest = np.empty((n, 8))
    measured = np.empty(n, dtype=np.bool_)
    R = T_task_camera
    for j in range(K):
        t = t + dt
        for r in range(n):
            mask[r] = alive[j, r] and not ended[r]
            if mask[r]:
                counted[r] += 1
            x, y, z = tip[j, r, 0], tip[j, r, 1], tip[j, r, 2]
            for i in range(3):
                s_tip[r, i] = (x * R[i, 0] + y * R[i, 1]) + z * R[i, 2] + R[i, 3]
            s_time[r] = t
            s_clutch[r] = False
            s_visible[r] = in_left_image_floats(x, y, z, f, half_baseline, width, height)
        first = j == 0 and not has_prev
        if first:  # (no previous sample yet: this one is its own)
            _keep(n, None, s_time, s_tip, force[j], s_clutch, s_visible, master[j], contacts,
                  tool_force, prev)  # fmt: skip
        path_tick_rows(
            *constants, mask, phase, t_start, t_finish, progress, s_time, s_tip, force[j],
            s_clutch, True, contacts, True, tool_force, True, s_visible, True, master[j],
            p_time, p_tip, p_clutch, p_contacts, *running, prev_in, closest, measured,
        )  # fmt: skip
        if not first:  # (update_previous: the measured rows' sample; else kept)
            _keep(n, measured, s_time, s_tip, force[j], s_clutch, s_visible, master[j],
                  contacts, tool_force, prev)  # fmt: skip
        for r in range(n):
            prev_in[r] = measured[r]
            if mask[r] and (phase[r] >= FINISHED or t >= t_end[r] - 1e-9):
                ended[r] = True
    return t


@numba.njit(cache=True, nogil=True)
def _keep(n, rows, time, tip, force, clutch, visible, master, contacts, tool_force, prev):
    """The sample's fields into ``prev``'s, for ``rows`` (n,) (None: every row)."""
    p_time, p_tip, p_force, p_clutch, p_visible, p_master, p_contacts, p_tool = prev
    for r in range(n):
        if rows is None or rows[r]:
            p_time[r], p_clutch[r], p_visible[r] = time[r], clutch[r], visible[r]
            p_contacts[r], p_tool[r] = contacts[r], tool_force[r]
            for i in range(3):
                p_tip[r, i], p_force[r, i], p_master[r, i] = tip[r, i], force[r, i], master[r, i]
