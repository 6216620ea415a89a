"""The path kind's metrics of one trial, sample by sample, on floats: the live session's
:meth:`~davinci_sim.tasks.metrics.MetricsAccumulator.update` at 1 kHz.

:class:`MetricsAccumulator` runs each metric's reducer on (n,) arrays, which for the one
trial of the live session costs a microsecond per numpy call, some 200 µs a tick while a
repetition runs. For the path kind's own declaration (:data:`PATH_KIND_METRICS`, what
``seed_path`` and every path task file score), :func:`update_one` does the same reductions
on the trial's floats and writes them into the accumulator's own arrays: the same
comparisons, the same operations in the same order (numpy's ``maximum``/``minimum`` rules,
a row's norm summed ``(x² + y²) + z²``), so the same bits (``tests/tasks/test_metrics_one.py``
runs both on the same samples, with and without the optional fields the trainer metrics
need). Any other declaration or a batch takes the reducers' path, which stays the oracle.
"""

from __future__ import annotations

import numpy as np

from davinci_sim.geometry.floats import norm3, np_maximum, np_minimum
from davinci_sim.kinematics import jit
from davinci_sim.tasks.metrics import PATH_METRICS
from davinci_sim.tasks.trainer import PATH_MISSED_TARGETS, force_threshold, trainer_metrics

#: The path kind's declaration (``PathTask.METRICS``): the path metrics, then the trainers'
#: with the path's missed targets.
PATH_KIND_METRICS = (*PATH_METRICS, *trainer_metrics(replace=(PATH_MISSED_TARGETS,)))

_NAMES = tuple(m.name for m in PATH_KIND_METRICS)
assert _NAMES == (
    "deviation_error",
    "deviation_rms",
    "deviation_max",
    "completion_time",
    "path_length",
    "mean_speed",
    "peak_force",
    "mean_force",
    "time_outside",
    "clutch_count",
    "samples",
    "instrument_collisions",
    "excessive_force",
    "out_of_view",
    "master_workspace",
    "drops",
    "missed_targets",
), _NAMES  # fmt: skip  (update_one's indices below)

jit.helper(norm3)
jit.helper(np_maximum)
jit.helper(np_minimum)


def applies(metrics, n: int) -> bool:
    """Whether :func:`update_one` computes these ``metrics`` of ``n`` trials."""
    return n == 1 and tuple(metrics) == PATH_KIND_METRICS


def update_one(acc, mask, sample, obs) -> bool:
    """:meth:`MetricsAccumulator.update` of ``acc`` (one trial of :data:`PATH_KIND_METRICS`)
    on floats; False (nothing changed) for an observation the path kind does not make (the
    reducers' path runs then)."""
    if "dropped" in obs:  # (a path observes no drops: its Sum adds 0)
        return False
    prev = previous_of(acc, sample)
    if prev is None:
        return False
    mark_missing(acc, sample)
    task = acc.task
    master, contacts, tool_force, visible = (sample.master, sample.contacts,
                                             sample.tool_force, sample.visible)  # fmt: skip
    tip, f, pt = sample.tip[0], sample.force[0], prev.tip[0]
    m = bool(mask[0])
    path_update(
        *running(acc), m, bool(acc._prev_in[0]), float(sample.time[0]),
        float(tip[0]), float(tip[1]), float(tip[2]), float(prev.time[0]), float(pt[0]),
        float(pt[1]), float(pt[2]), bool(sample.clutch[0]), bool(prev.clutch[0]),
        contacts is not None, 0 if contacts is None else int(contacts[0]),
        0 if contacts is None else int(prev.contacts[0]), tool_force is not None,
        0.0 if tool_force is None else float(tool_force[0]), visible is not None,
        visible is not None and bool(visible[0]), master is not None, _NO_MASTER
        if master is None else master[0], float(f[0]), float(f[1]), float(f[2]),
        float(obs["distance"][0]), float(task.tube_radius), force_threshold(task),
        targets(task),
    )  # fmt: skip
    update_previous(acc, np.asarray(mask, dtype=bool), sample)
    return True


_NO_MASTER = np.zeros(3)


def running(acc) -> tuple:
    """``acc``'s running arrays in :func:`path_update`'s order (from the mean deviation's
    sum to the sample count), which it and the compiled path ticks update in place."""
    a = acc._acc
    return (a[0], a[1], a[2], a[3][0], a[3][1], a[4], a[6], a[7], a[8], a[9], a[11], a[12],
            a[13], a[14][0], a[14][1], a[16], acc._k)  # fmt: skip


def previous_of(acc, sample):
    """The previous sample :func:`path_update` pairs ``sample`` with (``sample`` itself at
    the first), or None where the float law does not apply: one of the two has contacts
    and the other not (the reducers' path decides what that means)."""
    prev = sample if acc._prev is None else acc._prev
    return None if (sample.contacts is None) != (prev.contacts is None) else prev


def mark_missing(acc, sample) -> None:
    """A metric whose field the sample lacks cannot tell: unavailable (nan in the results),
    its running value left as it is, as the reducers' path does."""
    for value, name in ((sample.contacts, "instrument_collisions"),
                        (sample.tool_force, "excessive_force"),
                        (sample.visible, "out_of_view"),
                        (sample.master, "master_workspace")):  # fmt: skip
        if value is None:
            acc._missing.add(name)


def update_previous(acc, measured, sample) -> None:
    """The accumulator's previous sample and which trials it measured (``measured`` (n,)
    bool), after ``sample``: as :meth:`MetricsAccumulator.update` leaves them."""
    idle = not measured.any()
    acc._prev_in = np.array(measured, dtype=bool)
    if acc._prev is None:
        acc._prev = sample
    else:
        acc._prev = acc._prev.kept(sample) if idle else acc._prev.where(measured, sample)


def targets(task) -> np.ndarray:
    """The numbered points 2..N−1 of ``task``'s path (k, 3), m: the missed targets' marks
    (cached on the task: its markers do not change)."""
    cached = task.__dict__.get("_metrics_targets")
    if cached is None:
        cached = np.asarray(task.markers[1:-1], dtype=float).reshape(-1, 3).copy()
        object.__setattr__(task, "_metrics_targets", cached)
    return cached


@jit.helper
def path_update(
    deviation, squares, farthest, t_first, t_last, length, peak, force_sum, outside, presses,
    collisions, excessive, unseen, low, high, reached, count, m, prev_in, t, x, y, z, prev_t,
    px, py, pz, clutch, prev_clutch, has_contacts, contacts, prev_contacts, has_tool_force,
    tool_force, has_visible, visible, has_master, p_master, fx, fy, fz, distance, tube_radius,
    force_limit, marks,
):  # fmt: skip
    """One sample of one trial into the path kind's running reductions, in place: each
    argument up to ``count`` is the (1,)-row (or (1, 3) extent, (1, k) reached marks)
    array of :data:`PATH_KIND_METRICS`' reducers in order (the mean deviation's sum, the
    sum of its squares and its peak, the elapsed time's first and last times, the path
    length, the peak and summed force, the time outside the tube, clutch presses,
    instrument collisions, time over the force limit, distance out of view, the master's
    extent, the targets reached) and the sample
    count; ``m``: this sample is measured, ``prev_in``: the previous one was; then the
    sample (time s, tip m, clutch, the optional contacts, tool force N, visibility and
    master position m, each with whether the sample has it; the guidance force N), the
    previous sample's, the observed ``distance`` to the path (m), the task's tube radius
    (m), force limit (N) and target marks ``marks`` (k, 3), m. The reducers' arithmetic on
    floats: the same comparisons, the same operations in the same order (numpy's
    ``maximum``/``minimum`` rules, a row's norm summed ``(x² + y²) + z²``)."""
    pair = m and prev_in
    dx, dy, dz = x - px, y - py, z - pz
    dt = t - prev_t
    if pair:  # (the integer pair sums: counted whether or not the sample is measured)
        presses[0] += 1 if clutch and not prev_clutch else 0
        if has_contacts:
            collisions[0] += 1 if contacts > 0 and not prev_contacts > 0 else 0
    if not m:
        return
    force = norm3(fx, fy, fz)
    deviation[0] = deviation[0] + distance
    squares[0] = squares[0] + distance * distance
    farthest[0] = np_maximum(farthest[0], distance)
    if t_first[0] != t_first[0]:
        t_first[0] = t
    t_last[0] = t
    peak[0] = np_maximum(peak[0], force)
    force_sum[0] = force_sum[0] + force
    step = norm3(dx, dy, dz)
    if pair:
        length[0] = length[0] + step
        outside[0] = outside[0] + (dt if distance > tube_radius else 0.0)
        if has_tool_force:
            excessive[0] = excessive[0] + (dt if tool_force > force_limit else 0.0)
        if has_visible:
            unseen[0] = unseen[0] + (0.0 if visible else step)
    else:  # (+ 0: the same float, as where(pair, value, 0) adds)
        length[0] = length[0] + 0.0
        outside[0] = outside[0] + 0.0
        if has_tool_force:
            excessive[0] = excessive[0] + 0.0
        if has_visible:
            unseen[0] = unseen[0] + 0.0
    if has_master:
        for i in range(3):
            low[0, i] = np_minimum(low[0, i], p_master[i])
            high[0, i] = np_maximum(high[0, i], p_master[i])
    for k in range(marks.shape[0]):
        if norm3(x - marks[k, 0], y - marks[k, 1], z - marks[k, 2]) <= tube_radius:
            reached[0, k] = True
    count[0] += 1
