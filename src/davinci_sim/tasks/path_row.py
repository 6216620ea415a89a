"""One sample of one trial of the path kind in one compiled call: the task's tick of the
live session and of the single learning environment.

Each tick, :func:`~davinci_sim.tasks.state.advance` runs a task's state machine on the
sample and adds it to the metrics. For one trial of :class:`~davinci_sim.tasks.task.PathTask`
(``seed_path`` and every path task file) that is the tip's closest point on the path
(:func:`~davinci_sim.haptics.path_query.closest_point_row`'s body), its distances to point
1 and the last point, the state machine (:func:`~davinci_sim.tasks.state.phase_step`) and
the metrics' reductions (:func:`~davinci_sim.tasks.metrics_one.path_update`): a few dozen
numpy and Python calls. :func:`advance_one` runs them as one compiled call of those same
laws, so the same bits (``tests/tasks/test_path_row.py``), and leaves the Python objects
(the state, the observations, the accumulator and its previous sample) as the Python path
leaves them. Anything else — another kind, a batch, a path too long for the brute force,
no numba — returns None and takes the Python path, which stays the oracle.
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
from davinci_sim.tasks.metrics_one import keep_previous, mark_missing, path_update, targets
from davinci_sim.tasks.state import _FINISHED, _RUNNING, TaskState, phase_step
from davinci_sim.tasks.trainer import force_threshold

jit.helper(norm3)


@numba.njit(cache=True, nogil=True)
def path_tick_row(
    centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, start, finish, start_tol,
    finish_tol, min_arc, tube_radius, force_limit, marks, phase, progress, t, x, y, z, fx, fy,
    fz, clutch, has_contacts, contacts, has_tool_force, tool_force, has_visible, visible,
    has_master, mx, my, mz, prev_t, px, py, pz, prev_clutch, prev_contacts, deviation,
    t_first, t_last, length, peak, force_sum, outside, presses, collisions, excessive, unseen,
    low, high, reached, count, prev_in, closest,
):  # fmt: skip
    """One sample of one path trial: the path's constants (``closest_point_row``'s, point 1
    ``start`` and the last point ``finish`` (3,) m, their tolerances, the progress a finish
    needs ``min_arc`` m, the tube radius m, the force limit N and the target marks (k, 3)),
    the trial's ``phase`` and ``progress`` (m), the sample (time s, tip ``x, y, z`` m, force
    N, the optional fields with whether it has them, the master's position m), the previous
    sample's time, tip, clutch and contacts, and the metrics' running arrays
    (:func:`~davinci_sim.tasks.metrics_one.path_update`'s, updated in place).

    ``closest`` (8,) receives the closest point's row (point, deviation, distance, arc
    length: ``closest_point_row``'s). Returns ``(new phase, begins, finishes, progress,
    measured)``: :func:`~davinci_sim.tasks.state.phase_step`'s and whether the metrics
    took the sample."""
    p = np.empty(3)
    p[0], p[1], p[2] = x, y, z
    _closest_point_into(p, centre, basis, AE, AA, EE, starts, edges, cumulative, lengths,
                        closest)  # fmt: skip
    at_start = norm3(x - start[0], y - start[1], z - start[2]) <= start_tol
    at_finish = norm3(x - finish[0], y - finish[1], z - finish[2]) <= finish_tol
    new, begin, done, progress = phase_step(phase, progress, at_start, at_finish, closest[7],
                                            min_arc)  # fmt: skip
    m = new == _RUNNING or new == _FINISHED
    path_update(
        deviation, t_first, t_last, length, peak, force_sum, outside, presses, collisions,
        excessive, unseen, low, high, reached, count, m, prev_in, t, x, y, z, prev_t, px, py,
        pz, clutch, prev_clutch, has_contacts, contacts, prev_contacts, has_tool_force,
        tool_force, has_visible, visible, has_master, (mx, my, mz), fx, fy, fz, closest[6],
        tube_radius, force_limit, marks,
    )  # fmt: skip
    return new, begin, done, progress, m


def _constants(task) -> tuple | None:
    """``task``'s constants of :func:`path_tick_row` (cached on it: a task is a value), or
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


def advance_one(task, state: TaskState, metrics, sample) -> tuple | None:
    """:func:`~davinci_sim.tasks.state.advance` of one trial of a
    :class:`~davinci_sim.tasks.task.PathTask` by :func:`path_tick_row`: ``(new state,
    observations)``, with ``metrics`` updated as its float path updates it; None (nothing
    changed) where the compiled tick does not apply."""
    from davinci_sim.tasks.task import PathTask

    if not COMPILED or type(task) is not PathTask or not metrics.floats or metrics.n != 1:
        return None
    if state.phase.shape != (1,) or sample.tip.shape != (1, 3):
        return None
    prev = sample if metrics._prev is None else metrics._prev
    if (sample.contacts is None) != (prev.contacts is None):
        return None  # (the float path's own rule: the reducers then)
    constants = _constants(task)
    if constants is None:
        return None
    a = metrics._acc
    contacts, tool_force = sample.contacts, sample.tool_force
    visible, master = sample.visible, sample.master
    t = float(sample.time[0])
    closest = np.empty(8)
    # (the rows as floats: the kernel's one signature, whatever views the sample holds)
    tip, force, p_prev = sample.tip[0].tolist(), sample.force[0].tolist(), prev.tip[0].tolist()
    p_master = (0.0, 0.0, 0.0) if master is None else master[0].tolist()
    args = (
        *constants, int(state.phase[0]), float(state.progress[0]), t, *tip, *force,
        bool(sample.clutch[0]), contacts is not None, 0 if contacts is None else int(contacts[0]),
        tool_force is not None, 0.0 if tool_force is None else float(tool_force[0]),
        visible is not None, visible is not None and bool(visible[0]), master is not None,
        *p_master, float(prev.time[0]), *p_prev, bool(prev.clutch[0]),
        0 if contacts is None else int(prev.contacts[0]), a[0],
        a[1][0], a[1][1], a[2], a[4], a[5], a[6], a[7], a[9], a[10], a[11], a[12][0],
        a[12][1], a[14], metrics._k, bool(metrics._prev_in[0]), closest,
    )  # fmt: skip
    new, begin, done, progress, m = path_tick_row(*args)
    new_state = TaskState(
        np.array([new], dtype=state.phase.dtype),
        np.array([t]) if begin else state.t_start.astype(float),
        np.array([t]) if done else state.t_finish.astype(float),
        np.array([closest[7] if begin else progress], dtype=float),
    )
    mark_missing(metrics, sample)
    keep_previous(metrics, np.array([m]), sample, bool(m))
    return new_state, {"distance": closest[6:7], "arc_length": closest[7:8]}


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the live session's signature."""
    from davinci_sim.tasks import load_task
    from davinci_sim.tasks.base import Sample
    from davinci_sim.tasks.state import TaskMonitor

    task = load_task("seed_path")
    monitor = TaskMonitor(task)
    sample = Sample.of(0.0, task.start, np.zeros(3), False, visible=True, master=np.zeros(3),
                       contacts=0, tool_force=0.0)  # fmt: skip
    advance_one(task, monitor.state, monitor.metrics, sample)


COMPILED = jit.ENABLED
if COMPILED and not jit.warmed_up(_warm_up, "the path task's compiled tick: Python runs"):
    COMPILED = False
