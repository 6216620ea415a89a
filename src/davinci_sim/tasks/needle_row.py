"""The needle kinds' state machine in one compiled call a sample, for n trials.

:meth:`NeedlePickupTask.step <davinci_sim.tasks.needle_pickup.NeedlePickupTask.step>` and
:meth:`NeedleDriveTask.step <davinci_sim.tasks.needle_drive.NeedleDriveTask.step>` run every
tick of a live session (one trial) and of a study's batch (n trials). Written over numpy
arrays, one trial's step was some seventy small array operations, ~80 µs a tick: a fifth of
the live loop's time with a needle exercise served (py-spy, 2026-12-03). Here the same
laws, each trial in a loop (:func:`pickup_rows`, :func:`drive_rows`): the needle's handling
(:func:`~davinci_sim.tasks.handling.handling_rows`, already compiled), the phases, the
delivery or the passage through the skin, the observations. The numpy steps
(``step_arrays`` of both kinds, :func:`~davinci_sim.tasks.suture_pad.passage_step`) stay the
tests' oracle: the same bits (``tests/tasks/test_needle_row.py``).

Arithmetic is written in the numpy steps' order (a 3-vector's norm ``sqrt((x² + y²) + z²)``
as ``np.linalg.norm`` sums it; the needle's point ``R @ p + o`` and the entry point in the
needle's frame ``Rᵀ (p_entry − o)`` summed over the index in order).
"""

from __future__ import annotations

import math

import numpy as np

from davinci_sim.kinematics import jit as jit_module
from davinci_sim.kinematics.jit import helper, jit
from davinci_sim.tasks.handling import handling_rows

_handling = handling_rows.dispatcher  # (the compiled kernel itself, callable from here)

#: The phases (:class:`~davinci_sim.tasks.state.Phase`'s values).
_IDLE, _READY, _RUNNING, _FINISHED, _RESULTS = 0, 1, 2, 3, 4


@helper
def _norm3(x: float, y: float, z: float) -> float:
    return math.sqrt((x * x + y * y) + z * z)


@helper
def _handle(start, park_tolerance, instruments, rest_speed, rest_time, t_still, owner, carried,
            handed, loose, p_prev, t_prev, t, objects, grasp, new_still, new_owner, new_carried,
            new_handed, new_loose):  # fmt: skip
    """The needle's handling of every trial (``NeedlePickupTask._handle``): its state into
    the ``new_*`` arrays; returns the events the steps read and whether the needle is in
    its park, (n,) each: (held, alone, who, resting, handoff, drop, parked)."""
    n = len(t)
    flags = np.empty((8, n), dtype=np.bool_)
    held, alone, resting, handoff = flags[0], flags[1], flags[2], flags[3]
    land, handed_now, drop, parked = flags[4], flags[5], flags[6], flags[7]
    who = np.empty(n, dtype=np.int64)
    for i in range(n):
        parked[i] = _norm3(objects[i, 0] - start[0], objects[i, 1] - start[1],
                           objects[i, 2] - start[2]) <= park_tolerance  # fmt: skip
    k1 = (n, 1)
    _handling(t_still.reshape(k1), owner.reshape(k1), carried.reshape(k1), handed.reshape(k1),
              loose.reshape(k1), grasp.reshape(k1), objects.reshape((n, 1, 3)),
              p_prev.reshape((n, 1, 3)), t, t_prev, parked.reshape(k1), instruments, rest_speed,
              rest_time, new_still.reshape(k1), new_owner.reshape(k1), new_carried.reshape(k1),
              new_handed.reshape(k1), new_loose.reshape(k1), held.reshape(k1),
              alone.reshape(k1), who.reshape(k1), resting.reshape(k1), handoff.reshape(k1),
              land.reshape(k1), handed_now.reshape(k1), drop.reshape(k1))  # fmt: skip
    return held, alone, who, resting, handoff, drop, parked


@helper
def _start(phase: int, resting: bool, parked: bool, held: bool, t: float, t_start: float,
           time_limit: float) -> tuple:  # fmt: skip
    """One trial's ``NeedlePickupTask._start``: (phase, t_start, running, timed out)."""
    new = phase
    if phase == _IDLE and resting and parked:
        new = _READY
    begin = phase == _READY and held
    if begin:
        new = _RUNNING
    t0 = t if begin else t_start
    timeout = time_limit > 0 and t - t0 >= time_limit
    return new, t0, phase == _RUNNING or begin, timeout


@helper
def _finish(i, ph, t0, finish, phase, t_finish, t, objects, tip, new_phase, new_start,
            new_finish, distance) -> None:  # fmt: skip
    """Trial ``i``'s phase after :func:`_start`'s ``ph``: FINISHED where it ``finish``-es,
    RESULTS after FINISHED (``NeedlePickupTask._finish``); its start and finish times and the
    tip's distance to the needle's centre (m)."""
    if finish:
        ph = _FINISHED
    if phase[i] == _FINISHED:
        ph = _RESULTS
    new_phase[i], new_start[i] = ph, t0
    new_finish[i] = t[i] if finish else t_finish[i]
    distance[i] = _norm3(objects[i, 0] - tip[i, 0], objects[i, 1] - tip[i, 1],
                         objects[i, 2] - tip[i, 2])  # fmt: skip


@jit
def pickup_rows(start, park_tolerance, lift_height, hold_time, time_limit, instruments,
                rest_speed, rest_time, phase, t_start, t_finish, t_prev, p_prev, t_still, owner,
                carried, handed, loose, t_held, t, objects, grasp, tip, new_phase, new_start,
                new_finish, new_still, new_owner, new_carried, new_handed, new_loose, new_held,
                distance, handoffs, dropped, missed, held_by):  # fmt: skip
    """``NeedlePickupTask.step`` of n trials: the state ((n,) arrays, ``p_prev`` (n, 3)), the
    sample's time (n,) s, needle centre ``objects`` (n, 3) m, jaw bits ``grasp`` (n,) and
    ``tip`` (n, 3) m into the ``new_*`` state and the observations ((n,) each). The new
    state's ``t_prev`` and ``p_prev`` are the sample's time and ``objects``."""
    n = len(t)
    held, alone, who, resting, handoff, drop, parked = _handle(
        start, park_tolerance, instruments, rest_speed, rest_time, t_still, owner, carried,
        handed, loose, p_prev, t_prev, t, objects, grasp, new_still, new_owner, new_carried,
        new_handed, new_loose)  # fmt: skip
    lift = start[2] + lift_height
    for i in range(n):
        ti = t[i]
        holding = new_handed[i] and alone[i] and objects[i, 2] >= lift
        th = np.nan
        if holding:
            th = ti if np.isnan(t_held[i]) else t_held[i]
        delivered = holding and ti - th >= hold_time
        ph, t0, running, timeout = _start(phase[i], resting[i], parked[i], held[i], ti,
                                          t_start[i], time_limit)  # fmt: skip
        finish = running and (delivered or timeout)
        _finish(i, ph, t0, finish, phase, t_finish, t, objects, tip, new_phase, new_start,
                new_finish, distance)  # fmt: skip
        new_held[i] = th
        handoffs[i], dropped[i] = handoff[i], drop[i]
        missed[i] = finish and not delivered
        held_by[i] = (who[i] if alone[i] else 3) if held[i] else 0


@helper
def _passage(T, tip_point, marks, half_x, half_y, mark_radius, radius, inside, pair, p_entry,
             entry_error, trauma, p_tip, i, out):  # fmt: skip
    """One trial's :func:`~davinci_sim.tasks.suture_pad.passage_step` (row ``i`` of the
    passage's arrays, updated in place: the new passage); its events into ``out``
    (entered, exited, withdrawn, passed, pair, entry error, exit error, trauma; booleans as
    0 and 1)."""
    tip = np.empty(3)
    for j in range(3):
        tip[j] = (T[j, 0] * tip_point[0] + T[j, 1] * tip_point[1] + T[j, 2] * tip_point[2]
                  ) + T[j, 3]  # fmt: skip
    was_inside = inside[i]
    prev_z = p_tip[i, 2]
    on_pad = abs(tip[0]) <= half_x and abs(tip[1]) <= half_y
    known = not np.isnan(prev_z)
    down = known and prev_z >= 0 and tip[2] < 0 and on_pad and not was_inside
    up = known and prev_z < 0 and tip[2] >= 0 and was_inside
    den = prev_z - tip[2]
    w = prev_z / den if den != 0.0 else 0.0  # (numpy's ±inf or nan there: taken as 0)
    if not np.isfinite(w):
        w = 0.0
    cross = np.empty(3)
    for j in range(2):
        cross[j] = p_tip[i, j] + w * (tip[j] - p_tip[i, j])
    cross[2] = 0.0
    if down:
        best, d_best = 0, np.nan
        for k in range(marks.shape[0]):
            dx, dy = cross[0] - marks[k, 0, 0], cross[1] - marks[k, 0, 1]
            d = math.sqrt(dx * dx + dy * dy)
            if k == 0 or d < d_best:
                best, d_best = k, d
        inside[i], pair[i], entry_error[i], trauma[i] = True, best, d_best, 0.0
        for j in range(3):
            p_entry[i, j] = cross[j]
    if inside[i]:
        e = np.empty(3)
        for j in range(3):
            e[j] = (T[0, j] * (p_entry[i, 0] - T[0, 3]) + T[1, j] * (p_entry[i, 1] - T[1, 3])
                    ) + T[2, j] * (p_entry[i, 2] - T[2, 3])  # fmt: skip
        dev = math.hypot(math.hypot(e[0], e[1]) - radius, e[2])
        if np.isnan(trauma[i]) or dev > trauma[i]:  # (np.fmax: a nan gives the other)
            trauma[i] = dev
    back = up and _norm3(cross[0] - p_entry[i, 0], cross[1] - p_entry[i, 1],
                         cross[2] - p_entry[i, 2]) <= mark_radius  # fmt: skip
    exited = up and not back
    exit_error = np.nan
    if exited:
        k = min(max(pair[i], 0), marks.shape[0] - 1)
        dx, dy = cross[0] - marks[k, 1, 0], cross[1] - marks[k, 1, 1]
        exit_error = math.sqrt(dx * dx + dy * dy)
    passed = exited and entry_error[i] <= mark_radius and exit_error <= mark_radius
    out[0], out[1], out[2], out[3] = down, exited, back, passed
    out[4] = pair[i] if exited else -1
    out[5] = entry_error[i] if down or exited else np.nan
    out[6] = exit_error
    out[7] = trauma[i] if exited else np.nan
    if up:
        inside[i], pair[i], entry_error[i], trauma[i] = False, -1, np.nan, np.nan
        for j in range(3):
            p_entry[i, j] = np.nan
    for j in range(3):
        p_tip[i, j] = tip[j]


@jit
def drive_rows(start, park_tolerance, time_limit, instruments, rest_speed, rest_time, pairs,
               T_pad_needle, tip_point, marks, half_x, half_y, mark_radius, radius, phase,
               t_start, t_finish, t_prev, p_prev, t_still, owner, carried, handed, loose,
               next_pair, t, objects, grasp, tip, new_phase, new_start, new_finish, new_still,
               new_owner, new_carried, new_handed, new_loose, new_pair, inside, pair, p_entry,
               entry_error, trauma, p_tip, distance, handoffs, dropped, passes, entry_obs,
               exit_obs, trauma_obs, missed):  # fmt: skip
    """``NeedleDriveTask.step`` of n trials: :func:`pickup_rows`' inputs and outputs but the
    delivery's, the pairs passed so far ``next_pair`` (n,) into ``new_pair``, the needle's
    frames in the pad's frame ``T_pad_needle`` (n, 4, 4), its point in its own frame
    ``tip_point`` (3,), the pad's ``marks`` (P, 2, 3), its half extent and mark radius (m),
    the needle's radius (m); the passage's arrays (``inside`` … ``p_tip``, copies of the
    state's) updated in place; the observations."""
    n = len(t)
    held, alone, who, resting, handoff, drop, parked = _handle(
        start, park_tolerance, instruments, rest_speed, rest_time, t_still, owner, carried,
        handed, loose, p_prev, t_prev, t, objects, grasp, new_still, new_owner, new_carried,
        new_handed, new_loose)  # fmt: skip
    ev = np.empty(8)
    for i in range(n):
        ti = t[i]
        _passage(T_pad_needle[i], tip_point, marks, half_x, half_y, mark_radius, radius,
                 inside, pair, p_entry, entry_error, trauma, p_tip, i, ev)  # fmt: skip
        ph, t0, running, timeout = _start(phase[i], resting[i], parked[i], held[i], ti,
                                          t_start[i], time_limit)  # fmt: skip
        scored = running and ev[3] != 0 and int(ev[4]) == next_pair[i]
        k = next_pair[i] + (1 if scored else 0)
        finish = running and (k >= pairs or timeout)
        _finish(i, ph, t0, finish, phase, t_finish, t, objects, tip, new_phase, new_start,
                new_finish, distance)  # fmt: skip
        new_pair[i] = k
        handoffs[i], dropped[i], passes[i] = handoff[i], drop[i], scored
        entry_obs[i] = ev[5] if running and ev[0] != 0 else 0.0
        exit_obs[i] = ev[6] if running and ev[1] != 0 else 0.0
        trauma_obs[i] = ev[7] if running and ev[1] != 0 else 0.0
        missed[i] = pairs - k if finish else 0


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the tasks' one signature each."""
    f, i8, b = (lambda k=1: np.zeros(k)), np.zeros(1, dtype=np.int8), np.zeros(1, dtype=bool)
    i64 = np.zeros(1, dtype=np.int64)
    v = np.zeros((1, 3))
    common = (0.003, 0.1, 2, 0.001, 0.3)  # (park tolerance, time limit, instruments, rests)
    handling = (f(), i64.copy(), b.copy(), b.copy(), b.copy())
    new_handling = (f(), i64.copy(), b.copy(), b.copy(), b.copy())
    pickup_rows(f(3), common[0], 0.01, 0.5, common[1], common[2], common[3], common[4],
                i8.copy(), f(), f(), f(), v.copy(), *handling, f(), f(), v.copy(), i64.copy(),
                v.copy(), i8.copy(), f(), f(), *new_handling, f(), f(), i64.copy(), i64.copy(),
                i64.copy(), i64.copy())  # fmt: skip
    drive_rows(f(3), *common, 1, np.eye(4).reshape(1, 4, 4), f(3), np.zeros((1, 2, 3)), 0.01,
               0.01, 0.0025, 0.01, i8.copy(), f(), f(), f(), v.copy(), *handling, i64.copy(),
               f(), v.copy(), i64.copy(), v.copy(), i8.copy(), f(), f(), *new_handling,
               i64.copy(), b.copy(), i64.copy(), v.copy(), f(), f(), v.copy(), f(), i64.copy(),
               i64.copy(), i64.copy(), f(), f(), f(), i64.copy())  # fmt: skip


jit_module.warm(_warm_up)
