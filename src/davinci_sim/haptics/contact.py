"""Contact-force feedback: the force the environment exerts on the instrument, on the hand.

A built-in force field (:mod:`davinci_sim.haptics.field`). MuJoCo's contact forces vary
from one 1 ms step to the next, so the force is low-pass filtered (first order) before it is
scaled; the state of the filter is kept per PSM.
"""

from __future__ import annotations

import math

import numpy as np

from davinci_sim.haptics.field import HapticState
from davinci_sim.sim.state import capture, restore


class ContactFeedback:
    """``gain · lowpass(contact force on the instrument)``, in camera = HRSV axes.

    Args:
        gain: force scale from instrument to hand (our default 0.5: with the 0.2 motion
            scale, a stiffer feel would make the loop ring).
        cutoff_hz: cut-off frequency of the first-order filter, Hz.
        dt: tick period, s.
    """

    def __init__(self, gain: float = 0.5, cutoff_hz: float = 30.0, dt: float = 0.001) -> None:
        for name, value in (("gain", gain), ("cutoff_hz", cutoff_hz), ("dt", dt)):
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ValueError(
                    f"ContactFeedback {name} must be a finite number >= 0, got {value!r}"
                )
        if cutoff_hz <= 0 or dt <= 0:
            raise ValueError("ContactFeedback cutoff_hz and dt must be > 0")
        self.gain = float(gain)
        self.alpha = 1.0 - math.exp(-2.0 * math.pi * cutoff_hz * dt)
        self._filtered: dict[str, np.ndarray] = {}

    def __call__(self, state: HapticState) -> np.ndarray:
        previous = self._filtered.get(state.psm, np.zeros(3))
        y = previous + self.alpha * (state.contact_force_camera - previous)
        self._filtered[state.psm] = y
        return self.gain * y

    def reset(self) -> None:
        self._filtered.clear()

    def get_state(self) -> dict:
        """The filtered contact force of each PSM (copies)."""
        return capture(self, ("_filtered",))

    def set_state(self, state: dict) -> None:
        restore(self, state, ("_filtered",))
