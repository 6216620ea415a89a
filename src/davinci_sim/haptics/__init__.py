"""Haptics: the force-field interface, built-in fields, the safety limits, the haptic loop.

* :class:`HapticState`, :class:`ForceField` — what a field sees and returns (field.py).
* :class:`ContactFeedback` — contact force on the instrument, on the hand.
* :class:`WrenchLimits`, :func:`clamp_wrench` — the clamp every MTM wrench goes through.
* :class:`HapticLoop` — fields → limits → MTM, each tick after the physics step.
* Virtual fixtures, pure ``force(p, v)`` laws: :class:`ViscousGuidance` (the seed's
  equations (1)-(7), viscous.py), :class:`SpringGuidance`, :class:`PlaneWall`,
  :class:`SphereWall`, :func:`combine`; :class:`FixtureField` plugs one into the loop.
* :class:`Polyline` — paths and closest-point queries (path.py).
"""

from davinci_sim.haptics.combine import combine
from davinci_sim.haptics.contact import ContactFeedback
from davinci_sim.haptics.field import ForceField, HapticState, as_wrench
from davinci_sim.haptics.fixture import FixtureField
from davinci_sim.haptics.loop import HapticLoop, HapticsState
from davinci_sim.haptics.path import Polyline
from davinci_sim.haptics.safety import WrenchLimiter, WrenchLimits, clamp_wrench
from davinci_sim.haptics.spring import SpringGuidance
from davinci_sim.haptics.viscous import ViscousGuidance
from davinci_sim.haptics.wall import PlaneWall, SphereWall

__all__ = [
    "ContactFeedback",
    "FixtureField",
    "ForceField",
    "HapticLoop",
    "HapticState",
    "HapticsState",
    "PlaneWall",
    "Polyline",
    "SphereWall",
    "SpringGuidance",
    "ViscousGuidance",
    "WrenchLimiter",
    "WrenchLimits",
    "as_wrench",
    "clamp_wrench",
    "combine",
]
