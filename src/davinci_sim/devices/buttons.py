"""Button events with the dVRK's Joy convention (dvrk.md 2.3).

The dVRK publishes pedal and console buttons as ``sensor_msgs/Joy`` with one button:
``[1]`` pressed, ``[0]`` released, ``[2]`` quick tap (cisst ``CLICKED``). :class:`ButtonEvent`
carries exactly these values, so ``ButtonEvent(buttons[0])`` decodes a Joy message.
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import IntEnum


class ButtonEvent(IntEnum):
    """A button event; the value is its Joy code (dvrk.md 2.3)."""

    RELEASED = 0
    PRESSED = 1
    CLICKED = 2

    def to_joy(self) -> list[int]:
        """The ``buttons`` field of the dVRK's Joy message for this event."""
        return [int(self)]


_NAMES = {e.name.lower(): e for e in ButtonEvent}
_VALID_FORMS = (
    "a ButtonEvent, a bool (pressed or not), a Joy buttons list [1]/[0]/[2], "
    "a Joy message {'buttons': [...]}, or 'pressed'/'released'/'clicked'"
)


def parse_button_event(value) -> ButtonEvent:
    """A :class:`ButtonEvent` from the forms clients use.

    Accepts a ``ButtonEvent``, a ``bool`` (True = pressed), a Joy ``buttons`` list (``[1]``
    pressed, ``[0]`` released, ``[2]`` clicked), a Joy-like mapping ``{"buttons": [...]}``, or
    the names ``"pressed"``, ``"released"``, ``"clicked"`` (any case; cisst's
    ``prmEventButton`` type names).

    Raises:
        ValueError: for anything else, naming the accepted forms.
    """
    if isinstance(value, ButtonEvent):
        return value
    if isinstance(value, bool):
        return ButtonEvent.PRESSED if value else ButtonEvent.RELEASED
    if isinstance(value, str):
        event = _NAMES.get(value.strip().lower())
        if event is None:
            raise ValueError(f"unknown button event {value!r}; expected {_VALID_FORMS}")
        return event
    if isinstance(value, Mapping):
        if "buttons" not in value:
            raise ValueError(f"button event mapping needs a 'buttons' key, got {value!r}")
        value = value["buttons"]
    if isinstance(value, list | tuple) and len(value) == 1 and _is_int(value[0]):
        code = int(value[0])
        if code in (0, 1, 2):
            return ButtonEvent(code)
    raise ValueError(f"invalid button event {value!r}; expected {_VALID_FORMS}")


def _is_int(x) -> bool:
    return (
        isinstance(x, int) and not isinstance(x, bool) or (isinstance(x, float) and x.is_integer())
    )
