"""The path's closest point to one tool tip as a compiled row kernel, for the 1 kHz loop.

The haptic loop's guidance (:class:`~davinci_sim.haptics.viscous.ViscousGuidance`) and the
task session's step (:meth:`~davinci_sim.tasks.task.PathTask.step`) each ask for the closest
point of the path to one tip every tick. :func:`closest_point` answers one query with
:func:`closest_point_row`, the per-row form of
:func:`~davinci_sim.geometry.path.closest_point_brute` (the same products, sums, clip and
first-minimum rule, operation by operation, so the same bits: tested against it), and
:func:`closest_point_rows` a batch (the study's trials) row by row with the same kernel; it
leaves long paths (the k-d tree), other shapes and a run without numba to
:meth:`Polyline.closest_point <davinci_sim.geometry.path.Polyline.closest_point>`.

(Here rather than in ``geometry``: that layer is numpy only, and the compiled kernels live
from ``kinematics.jit`` up; the haptics and the tasks above both use it.)
"""

from __future__ import annotations

import math

import numpy as np

from davinci_sim.geometry.path import (
    BRUTE_FORCE_MAX_SEGMENTS,
    ClosestPoint,
    Polyline,
    brute_force_constants,
)
from davinci_sim.kinematics import jit


@jit.helper
def _closest_segment(q0, q1, q2, basis, AE, AA, EE):
    """``(segment, u)`` of the closest point to the query ``(q0, q1, q2)``, centred on the
    path's centre, by :func:`~davinci_sim.geometry.path.closest_point_brute`'s arithmetic
    (``basis``, ``AE``, ``AA``, ``EE``: :func:`~davinci_sim.geometry.path.
    brute_force_constants`): per segment ``(q − A)·E``, ``u`` clipped to [0, 1] (NaN kept,
    as ``np.clip``), the compared ``u²‖E‖² − 2u (q − A)·E − 2q·A + ‖A‖²``, and the first
    minimum (the first NaN if any, as ``np.argmin``)."""
    S = EE.shape[0]
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


@jit.helper
def _closest_point_into(p, centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, out):
    """:func:`closest_point_row`'s body, callable from other kernels (see it)."""
    seg, u = _closest_segment(p[0] - centre[0], p[1] - centre[1], p[2] - centre[2],
                              basis, AE, AA, EE)  # fmt: skip
    for i in range(3):
        x = starts[seg, i] + u * edges[seg, i]
        out[i] = x
        out[3 + i] = x - p[i]
    out[6] = math.sqrt((out[3] * out[3] + out[4] * out[4]) + out[5] * out[5])
    out[7] = cumulative[seg] + u * lengths[seg]
    return seg


@jit.jit
def closest_point_row(p, centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, out):
    """The closest point of the path to one query ``p`` (3,), m: its segment (returned) and,
    into ``out`` (8,), the point (3), the deviation φ = point − p (3), ‖φ‖ (summed left to
    right, as ``np.linalg.norm``) and the arc length, with the arithmetic every query of
    :mod:`davinci_sim.geometry.path` ends with (``starts``, ``edges``, ``cumulative``,
    ``lengths``: the path's)."""
    return _closest_point_into(p, centre, basis, AE, AA, EE, starts, edges, cumulative,
                               lengths, out)  # fmt: skip


@jit.jit
def closest_point_rows(P, centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, out,
                       segments):  # fmt: skip
    """:func:`closest_point_row` of every row of ``P`` (n, 3), into ``out`` (n, 8) and
    ``segments`` (n,): a batch of trials' tips in one call, each row the bits of one query."""
    for r in range(P.shape[0]):
        segments[r] = _closest_point_into(P[r], centre, basis, AE, AA, EE, starts, edges,
                                          cumulative, lengths, out[r])  # fmt: skip


def closest_point(path: Polyline, points) -> ClosestPoint:
    """``path.closest_point(points)``: one query (shape (3,) or (1, 3)) by the compiled
    :func:`closest_point_row`, a batch (n, 3) by :func:`closest_point_rows`; any other
    query, a long path (the k-d tree) or a run without numba by the path itself. The same
    result, bit for bit and type for type, either way."""
    p = np.asarray(points, dtype=float)
    if (
        p.ndim not in (1, 2)
        or p.shape[-1] != 3
        or len(p) == 0
        or not jit.ENABLED
        or len(path.segment_lengths) > BRUTE_FORCE_MAX_SEGMENTS
    ):
        return path.closest_point(p)
    constants = (path.centre, *brute_force_constants(path), path.starts, path.edges,
                 path.cumulative_length, path.segment_lengths)  # fmt: skip
    if p.ndim == 2 and len(p) > 1:  # a batch (the study's trials)
        out = np.empty((len(p), 8))
        seg = np.empty(len(p), dtype=int)
        closest_point_rows(np.ascontiguousarray(p), *constants, out, seg)
        return ClosestPoint(out[:, 0:3], out[:, 3:6], out[:, 6], out[:, 7], seg)
    out = np.empty(8)
    # (a new C row: the one compiled signature)
    seg = closest_point_row(np.array(p.reshape(3), dtype=float, order="C"), *constants, out)
    if p.ndim == 1:  # the batch shape (): scalars as numpy's reductions give them
        return ClosestPoint(out[0:3], out[3:6], out[6], out[7], np.array(seg, dtype=int))
    return ClosestPoint(out[0:3].reshape(1, 3), out[3:6].reshape(1, 3), out[6:7], out[7:8],
                        np.array([seg], dtype=int))  # fmt: skip


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import, never in the 1 kHz loop."""
    path = Polyline(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]))
    closest_point(path, np.zeros(3))
    closest_point(path, np.zeros((2, 3)))


jit.warm(_warm_up)
