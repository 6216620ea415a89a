"""Haptics: the force-field interface, built-in fields, the safety limits, the haptic loop.

* :class:`HapticState`, :class:`ForceField` — what a field sees and returns (field.py).
* :class:`ContactFeedback` — contact force on the instrument, on the hand.
* :class:`WrenchLimits`, :func:`clamp_wrench` — the clamp every MTM wrench goes through.
* :class:`HapticLoop` — fields → limits → MTM, each tick after the physics step.
"""

from davinci_sim.haptics.contact import ContactFeedback
from davinci_sim.haptics.field import ForceField, HapticState, as_wrench
from davinci_sim.haptics.loop import HapticLoop, HapticsState
from davinci_sim.haptics.safety import WrenchLimiter, WrenchLimits, clamp_wrench

__all__ = [
    "ContactFeedback",
    "ForceField",
    "HapticLoop",
    "HapticState",
    "HapticsState",
    "WrenchLimiter",
    "WrenchLimits",
    "as_wrench",
    "clamp_wrench",
]
