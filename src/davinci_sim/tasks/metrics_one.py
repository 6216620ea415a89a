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
from davinci_sim.tasks.metrics import PATH_METRICS
from davinci_sim.tasks.trainer import PATH_MISSED_TARGETS, force_threshold, trainer_metrics

#: The path kind's declaration (``PathTask.METRICS``): the path metrics, then the trainers'
#: with the path's missed targets.
PATH_KIND_METRICS = (*PATH_METRICS, *trainer_metrics(replace=(PATH_MISSED_TARGETS,)))

_NAMES = tuple(m.name for m in PATH_KIND_METRICS)
assert _NAMES == (
    "deviation_error",
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


def applies(metrics, n: int) -> bool:
    """Whether :func:`update_one` computes these ``metrics`` of ``n`` trials."""
    return n == 1 and tuple(metrics) == PATH_KIND_METRICS


def update_one(acc, mask, sample, obs) -> bool:
    """:meth:`MetricsAccumulator.update` of ``acc`` (one trial of :data:`PATH_KIND_METRICS`)
    on floats; False (nothing changed) for an observation the path kind does not make (the
    reducers' path runs then)."""
    if "dropped" in obs:  # (a path observes no drops: its Sum adds 0)
        return False
    master, visible = sample.master, sample.visible
    contacts, tool_force = sample.contacts, sample.tool_force
    # A metric whose field the sample lacks cannot tell: unavailable (nan in the results),
    # its running value left as it is, as the reducers' path does.
    for value, name in ((contacts, "instrument_collisions"), (tool_force, "excessive_force"),
                        (visible, "out_of_view"), (master, "master_workspace")):  # fmt: skip
        if value is None:
            acc._missing.add(name)
    a = acc._acc
    m = bool(mask[0])
    pair = m and bool(acc._prev_in[0])
    prev = sample if acc._prev is None else acc._prev
    tip = sample.tip[0]
    x, y, z = float(tip[0]), float(tip[1]), float(tip[2])
    pt = prev.tip[0]
    dx, dy, dz = x - float(pt[0]), y - float(pt[1]), z - float(pt[2])
    t = float(sample.time[0])
    dt = t - float(prev.time[0])
    if pair:  # (the integer pair sums: counted whether or not the sample is measured)
        a[7][0] += int(bool(sample.clutch[0]) and not bool(prev.clutch[0]))
        if contacts is not None:
            a[9][0] += int(bool(contacts[0] > 0) and not bool(prev.contacts[0] > 0))
    # (drops: the path kind observes none, its Sum adds 0)
    if m:
        task = acc.task
        distance = float(obs["distance"][0])
        f = sample.force[0]
        force = norm3(float(f[0]), float(f[1]), float(f[2]))
        a[0][0] = a[0][0] + distance
        t0, t1 = a[1]
        if t0[0] != t0[0]:
            t0[0] = t
        t1[0] = t
        a[4][0] = np_maximum(float(a[4][0]), force)
        a[5][0] = a[5][0] + force
        step = norm3(dx, dy, dz)
        if pair:
            a[2][0] = a[2][0] + step
            a[6][0] = a[6][0] + (dt if distance > task.tube_radius else 0.0)
            if tool_force is not None:
                over = float(tool_force[0]) > force_threshold(task)
                a[10][0] = a[10][0] + (dt if over else 0.0)
            if visible is not None:
                a[11][0] = a[11][0] + (0.0 if bool(visible[0]) else step)
        else:  # (+ 0: the same float, as where(pair, value, 0) adds)
            a[2][0] = a[2][0] + 0.0
            a[6][0] = a[6][0] + 0.0
            if tool_force is not None:
                a[10][0] = a[10][0] + 0.0
            if visible is not None:
                a[11][0] = a[11][0] + 0.0
        if master is not None:
            lo, hi = a[12]
            p = master[0]
            for i in range(3):
                lo[0, i] = np_minimum(float(lo[0, i]), float(p[i]))
                hi[0, i] = np_maximum(float(hi[0, i]), float(p[i]))
        reached = a[14]
        tolerance = task.tube_radius
        for k, q in enumerate(np.asarray(task.markers[1:-1], dtype=float).reshape(-1, 3)):
            if norm3(x - float(q[0]), y - float(q[1]), z - float(q[2])) <= tolerance:
                reached[0, k] = True
        acc._k[0] += 1
    acc._prev_in[0] = m
    if acc._prev is None:
        acc._prev = sample
    else:
        acc._prev = acc._prev.where(mask, sample) if m else acc._prev.kept(sample)
    return True
