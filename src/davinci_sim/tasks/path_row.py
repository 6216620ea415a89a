"""The path kind's tick in one compiled call: a sample of every trial through the task's
state machine and metrics (the live session's one trial, the single environment's, the
study batch's trials).

Each tick, :func:`~davinci_sim.tasks.state.advance` runs a task's state machine on the
sample and adds it to the metrics. For :class:`~davinci_sim.tasks.task.PathTask` (``seed_path``
and every path task file) scoring :data:`~davinci_sim.tasks.metrics_one.PATH_KIND_METRICS`
that is, per trial, the tip's closest point on the path
(:func:`~davinci_sim.haptics.path_query.closest_point_row`'s body), its distances to point
1 and the last point, the state machine (:func:`~davinci_sim.tasks.state.phase_step`) and
the metrics' reductions (:func:`~davinci_sim.tasks.metrics_one.path_update`): a few dozen
numpy and Python calls a tick. :func:`advance_rows` runs them as one compiled call of those
same laws, row by row, so the same bits (``tests/tasks/test_path_row.py``), and leaves the
Python objects (the state, the observations, the accumulator and its previous sample) as
the Python path leaves them. Anything else — another kind or declaration, a path too long
for the brute force, no numba — returns None and takes the Python path, the oracle.
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.geometry.floats import norm3
from davinci_sim.haptics.path_query import (
    BRUTE_FORCE_MAX_SEGMENTS,
    _closest_point_into,
    brute_force_constants,
)
from davinci_sim.kinematics import jit
from davinci_sim.model.cameras import in_left_image_floats
from davinci_sim.tasks.metrics_one import (
    mark_missing,
    path_update,
    previous_of,
    running,
    targets,
    update_previous,
)
from davinci_sim.tasks.state import _FINISHED, _RUNNING, TaskState, phase_step
from davinci_sim.tasks.trainer import force_threshold

jit.helper(norm3)


@numba.njit(cache=True, nogil=True)
def path_tick_rows(
    centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, start, finish, start_tol,
    finish_tol, min_arc, tube_radius, force_limit, marks, active, phase, t_start, t_finish,
    progress, time, tip, force, clutch, has_contacts, contacts, has_tool_force, tool_force,
    has_visible, visible, has_master, master, prev_time, prev_tip, prev_clutch, prev_contacts,
    deviation, squares, farthest, t_first, t_last, length, peak, force_sum, outside, presses,
    collisions, excessive, unseen, low, high, reached, count, prev_in, closest, measured,
):  # fmt: skip
    """One sample of n path trials.

    The path's constants (``closest_point_row``'s, point 1 ``start`` and the last point
    ``finish`` (3,) m, their tolerances, the progress a finish needs ``min_arc`` m, the
    tube radius m, the force limit N and the target marks (k, 3)); ``active`` (n,) the
    trials going on (the others keep their state and are not measured); the trials' state
    (``phase``, ``t_start``, ``t_finish``, ``progress``, (n,), updated in place); the sample
    (``time`` (n,) s, ``tip`` and ``force`` (n, 3) m and N, ``clutch`` (n,), the optional
    fields with whether it has them, ``master`` (n, 3)); the previous sample's time, tip,
    clutch and contacts; the metrics' running arrays
    (:func:`~davinci_sim.tasks.metrics_one.path_update`'s, (n,) rows, updated in place).

    ``closest`` (n, 8) receives each tip's closest point (point, deviation, distance, arc
    length: ``closest_point_row``'s row); ``measured`` (n,) whether the metrics took the
    trial's sample."""
    for r in range(tip.shape[0]):
        x, y, z = tip[r, 0], tip[r, 1], tip[r, 2]
        _closest_point_into(tip[r], centre, basis, AE, AA, EE, starts, edges, cumulative,
                            lengths, closest[r])  # fmt: skip
        measured[r] = False
        if not active[r]:
            continue
        at_start = norm3(x - start[0], y - start[1], z - start[2]) <= start_tol
        at_finish = norm3(x - finish[0], y - finish[1], z - finish[2]) <= finish_tol
        new, begin, done, progressed = phase_step(phase[r], progress[r], at_start, at_finish,
                                                  closest[r, 7], min_arc)  # fmt: skip
        phase[r] = new
        if begin:
            t_start[r] = time[r]
            progress[r] = closest[r, 7]
        else:
            progress[r] = progressed
        if done:
            t_finish[r] = time[r]
        m = new == _RUNNING or new == _FINISHED
        measured[r] = m
        q = r + 1
        path_update(
            deviation[r:q], squares[r:q], farthest[r:q], t_first[r:q], t_last[r:q], length[r:q],
            peak[r:q], force_sum[r:q], outside[r:q], presses[r:q], collisions[r:q], excessive[r:q],
            unseen[r:q], low[r:q], high[r:q], reached[r:q], count[r:q], m, prev_in[r],
            time[r], x, y, z, prev_time[r], prev_tip[r, 0], prev_tip[r, 1], prev_tip[r, 2],
            clutch[r], prev_clutch[r], has_contacts, contacts[r], prev_contacts[r],
            has_tool_force, tool_force[r], has_visible, visible[r], has_master, master[r],
            force[r, 0], force[r, 1], force[r, 2], closest[r, 6], tube_radius, force_limit,
            marks,
        )  # fmt: skip


@numba.njit(cache=True, nogil=True)
def live_path_row(
    centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, start, finish, start_tol,
    finish_tol, min_arc, tube_radius, force_limit, marks, active, T_task_tip, p_camera, f_px,
    half_baseline, width, height, has_force, force_in, has_master, master_in, t, clutch,
    contacts, tool_force, phase, t_start, t_finish, progress, s_time, s_tip, s_force,
    s_clutch, s_visible, s_master, s_contacts, s_tool_force, prev_time, prev_tip, prev_clutch,
    prev_contacts, deviation, squares, farthest, t_first, t_last, length, peak, force_sum,
    outside, presses, collisions, excessive, unseen, low, high, reached, count, prev_in, closest,
    measured,
):  # fmt: skip
    """The live session's sample of its one path trial, then :func:`path_tick_rows` on it.

    The sample (written into the ``s_*`` (1,)-row arrays, as
    :func:`~davinci_sim.tasks.session.live_sample` builds it): the time ``t`` (s), the tip
    ``T_task_tip[:3, 3]`` (m, task frame), the guidance force ``force_in[:3]`` (N; 0 without
    one), the clutch, whether the tip ``p_camera[:3, 3]`` (m, camera frame) is in the left
    endoscope image (:func:`~davinci_sim.model.cameras.project_left`'s pinhole: focal length
    ``f_px`` px, the left camera ``half_baseline`` m towards +x, a ``width`` x ``height``
    image), the master's position ``master_in`` (m, HRSV; ``has_master``), the instrument's
    contacts and their force (N). The previous sample's arrays may be the ``s_*`` ones (the
    first sample is its own previous one). The rest: :func:`path_tick_rows`' arguments."""
    s_time[0] = t
    s_clutch[0] = clutch
    s_contacts[0] = contacts
    s_tool_force[0] = tool_force
    for i in range(3):
        s_tip[0, i] = T_task_tip[i, 3]
        s_force[0, i] = force_in[i] if has_force else 0.0
        s_master[0, i] = master_in[i] if has_master else 0.0
    s_visible[0] = in_left_image_floats(
        p_camera[0, 3], p_camera[1, 3], p_camera[2, 3], f_px, half_baseline, width, height
    )
    path_tick_rows(
        centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, start, finish,
        start_tol, finish_tol, min_arc, tube_radius, force_limit, marks, active, phase, t_start,
        t_finish, progress, s_time, s_tip, s_force, s_clutch, True, s_contacts, True,
        s_tool_force, True, s_visible, has_master, s_master, prev_time, prev_tip, prev_clutch,
        prev_contacts, deviation, squares, farthest, t_first, t_last, length, peak, force_sum,
        outside, presses, collisions, excessive, unseen, low, high, reached, count, prev_in,
        closest, measured,
    )  # fmt: skip


@numba.njit(cache=True, nogil=True)
def live_path_rows(
    centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, start, finish, start_tol,
    finish_tol, min_arc, tube_radius, force_limit, marks, active, T_task_tip, p_camera, f_px,
    half_baseline, width, height, has_force, force, has_master, master, t, contacts,
    tool_force, stop, phase, t_start, t_finish, progress, s_time, s_tip, s_force, s_clutch,
    s_visible, s_master, s_contacts, s_tool_force, prev_time, prev_tip, prev_clutch,
    prev_contacts, deviation, squares, farthest, t_first, t_last, length, peak, force_sum,
    outside, presses, collisions, excessive, unseen, low, high, reached, count, prev_in, closest,
    measured, done,
):  # fmt: skip
    """m samples of one path trial in turn, each :func:`live_path_row` with no clutch: row j
    of ``T_task_tip``, ``p_camera`` (m, 4, 4), ``t``, ``contacts``, ``tool_force`` (m,), of
    the guidance force ``force`` and the master's position ``master`` (m, 3; zeros without
    ``has_force``, ``has_master``) and of the ``s_*`` (m, ...) sample arrays it fills. The
    previous sample (``prev_*``, (1,)-row arrays) and ``prev_in`` (1,) become each measured
    sample's, as the metrics' previous sample does; ``closest`` and ``measured`` (1, 8),
    (1,) are the last sample's. With ``stop``, the samples end after one that changes the
    trial's phase. ``done[0]``: the samples taken. Returns the last measured sample's row
    (−1: none)."""
    last = -1
    done[0] = 0
    for j in range(t.shape[0]):
        q = j + 1
        before = phase[0]
        live_path_row(
            centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, start, finish,
            start_tol, finish_tol, min_arc, tube_radius, force_limit, marks, active,
            T_task_tip[j], p_camera[j], f_px, half_baseline, width, height, has_force, force[j],
            has_master, master[j], t[j], False, contacts[j], tool_force[j], phase, t_start,
            t_finish, progress, s_time[j:q], s_tip[j:q], s_force[j:q], s_clutch[j:q],
            s_visible[j:q], s_master[j:q], s_contacts[j:q], s_tool_force[j:q], prev_time,
            prev_tip, prev_clutch, prev_contacts, deviation, squares, farthest, t_first, t_last,
            length, peak, force_sum, outside, presses, collisions, excessive, unseen, low, high,
            reached, count, prev_in, closest, measured,
        )  # fmt: skip
        prev_in[0] = measured[0]
        if measured[0]:  # (the metrics' previous sample: this one)
            last = j
            prev_time[0] = s_time[j]
            prev_clutch[0] = s_clutch[j]
            prev_contacts[0] = s_contacts[j]
            for i in range(3):
                prev_tip[0, i] = s_tip[j, i]
        done[0] = q
        if stop and phase[0] != before:
            break
    return last


def _constants(task) -> tuple | None:
    """``task``'s constants of :func:`path_tick_rows` (cached on it: a task is a value), or
    None where the brute force does not serve its path."""
    cached = task.__dict__.get("_tick_row_constants", False)
    if cached is False:
        path = task.path
        cached = None
        if len(path.segment_lengths) <= BRUTE_FORCE_MAX_SEGMENTS:
            cached = (
                path.centre, *brute_force_constants(path), path.starts, path.edges,
                path.cumulative_length, path.segment_lengths,
                np.array(task.start, dtype=float), np.array(task.finish, dtype=float),
                float(task.start_tolerance), float(task.finish_tolerance),
                path.length * task.min_progress, float(task.tube_radius),
                force_threshold(task), targets(task),
            )  # fmt: skip
        object.__setattr__(task, "_tick_row_constants", cached)  # (cached_property's way)
    return cached


def next_state(state: TaskState) -> TaskState:
    """New arrays of ``state`` for a kernel to update in place (floats where the state may
    hold the integers of a fresh one), as the Python step returns a new state."""
    return TaskState(state.phase.copy(), state.t_start.astype(float),
                     state.t_finish.astype(float), state.progress.astype(float))  # fmt: skip


def _c(a, dtype, missing=None) -> np.ndarray:
    """``a`` as a writable C-ordered array of ``dtype`` (a copy only where it is not one): the
    kernel's one signature, whatever views the sample holds; for an optional field the
    sample lacks (``a`` None), zeros of shape ``missing`` (the kernel ignores them)."""
    if a is None:
        return np.zeros(missing, dtype=dtype)
    return jit.kernel_array(a, dtype)


def advance_rows(task, state: TaskState, metrics, sample, active=None) -> tuple | None:
    """:func:`~davinci_sim.tasks.state.advance` of the trials of a
    :class:`~davinci_sim.tasks.task.PathTask` by :func:`path_tick_rows`: ``(new state,
    observations)``, with ``metrics`` updated as the reducers update it; None (nothing
    changed) where the compiled tick does not apply."""
    from davinci_sim.tasks.task import PathTask

    if not COMPILED or type(task) is not PathTask or not metrics.floats:  # (the declaration)
        return None
    n = metrics.n
    if state.phase.shape != (n,) or sample.tip.shape != (n, 3):
        return None
    prev = previous_of(metrics, sample)
    constants = _constants(task)
    if prev is None or constants is None:
        return None
    contacts, tool_force = sample.contacts, sample.tool_force
    visible, master = sample.visible, sample.master
    new = next_state(state)
    closest, measured = np.empty((n, 8)), np.empty(n, dtype=bool)
    args = (
        *constants, np.ones(n, dtype=bool) if active is None else _c(active, bool), *new,
        _c(sample.time, float), _c(sample.tip, float), _c(sample.force, float),
        _c(sample.clutch, bool), contacts is not None, _c(contacts, np.int64, n),
        tool_force is not None, _c(tool_force, float, n), visible is not None,
        _c(visible, bool, n), master is not None, _c(master, float, (n, 3)),
        _c(prev.time, float), _c(prev.tip, float), _c(prev.clutch, bool),
        _c(prev.contacts, np.int64, n), *running(metrics), metrics._prev_in.copy(), closest,
        measured,
    )  # fmt: skip
    path_tick_rows(*args)
    mark_missing(metrics, sample)
    update_previous(metrics, measured, sample)
    return new, {"distance": closest[:, 6], "arc_length": closest[:, 7]}


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the callers' one signature."""
    from davinci_sim.tasks import load_task
    from davinci_sim.tasks.base import Sample
    from davinci_sim.tasks.state import TaskMonitor

    task = load_task("seed_path")
    monitor = TaskMonitor(task)
    sample = Sample.of(0.0, task.start, np.zeros(3), False, visible=True, master=np.zeros(3),
                       contacts=0, tool_force=0.0)  # fmt: skip
    advance_rows(task, monitor.state, monitor.metrics, sample)
    batch = TaskMonitor(task, 2)
    two = Sample.of(0.0, np.zeros((2, 3)), master=np.zeros((2, 3)), visible=True, contacts=0,
                    tool_force=0.0)  # fmt: skip
    advance_rows(task, batch.state, batch.metrics, two, np.ones(2, dtype=bool))


COMPILED = jit.ENABLED
if COMPILED and not jit.warmed_up(_warm_up, "the path task's compiled tick: Python runs"):
    COMPILED = False
