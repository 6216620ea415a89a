"""Metrics of one repetition of a path-following task, over recorded samples.

A repetition is the samples i = 1..K of one trial while it runs (from the sample where the
tip leaves point 1 to the one where it reaches the last point, :mod:`davinci_sim.tasks.state`),
at times t_i (s), with tip positions p_i (m, task frame), distances to the path ‖φ_i‖ (m),
forces on the hand F_i (N) and the clutch pedal c_i. The metrics:

* **deviation error** e_jn = (1/K)·Σ ‖φ_i‖, m — equation (8) of the seed: the mean over the
  time steps of the distance to the path (a time average when the rate is constant, as the
  1 kHz haptic loop's is);
* **completion time** T = t_K − t_1, s;
* **path length** of the tip Σ_{i≥2} ‖p_i − p_{i−1}‖, m — economy of motion, as commercial
  trainers score it (the shortest possible is about the path's length). It depends on the
  sampling: at 1 kHz it includes the tremor's back-and-forth (tens of µm at ~10 Hz add a few
  mm per second), which a camera-rate tracker would not see;
* **mean speed** = path length / T, m/s (nan if T = 0);
* **peak force** max ‖F_i‖ and **mean force** (1/K)·Σ ‖F_i‖, N — of the guidance the hand
  feels;
* **time outside** the tolerance tube Σ_{i≥2} (t_i − t_{i−1})·[‖φ_i‖ > r], s — each interval
  counted by its end sample, r the task's ``tube_radius``;
* **clutch count**: presses of the clutch, the samples where it goes from released to
  pressed (i ≥ 2; a clutch already pressed at the first sample is not a press).

The functions take arrays with a leading trial axis, (n, K[, 3]), and a mask (n, K) of the
samples of each repetition (one contiguous run per trial; a 1-D (K,) input is one trial);
sums over pairs use the pairs of consecutive samples that are both in the mask.
:class:`MetricsAccumulator` computes the same numbers sample by sample, for a batch of
trials, without storing the trajectories.
"""

from __future__ import annotations

import copy
from typing import NamedTuple

import numpy as np


class RepetitionMetrics(NamedTuple):
    """The metrics of a batch of repetitions, each (n,) (see the module docstring)."""

    deviation_error: np.ndarray
    completion_time: np.ndarray
    path_length: np.ndarray
    mean_speed: np.ndarray
    peak_force: np.ndarray
    mean_force: np.ndarray
    time_outside: np.ndarray
    clutch_count: np.ndarray
    samples: np.ndarray
    """K, the number of samples of each repetition."""


def _2d(x, mask, trailing: int = 0):
    a = np.asarray(x)
    m = np.asarray(mask, dtype=bool)
    if m.ndim == 1:
        m = m[None]
        a = a[None]
    if a.shape[: a.ndim - trailing] != m.shape:
        raise ValueError(f"data of shape {np.shape(x)} does not match the mask {np.shape(mask)}")
    return a, m


def _pairs(m: np.ndarray) -> np.ndarray:
    """(n, K−1): sample i and i−1 both in the repetition."""
    return m[:, 1:] & m[:, :-1]


def _mean(values: np.ndarray, m: np.ndarray) -> np.ndarray:
    k = m.sum(axis=1)
    total = np.where(m, values, 0.0).sum(axis=1)
    return np.where(k > 0, total / np.maximum(k, 1), np.nan)


def deviation_error(distance, mask) -> np.ndarray:
    """e_jn of equation (8): mean distance to the path over the samples, m."""
    d, m = _2d(distance, mask)
    return _mean(d.astype(float), m)


def completion_time(time, mask) -> np.ndarray:
    """t_K − t_1, s (nan without samples)."""
    t, m = _2d(np.broadcast_to(time, np.shape(mask)), mask)
    has = m.any(axis=1)
    first = np.argmax(m, axis=1)
    last = m.shape[1] - 1 - np.argmax(m[:, ::-1], axis=1)
    rows = np.arange(len(m))
    return np.where(has, t[rows, last] - t[rows, first], np.nan)


def path_length(position, mask) -> np.ndarray:
    """Length of the tip's trajectory, m."""
    p, m = _2d(position, mask, trailing=1)
    step = np.linalg.norm(np.diff(p, axis=1), axis=2)
    return np.where(_pairs(m), step, 0.0).sum(axis=1)


def mean_speed(position, time, mask) -> np.ndarray:
    """Path length over completion time, m/s (nan if the time is 0)."""
    T = completion_time(time, mask)
    L = path_length(position, mask)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(T > 0, L / np.where(T > 0, T, 1.0), np.nan)


def force_peak(force, mask) -> np.ndarray:
    """max ‖F_i‖, N (0 without samples)."""
    f, m = _2d(force, mask, trailing=1)
    return np.where(m, np.linalg.norm(f, axis=2), 0.0).max(axis=1, initial=0.0)


def force_mean(force, mask) -> np.ndarray:
    """(1/K)·Σ ‖F_i‖, N."""
    f, m = _2d(force, mask, trailing=1)
    return _mean(np.linalg.norm(f, axis=2), m)


def time_outside(distance, time, mask, *, tube_radius: float) -> np.ndarray:
    """Time spent farther than ``tube_radius`` from the path, s."""
    d, m = _2d(distance, mask)
    t, _ = _2d(np.broadcast_to(time, np.shape(mask)), mask)
    dt = np.diff(t.astype(float), axis=1)
    return np.where(_pairs(m) & (d[:, 1:] > tube_radius), dt, 0.0).sum(axis=1)


def clutch_count(clutch, mask) -> np.ndarray:
    """Number of clutch presses (released → pressed transitions) during the repetition."""
    c, m = _2d(clutch, mask)
    c = c.astype(bool)
    return (_pairs(m) & c[:, 1:] & ~c[:, :-1]).sum(axis=1)


def repetition_metrics(
    time, position, distance, force, clutch, mask, *, tube_radius: float
) -> RepetitionMetrics:
    """All the metrics of a batch of recorded repetitions (see the module docstring)."""
    m = np.asarray(mask, dtype=bool)
    return RepetitionMetrics(
        deviation_error(distance, m),
        completion_time(time, m),
        path_length(position, m),
        mean_speed(position, time, m),
        force_peak(force, m),
        force_mean(force, m),
        time_outside(distance, time, m, tube_radius=tube_radius),
        clutch_count(clutch, m),
        np.atleast_2d(m).sum(axis=1),
    )


class MetricsAccumulator:
    """The same metrics as :func:`repetition_metrics`, accumulated sample by sample for n
    trials (no trajectories stored: O(n) memory whatever the duration)."""

    def __init__(self, n: int, *, tube_radius: float) -> None:
        self.n = n
        self.tube_radius = float(tube_radius)
        self.reset()

    def reset(self, mask=None) -> None:
        """Start over, all trials or those where ``mask`` (n,) is true."""
        m = np.ones(self.n, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        if mask is None:
            self._k = np.zeros(self.n, dtype=np.int64)
            self._sum_d = np.zeros(self.n)
            self._t0 = np.full(self.n, np.nan)
            self._t1 = np.full(self.n, np.nan)
            self._length = np.zeros(self.n)
            self._peak = np.zeros(self.n)
            self._sum_f = np.zeros(self.n)
            self._outside = np.zeros(self.n)
            self._clutches = np.zeros(self.n, dtype=np.int64)
            self._prev_in = np.zeros(self.n, dtype=bool)
            self._prev_p = np.zeros((self.n, 3))
            self._prev_t = np.zeros(self.n)
            self._prev_c = np.zeros(self.n, dtype=bool)
            return
        for a, v in (
            (self._k, 0),
            (self._sum_d, 0.0),
            (self._t0, np.nan),
            (self._t1, np.nan),
            (self._length, 0.0),
            (self._peak, 0.0),
            (self._sum_f, 0.0),
            (self._outside, 0.0),
            (self._clutches, 0),
            (self._prev_in, False),
        ):
            a[m] = v

    def take(self, rows) -> MetricsAccumulator:
        """An accumulator of the trials ``rows`` (indices), with what they have so far."""
        rows = np.asarray(rows, dtype=int)
        out = copy.copy(self)
        for name, value in vars(self).items():
            if name.startswith("_") and isinstance(value, np.ndarray):
                setattr(out, name, value[rows])
        out.n = len(rows)
        return out

    def update(self, mask, time, position, distance, force, clutch) -> None:
        """One sample of every trial; ``mask`` (n,) marks the trials whose repetition
        includes it. time: scalar or (n,); position, force: (n, 3); distance, clutch: (n,)."""
        m = np.asarray(mask, dtype=bool)
        t = np.broadcast_to(np.asarray(time, dtype=float), (self.n,))
        p = np.asarray(position, dtype=float)
        d = np.asarray(distance, dtype=float)
        f = np.linalg.norm(np.asarray(force, dtype=float), axis=-1)
        c = np.asarray(clutch, dtype=bool)
        pair = m & self._prev_in
        self._k += m
        self._sum_d += np.where(m, d, 0.0)
        self._t0 = np.where(m & np.isnan(self._t0), t, self._t0)
        self._t1 = np.where(m, t, self._t1)
        self._length += np.where(pair, np.linalg.norm(p - self._prev_p, axis=1), 0.0)
        self._peak = np.where(m, np.maximum(self._peak, f), self._peak)
        self._sum_f += np.where(m, f, 0.0)
        self._outside += np.where(pair & (d > self.tube_radius), t - self._prev_t, 0.0)
        self._clutches += pair & c & ~self._prev_c
        self._prev_in = m.copy()
        self._prev_p = np.where(m[:, None], p, self._prev_p)
        self._prev_t = np.where(m, t, self._prev_t)
        self._prev_c = np.where(m, c, self._prev_c)

    def result(self) -> RepetitionMetrics:
        k = self._k
        T = self._t1 - self._t0
        with np.errstate(invalid="ignore", divide="ignore"):
            mean_d = np.where(k > 0, self._sum_d / np.maximum(k, 1), np.nan)
            speed = np.where(T > 0, self._length / np.where(T > 0, T, 1.0), np.nan)
            mean_f = np.where(k > 0, self._sum_f / np.maximum(k, 1), np.nan)
        return RepetitionMetrics(
            mean_d,
            T,
            self._length.copy(),
            speed,
            self._peak.copy(),
            mean_f,
            self._outside.copy(),
            self._clutches.copy(),
            k.copy(),
        )

    def get_state(self) -> dict:
        """The running sums and the previous sample (copies)."""
        return {k: v.copy() for k, v in vars(self).items() if k.startswith("_")}

    def set_state(self, state: dict) -> None:
        for k, v in state.items():
            setattr(self, k, v.copy())
