"""Haptics: the force-field interface, built-in fields and the virtual fixtures' force laws.

* :class:`HapticState`, :class:`ForceField` — what a field sees and returns (field.py).
* :class:`ContactFeedback` — contact force on the instrument, on the hand.
* Virtual fixtures, pure ``force(p, v)`` laws: :class:`ViscousGuidance` (the seed's
  equations (1)-(7), viscous.py), :class:`SpringGuidance`, :class:`PlaneWall`,
  :class:`SphereWall`, :func:`combine`; :class:`FixtureField` plugs one into the loop.
* Fixture kinds (kinds.py): what a task file's fixture entry builds (``viscous``, ``spring``,
  ``none``, registered kinds, ``module:Name`` laws) and how its law is described.

The wrench clamp is the devices' (``devices.safety``), the loop that runs the fields every
tick is the console's (``console.haptic_loop``), paths and closest points are ``geometry.path``.
"""

from davinci_sim.haptics.combine import combine
from davinci_sim.haptics.contact import ContactFeedback
from davinci_sim.haptics.field import ForceField, HapticState, as_wrench
from davinci_sim.haptics.fixture import FixtureField
from davinci_sim.haptics.spring import SpringGuidance
from davinci_sim.haptics.viscous import ViscousGuidance
from davinci_sim.haptics.wall import PlaneWall, SphereWall

__all__ = [
    "ContactFeedback",
    "FixtureField",
    "ForceField",
    "HapticState",
    "PlaneWall",
    "SphereWall",
    "SpringGuidance",
    "ViscousGuidance",
    "as_wrench",
    "combine",
]
