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
from davinci_sim.operators.trainee_row import command_row
from davinci_sim.sim.rows_kernel import i32_at
from davinci_sim.study.tick_kernel import (
    haptics_row,
    physics_scratch,
    step_row,
    teleop_scratch,
    teleop_solve_row,
    teleop_write_row,
    tracking_row,
)

_hand = _hand_rows.dispatcher


@numba.njit(cache=True, nogil=True)
def chunk_rows(K, t0, dt, t_end, tp, pp, tr_args, k0, tr_dt, white, stiffness, damping, hand,
               ncon_at, tip, force, master, alive):  # fmt: skip
    """Up to ``K`` ticks of every active row, row after row, from the batch's time ``t0``
    (s; ``dt`` the tick), each row until its trial's end time ``t_end`` (n,) or a tracking
    fault (``active``, ``fault`` in ``pp``).

    ``tp``, ``pp``: the tick's teleoperation and physics arguments
    (:func:`~davinci_sim.study.tick_kernel.teleop_rows`' and ``physics_rows``' after its
    time); ``tr_args``: the trainees' (:data:`~davinci_sim.operators.trainee_row.ARGS`, the
    seen tips and felt forces there written here each tick), at step ``k0`` (steps of
    ``tr_dt`` s), ``white`` (n, ≥ K, 6) their normals from this chunk's first step;
    ``stiffness``, ``damping`` (n,) the limbs' relaxed values; ``hand``: the hands' targets
    (n, 4, 4), impedance (4,), HRSV in the world (3, 3), (3,) and the handle bodies' centres
    (n, 3). ``ncon_at`` (n,): the address of each row's contact count.

    Records, per tick j and row: ``tip``, ``force``, ``master`` (K, n, 3) (the PSM tip and
    the MTM handle, camera/HRSV, m; the guidance force, N) and ``alive`` (K, n) (the row
    ran the tick's task). Returns (-1, K) when done, or the row and tick a tick needs Python
    at (the state is then partly advanced: the caller restores it)."""
    (T_hand, impedance, R_world_hrsv, p_world_hrsv, xipos) = hand
    active = pp[4]
    T_psm, T_mtm, twist_mtm, requested, wrench_sent, xfrc = (
        pp[32],
        pp[41],
        pp[43],
        pp[63],
        pp[64],
        pp[26],
    )
    Y, F, co, v_eq, ff, tremor, x_eq = (tr_args[10], tr_args[11], tr_args[14], tr_args[41],
                                        tr_args[25], tr_args[39], tr_args[40])  # fmt: skip
    feel = tr_args[12]
    tsc = teleop_scratch(pp[8].shape[0])
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
