"""Time-synchronised joint trajectories within velocity and acceleration limits.

``move_jp``, ``move_cp`` and homing in the dVRK run a Reflexxes Type II trajectory
(dvrk.md 1.9): trapezoidal velocity profiles, bounded velocity and acceleration, all joints
arriving together. This module plans the same kind of profile from rest to rest. Joint values
are in rad or m, times in s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from davinci_sim.geometry.floats import np_maximum, np_minimum
from davinci_sim.kinematics.jit import helper


@dataclass(frozen=True, eq=False)
class JointTrajectory:
    """A rest-to-rest, time-synchronised trapezoidal trajectory from ``q_start`` to ``q_goal``."""

    q_start: np.ndarray
    q_goal: np.ndarray
    v_peak: np.ndarray
    """Peak speed of each joint (>= 0), scaled down so that all joints finish together."""
    a_max: np.ndarray
    duration: float
    """Seconds from start to goal."""

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity at time ``t`` s after the start (clamped to [0, duration])."""
        t = min(max(t, 0.0), self.duration)
        delta = self.q_goal - self.q_start
        dist = np.abs(delta)
        direction = np.sign(delta)
        a, v = self.a_max, self.v_peak
        with np.errstate(divide="ignore", invalid="ignore"):
            t_acc = np.where(a > 0, v / a, 0.0)
        t_dec = self.duration - t
        s_acc = 0.5 * a * t * t
        s_cruise = 0.5 * a * t_acc * t_acc + v * (t - t_acc)
        s_dec = dist - 0.5 * a * t_dec * t_dec
        s = np.where(t < t_acc, s_acc, np.where(t <= self.duration - t_acc, s_cruise, s_dec))
        sd = np.where(t < t_acc, a * t, np.where(t <= self.duration - t_acc, v, a * t_dec))
        moving = dist > 0
        s = np.where(moving, np.clip(s, 0.0, dist), 0.0)
        sd = np.where(moving, np.maximum(sd, 0.0), 0.0)
        if t >= self.duration:
            return self.q_goal.copy(), np.zeros_like(self.q_goal)
        return self.q_start + direction * s, direction * sd


def _minimum_time(dist: np.ndarray, v_max: np.ndarray, a_max: np.ndarray) -> np.ndarray:
    """Shortest rest-to-rest time of each joint alone (trapezoid, or triangle if short)."""
    triangle = dist < v_max * v_max / a_max
    return np.where(triangle, 2.0 * np.sqrt(dist / a_max), dist / v_max + v_max / a_max)


def plan_trajectory(
    q_start: np.ndarray, q_goal: np.ndarray, v_max: np.ndarray, a_max: np.ndarray
) -> JointTrajectory:
    """Plan a synchronised trapezoidal trajectory; every joint respects its ``v_max``/``a_max``.

    Raises:
        ValueError: if shapes differ or a limit is not strictly positive and finite.
    """
    q_start = np.asarray(q_start, dtype=float).copy()
    q_goal = np.asarray(q_goal, dtype=float).copy()
    v_max = np.broadcast_to(np.asarray(v_max, dtype=float), q_start.shape).copy()
    a_max = np.broadcast_to(np.asarray(a_max, dtype=float), q_start.shape).copy()
    if q_start.shape != q_goal.shape:
        raise ValueError(f"q_start {q_start.shape} and q_goal {q_goal.shape} differ in shape")
    if not (np.all(np.isfinite(v_max)) and np.all(v_max > 0)):
        raise ValueError(f"v_max must be finite and > 0, got {v_max!r}")
    if not (np.all(np.isfinite(a_max)) and np.all(a_max > 0)):
        raise ValueError(f"a_max must be finite and > 0, got {a_max!r}")
    dist = np.abs(q_goal - q_start)
    duration = float(np.max(_minimum_time(dist, v_max, a_max), initial=0.0))
    # Peak speed that makes a joint with acceleration a cover dist in exactly `duration`:
    # dist = v T - v^2 / a  ->  v = (a T - sqrt(a^2 T^2 - 4 a dist)) / 2.
    disc = np.maximum(a_max * a_max * duration * duration - 4.0 * a_max * dist, 0.0)
    v_peak = np.minimum((a_max * duration - np.sqrt(disc)) / 2.0, v_max)
    v_peak = np.where(dist > 0, v_peak, 0.0)
    return JointTrajectory(q_start, q_goal, v_peak, a_max, duration)


def step_towards(
    q: np.ndarray,
    qd: np.ndarray,
    goal: np.ndarray,
    v_max: np.ndarray,
    a_max: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, np.ndarray]:
    """One step of ``dt`` s of an online trajectory from ``(q, qd)`` towards ``goal`` (which
    may change at every step), each joint within ``v_max`` and ``a_max``: the position and
    velocity setpoints after the step. As the dVRK's online Reflexxes evaluation (dvrk.md
    1.9), the velocity changes continuously; each joint speeds up, cruises and brakes so as to
    stop at the goal (joints are not synchronised)."""
    e = goal - q
    dist = np.abs(e)
    # The fastest speed that can still stop at the goal, no faster than v_max, and no more
    # than what reaches it within this step.
    v_goal = np.sign(e) * np.minimum(np.minimum(v_max, np.sqrt(2.0 * a_max * dist)), dist / dt)
    dv = a_max * dt
    qd_next = qd + np.clip(v_goal - qd, -dv, dv)
    return q + qd_next * dt, qd_next


_min = helper(np_minimum)
_max = helper(np_maximum)


@helper
def step_towards_row(q, qd, goal, v_max, a_max, ratio, dt, q_out, qd_out):
    """:func:`step_towards` of one arm's joints on floats, into ``q_out``, ``qd_out``, with
    the limits ``v_max·ratio``, ``a_max·ratio`` (the arm's trajectory ratio): the same
    operations in the same order as numpy's (``np.sign``, ``np.minimum``, ``np.clip``
    with their NaN and signed-zero rules), so the same bits."""
    for i in range(q.shape[0]):
        v, a = v_max[i] * ratio, a_max[i] * ratio
        e = goal[i] - q[i]
        dist = abs(e)
        sign = 1.0 if e > 0 else -1.0 if e < 0 else 0.0 if e == 0 else e
        v_goal = sign * _min(_min(v, math.sqrt(2.0 * a * dist)), dist / dt)
        dv = a * dt
        qd_next = qd[i] + _min(_max(v_goal - qd[i], -dv), dv)
        q_out[i] = q[i] + qd_next * dt
        qd_out[i] = qd_next
