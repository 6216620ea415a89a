"""Noise sources of the synthetic trainee: per-trial random streams, tremor, motor noise.

* :class:`TrialNoise`: independent standard normal streams, one per trial, seeded by the
  trial's key (e.g. (seed, subject, condition, repetition)), drawn in blocks of 1000 steps:
  a trial's noise does not depend on which other trials share its batch, so a study gives
  the same numbers however it is split across processes or machines.
* :class:`Tremor`: physiological tremor as a narrow-band process: white noise through two
  band-pass resonators at the subject's frequency, per axis, normalised to unit variance.
  Scaled, it is a force on the hand whose free-hand displacement has the subject's rms
  amplitude at the subject's frequency.
* :class:`MotorNoise`: signal-dependent noise (Harris & Wolpert 1998): the command u is
  corrupted by k·‖u‖·n, n white noise low-pass filtered by the muscle's activation dynamics,
  here a first-order filter of 40 ms (the order of the 40 ms muscle filter time constants of
  Todorov & Jordan 2002), normalised to unit variance. For a minimum-jerk reach of
  amplitude A and duration T (∫‖u‖²dt = (10/7)·A²/T) without visual correction, the
  endpoint SD along one axis is about k·A·√(2τ·(10/7)/T): k = 0.1, T = 0.5 s gives ~5 % of
  A (the reason for the default k of :mod:`davinci_sim.operators.params`).
"""

from __future__ import annotations

import copy
import math

import numpy as np
from scipy.signal import lfilter

#: Muscle activation time constant of the motor noise filter, s.
MUSCLE_TIME_CONSTANT = 0.040


class TrialNoise:
    """Standard normal draws, ``channels`` per step, one independent stream per trial.

    Args:
        keys: one sequence of ints per trial, its stream's seed (e.g. ``(seed, subject,
            condition, repetition)``).
        channels: normals per step and trial.
        block: steps drawn at once per trial.
    """

    def __init__(self, keys, channels: int, *, block: int = 1000) -> None:
        self.generators = [np.random.default_rng([int(k) for k in key]) for key in keys]
        self.channels = int(channels)
        self.block = int(block)
        self._buffer = np.empty((len(self.generators), self.block, self.channels))
        self._k = self.block

    def take(self, rows) -> TrialNoise:
        """The streams of ``rows`` (indices), continuing where they are."""
        out = copy.copy(self)
        out.generators = [self.generators[i] for i in rows]
        out._buffer = self._buffer[np.asarray(rows, dtype=int)]
        return out

    def next(self) -> np.ndarray:
        """This step's normals, (n_trials, channels)."""
        out = self.ahead(1)[:, 0]
        self._k += 1
        return out

    def ahead(self, steps: int) -> np.ndarray:
        """The normals of the next steps, at most ``steps`` and no further than the block
        drawn (n_trials, ≤ steps, channels), without taking them (:meth:`skip` does)."""
        if self._k == self.block:
            for i, g in enumerate(self.generators):
                self._buffer[i] = g.standard_normal((self.block, self.channels))
            self._k = 0
        return self._buffer[:, self._k : self._k + steps]

    def skip(self, steps: int) -> None:
        """Take ``steps`` steps' normals (those :meth:`ahead` gave)."""
        self._k += steps


def resonator_coefficients(frequency_hz, bandwidth_hz: float, dt: float):
    """One band-pass resonator section ``y_k = a1·y_{k−1} + a2·y_{k−2} + x_k − x_{k−2}``:
    poles r·e^(±iω₀dt) with r = exp(−π·bandwidth·dt) (a peak at ``frequency_hz`` about
    ``bandwidth_hz`` wide), zeros at DC and Nyquist. Returns (a1, a2), each (n,)."""
    r = math.exp(-math.pi * bandwidth_hz * dt)
    w0 = 2.0 * np.pi * np.asarray(frequency_hz, dtype=float) * dt
    return 2.0 * r * np.cos(w0), -(r**2) * np.ones_like(w0)


class Tremor:
    """Narrow-band unit-variance tremor, (n, 3), one centre frequency (Hz) per trial.

    Two identical band-pass resonator sections in cascade (:func:`resonator_coefficients`):
    the spectrum falls off as 1/f² on both sides of the peak, so that the tremor drive has
    almost no power at the limb's own resonance (~3 Hz), only in the physiological band.
    The gain that gives unit stationary variance comes from the cascade's impulse response
    (Σ h² of its first 4000 samples, where it has decayed by e^(−25)).
    """

    def __init__(self, frequency_hz, *, bandwidth_hz: float, dt: float) -> None:
        f = np.asarray(frequency_hz, dtype=float)
        a1, a2 = resonator_coefficients(f, bandwidth_hz, dt)
        self.a1, self.a2 = a1[:, None], a2[:, None]
        length = int(math.ceil(8.0 / (math.pi * bandwidth_hz * dt)))
        gain = np.empty(len(f))
        for i in range(len(f)):
            impulse = np.zeros(length)
            impulse[0] = 1.0
            den = [1.0, -a1[i], -a2[i]]
            h = lfilter([1.0, 0.0, -1.0], den, lfilter([1.0, 0.0, -1.0], den, impulse))
            gain[i] = 1.0 / math.sqrt(float(np.sum(h * h)))
        self.gain = gain[:, None]
        # Inputs and outputs of the two sections, two samples back; starts at rest (the
        # amplitude settles within ~1/bandwidth, 0.5 s, while the trainee reaches point 1).
        n = len(f)
        self._x = np.zeros((2, n, 3))
        self._y1 = np.zeros((2, n, 3))
        self._y2 = np.zeros((2, n, 3))

    def take(self, rows) -> Tremor:
        """The tremors of ``rows`` (indices), in their current state."""
        rows = np.asarray(rows, dtype=int)
        out = copy.copy(self)
        out.a1, out.a2, out.gain = self.a1[rows], self.a2[rows], self.gain[rows]
        # (C-ordered: an index along the middle axis can give other strides, and the
        # study's compiled trainee would compile again for them)
        out._x, out._y1, out._y2 = (np.ascontiguousarray(a[:, rows])
                                    for a in (self._x, self._y1, self._y2))  # fmt: skip
        return out

    def step(self, white: np.ndarray) -> np.ndarray:
        x1, x2 = self._x
        y1 = self.a1 * self._y1[0] + self.a2 * self._y1[1] + white - x2
        y2 = self.a1 * self._y2[0] + self.a2 * self._y2[1] + y1 - self._y1[1]
        self._x = np.stack([white, x1])
        self._y1 = np.stack([y1, self._y1[0]])
        self._y2 = np.stack([y2, self._y2[0]])
        return self.gain * y2


class MotorNoise:
    """Unit-variance low-pass filtered noise (first order, :data:`MUSCLE_TIME_CONSTANT`),
    (n, 3): ``n_k = a·n_{k−1} + √(1 − a²)·w_k``, a = exp(−dt/τ)."""

    def __init__(self, n: int, *, dt: float, time_constant: float = MUSCLE_TIME_CONSTANT):
        self.a = math.exp(-dt / time_constant)
        self.b = math.sqrt(1.0 - self.a**2)
        self.state = np.zeros((n, 3))

    def take(self, rows) -> MotorNoise:
        """The noises of ``rows`` (indices), in their current state."""
        out = copy.copy(self)
        out.state = self.state[np.asarray(rows, dtype=int)]
        return out

    def step(self, white: np.ndarray) -> np.ndarray:
        self.state = self.a * self.state + self.b * white
        return self.state
