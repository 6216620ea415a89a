"""Tool velocity from measured tip positions: a first-order low-pass of finite differences.

The seed's fixture needs the tool tip velocity v(k) every haptic tick. A backward difference
of positions sampled at 1 kHz amplifies measurement noise by 1/dt (1000×: 1 µm of encoder
noise becomes 1 mm/s), so the difference is low-pass filtered, one pole:

    d_k = (p_k − p_{k−1})/dt,      v_k = v_{k−1} + α·(d_k − v_{k−1}),
    α = 1 − exp(−2π·f_c·dt)        (the exact discretisation of 1/(1 + s/(2π f_c))).

Default cut-off f_c = 20 Hz (our choice): voluntary movement is below ~2-5 Hz (98.9 % of
the power of surgeons' voluntary hand motion is below 2 Hz, Riviere, Rader & Khosla 1997)
and physiological tremor lies at 8-12 Hz (Elble & Koller 1990), so both pass with gain
≥ 0.85, while white position noise comes out α/√(2 − α) ≈ 0.09× as large (rms) as in the raw
difference (α = 0.118). The price is a lag of ~1/(2π f_c) = 8 ms at low frequencies.

The first sample of a track has no predecessor: its velocity is 0 (the seed's fixture then
gives no force). :class:`VelocityFilter` runs a batch of independent tracks (e.g. one per
trial), each resettable on its own.
"""

from __future__ import annotations

import copy
import math

import numpy as np

#: Default cut-off frequency, Hz (see the module docstring).
DEFAULT_CUTOFF_HZ = 20.0


def lowpass_alpha(cutoff_hz: float, dt: float) -> float:
    """Smoothing factor α of a first-order low-pass at ``cutoff_hz`` sampled every ``dt``."""
    if not (cutoff_hz > 0 and dt > 0):
        raise ValueError(f"cutoff_hz and dt must be > 0, got {cutoff_hz!r}, {dt!r}")
    return 1.0 - math.exp(-2.0 * math.pi * cutoff_hz * dt)


def filtered_velocity_step(
    velocity_prev, position_prev, position, *, dt: float, alpha: float
) -> np.ndarray:
    """One step of the filter (pure): the new velocity estimate, same shape as positions."""
    d = (np.asarray(position, dtype=float) - np.asarray(position_prev, dtype=float)) / dt
    v = np.asarray(velocity_prev, dtype=float)
    return v + alpha * (d - v)


class VelocityFilter:
    """Velocity estimates of a batch of tracks of positions, ``shape + (3,)``.

    Args:
        shape: batch shape, e.g. ``(n_trials,)`` or ``()`` for one track.
        dt: sample period, s (1 ms: the haptic rate).
        cutoff_hz: cut-off frequency, Hz.
    """

    def __init__(
        self,
        shape: tuple[int, ...] = (),
        *,
        dt: float = 0.001,
        cutoff_hz: float = DEFAULT_CUTOFF_HZ,
    ) -> None:
        self.dt = float(dt)
        self.cutoff_hz = float(cutoff_hz)
        self.alpha = lowpass_alpha(cutoff_hz, dt)
        self.shape = tuple(shape)
        self._p = np.zeros(self.shape + (3,))
        self._v = np.zeros(self.shape + (3,))
        self._started = np.zeros(self.shape, dtype=bool)

    @property
    def velocity(self) -> np.ndarray:
        """The latest estimates (a copy), m/s."""
        return self._v.copy()

    def update(self, position) -> np.ndarray:
        """Feed the positions of this sample (``shape + (3,)``, m); returns the velocities."""
        p = np.asarray(position, dtype=float)
        if p.shape != self.shape + (3,):
            raise ValueError(f"expected positions of shape {self.shape + (3,)}, got {p.shape}")
        v = filtered_velocity_step(self._v, self._p, p, dt=self.dt, alpha=self.alpha)
        self._v = np.where(self._started[..., None], v, 0.0)
        self._p = p.copy()
        self._started[...] = True
        return self._v.copy()

    def take(self, rows) -> VelocityFilter:
        """A filter of the tracks ``rows`` (indices along the first axis), in their state."""
        rows = np.asarray(rows, dtype=int)
        out = copy.copy(self)
        out._p, out._v, out._started = self._p[rows], self._v[rows], self._started[rows]
        out.shape = out._started.shape
        return out

    def reset(self, mask=None) -> None:
        """Forget the history of all tracks, or of those where ``mask`` (``shape``) is true."""
        if mask is None:
            self._started[...] = False
            self._v[...] = 0.0
            return
        m = np.asarray(mask, dtype=bool)
        self._started[m] = False
        self._v[m] = 0.0

    def get_state(self) -> dict:
        """The filter's memory: last positions, velocities, which tracks started (copies)."""
        return {"p": self._p.copy(), "v": self._v.copy(), "started": self._started.copy()}

    def set_state(self, state: dict) -> None:
        self._p, self._v = state["p"].copy(), state["v"].copy()
        self._started = state["started"].copy()
        self.shape = self._started.shape
