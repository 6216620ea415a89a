"""The path's closest point to one tool tip as a compiled row kernel, for the 1 kHz loop.

The haptic loop's guidance (:class:`~davinci_sim.haptics.viscous.ViscousGuidance`) and the
task session's step (:meth:`~davinci_sim.tasks.task.PathTask.step`) each ask for the closest
point of the path to one tip every tick. :func:`closest_point` answers one query with
:func:`closest_segment_row`, the per-row form of
:func:`~davinci_sim.geometry.path.closest_point_brute` (the same products, sums, clip and
first-minimum rule, operation by operation, so the same bits: tested against it), and
leaves batches (the study's trials), long paths (the k-d tree) and a run without numba to
:meth:`Polyline.closest_point <davinci_sim.geometry.path.Polyline.closest_point>`.

(Here rather than in ``geometry``: that layer is numpy only, and the compiled kernels live
from ``kinematics.jit`` up; the haptics and the tasks above both use it.)
"""

from __future__ import annotations

import numpy as np

from davinci_sim.geometry.path import (
    BRUTE_FORCE_MAX_SEGMENTS,
    ClosestPoint,
    Polyline,
    brute_force_constants,
    closest_point_result,
)
from davinci_sim.kinematics import jit


@jit.jit
def closest_segment_row(q, basis, AE, AA, EE):
    """For one query ``q`` (3,), centred on the path's centre: ``(segment, u)`` of its
    closest point, by :func:`~davinci_sim.geometry.path.closest_point_brute`'s arithmetic
    (``basis``, ``AE``, ``AA``, ``EE``: :func:`~davinci_sim.geometry.path.
    brute_force_constants`): per segment ``(q − A)·E``, ``u`` clipped to [0, 1] (NaN kept,
    as ``np.clip``), the compared ``u²‖E‖² − 2u (q − A)·E − 2q·A + ‖A‖²``, and the first
    minimum (the first NaN if any, as ``np.argmin``)."""
    S = EE.shape[0]
    q0, q1, q2 = q[0], q[1], q[2]
    best, best_d, best_u = 0, 0.0, 0.0
    for k in range(S):
        qE = (q0 * basis[0, k] + q1 * basis[1, k]) + q2 * basis[2, k]
        qE = qE - AE[k]
        uu = qE / EE[k]
        if uu < 0.0:
            uu = 0.0
        if uu > 1.0:
            uu = 1.0
        j = S + k
        qA = (q0 * basis[0, j] + q1 * basis[1, j]) + q2 * basis[2, j]
        d2 = uu * EE[k]
        d2 = d2 - 2.0 * qE
        d2 = d2 * uu
        d2 = d2 - 2.0 * qA
        d2 = d2 + AA[k]
        if k == 0:
            best, best_d, best_u = 0, d2, uu
        elif best_d == best_d and not (d2 >= best_d):  # smaller, or the first NaN
            best, best_d, best_u = k, d2, uu
    return best, best_u


def closest_point(path: Polyline, points) -> ClosestPoint:
    """``path.closest_point(points)``, one query (shape (3,) or (1, 3)) by the compiled
    :func:`closest_segment_row`; any other query by the path itself. The same result, bit
    for bit, either way."""
    p = np.asarray(points, dtype=float)
    if (
        p.shape not in ((3,), (1, 3))
        or not jit.ENABLED
        or len(path.segment_lengths) > BRUTE_FORCE_MAX_SEGMENTS
    ):
        return path.closest_point(p)
    basis, AE, AA, EE = brute_force_constants(path)
    seg, u = closest_segment_row(p.reshape(3) - path.centre, basis, AE, AA, EE)
    shape = p.shape[:-1]
    return closest_point_result(path, p, np.full(shape, seg, dtype=int), np.full(shape, u))


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import, never in the 1 kHz loop."""
    path = Polyline(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]))
    closest_point(path, np.zeros(3))


_warm_up()
