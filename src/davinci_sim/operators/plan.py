"""The trainee's intended tool motion: minimum-jerk movements along the path.

Point-to-point movements of the hand follow the minimum-jerk profile
``x(u) = x₀ + (x₁ − x₀)·(10u³ − 15u⁴ + 6u⁵)``, u = t/T (Flash & Hogan 1985). The
trainee plans the path as such movements along the arc length, one per run between
numbered points: sharp turns segment movements into strokes with a speed minimum at the turn
(Flash & Hogan 1985's via-point movements; Viviani & Flash 1995), here a stop at points
2, 3, 4. Each stroke's duration is its length over the trainee's mean speed, so the speed
is the same on average on every run.

Functions are vectorised over trials: per-trial times and durations, one shared path.
"""

from __future__ import annotations

import numpy as np

from davinci_sim.geometry.path import Polyline


def minimum_jerk(u) -> tuple[np.ndarray, np.ndarray]:
    """Normalised minimum-jerk position and its derivative d/du at u ∈ [0, 1] (clipped)."""
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    u2 = u * u
    return u2 * u * (10.0 - 15.0 * u + 6.0 * u2), 30.0 * u2 * (1.0 - u) ** 2


def stroke_durations(stroke_lengths, speed) -> np.ndarray:
    """Durations (n, S) of strokes of ``stroke_lengths`` (S,) m at mean ``speed`` (n,) m/s."""
    return np.asarray(stroke_lengths, dtype=float)[None, :] / np.asarray(speed, float)[:, None]


def path_plan(path: Polyline, knots, durations, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Planned tool position, velocity and arc length at time ``t`` since the start.

    Args:
        path: the path.
        knots: arc lengths of the stroke ends (S + 1,), m, from 0 to the path's length.
        durations: (n, S) stroke durations, s.
        t: (n,) time since the plan's start, s (before 0: at the start, after the end: at
            the end, at rest).

    Returns:
        position (n, 3), velocity (n, 3) (m, m/s) and arc length s (n,).
    """
    knots = np.asarray(knots, dtype=float)
    T = np.asarray(durations, dtype=float)
    t = np.asarray(t, dtype=float)
    ends = np.cumsum(T, axis=1)  # (n, S)
    k = np.minimum((t[:, None] >= ends).sum(axis=1), T.shape[1] - 1)
    rows = np.arange(len(t))
    start = ends[rows, k] - T[rows, k]
    u = (t - start) / T[rows, k]
    g, dg = minimum_jerk(u)
    length = knots[k + 1] - knots[k]
    s = knots[k] + length * g
    speed = np.where((u > 0) & (u < 1), length * dg / T[rows, k], 0.0)
    return path.point_at(s), speed[:, None] * path.tangent_at(s), s


def straight_plan(p0, p1, duration, t) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-jerk straight movement from ``p0`` to ``p1`` (n, 3) in ``duration`` (n,) s;
    position and velocity at ``t`` (n,) s since its start."""
    T = np.asarray(duration, dtype=float)
    u = np.asarray(t, dtype=float) / T
    g, dg = minimum_jerk(u)
    d = np.asarray(p1, dtype=float) - np.asarray(p0, dtype=float)
    inside = (u > 0) & (u < 1)
    return p0 + g[:, None] * d, np.where(inside, dg / T, 0.0)[:, None] * d
