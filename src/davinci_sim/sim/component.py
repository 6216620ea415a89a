"""The component contract: what the simulation ticks besides its arms.

A component is anything :meth:`Simulation.add_component
<davinci_sim.sim.simulation.Simulation.add_component>` accepts: master devices, the console,
teleoperations, the haptic loop, a training session, an operator's hand, probes. Each tick
the simulation calls, in the components' order (:attr:`Simulation.components`):

1. every component's ``pre_step(t)`` (``t``: sim time before the step, s);
2. the arms' setpoints, the joint servo and one ``mj_step``;
3. every component's ``post_step(t)`` if it has one (``t``: the new time), e.g. the haptic
   loop computing forces from the state the step produced.

The order is explicit: ``add_component(c, before=name)`` or ``after=name`` puts ``c`` next to
a component it must precede or follow (an operator's hand acts before the device reads it; a
task samples after the haptic loop); without either it goes last. Names, not a fixed list
of phases: a dependency is stated where it exists, between the two components concerned,
and the orders the system has always used stay exactly as they were.

State (:mod:`davinci_sim.sim.state`): ``get_state()`` returns a value holding everything
of the component that changes while it runs (not its wiring to the simulation, devices or
arms, nor its configuration), deep-copied so later ticks do not change it; ``set_state``
puts it back. :meth:`Simulation.get_state` collects them with the arms' and MuJoCo's.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

IDLE = "idle"
"""What a component's optional ``chunk_part()`` returns when its ticks do nothing in the
state the simulation's chunker runs compiled (:mod:`davinci_sim.console.chunk`); a component
without ``chunk_part`` keeps every tick in Python while it is in the simulation."""


@runtime_checkable
class Component(Protocol):
    """A part of the system ticked with the arms (see the module docstring).

    Optional members (not part of the structural check, looked up by name):

    - ``post_step(t: float) -> None``: called after the physics step with the new time;
    - ``channels``: a :class:`~davinci_sim.sim.channels.Channels` whose events the
      simulation's handle forwards (console buttons, teleop states, task results …).
    """

    name: str
    """Unique in its simulation; calls through the handle address the component by it."""

    def pre_step(self, t: float) -> None:
        """Before the arms and the physics step, every tick; ``t`` sim time, s."""

    def snapshot(self) -> Any:
        """What the component publishes (an immutable value; read by other threads)."""

    def get_state(self) -> Any:
        """Everything of the component that changes while it runs, deep-copied."""

    def set_state(self, state: Any) -> None:
        """Put back a state :meth:`get_state` returned (of this component or one built the
        same way)."""


def check_component(component: object) -> None:
    """Raise TypeError if ``component`` lacks what every tick needs (``name``,
    ``pre_step``, ``snapshot``; ``post_step`` if present must be callable). ``get_state`` and
    ``set_state`` are checked when the simulation's state is taken or restored."""
    name = getattr(component, "name", None)
    if not isinstance(name, str) or not name:
        raise TypeError(f"a component needs a non-empty str name, got {name!r} ({component!r})")
    for method in ("pre_step", "snapshot"):
        if not callable(getattr(component, method, None)):
            raise TypeError(f"component {name!r} has no {method}() method")
    post_step = getattr(component, "post_step", None)
    if post_step is not None and not callable(post_step):
        raise TypeError(f"component {name!r}: post_step must be callable, got {post_step!r}")
