"""The CRTK operating state machine of a dVRK arm (dvrk.md 2.4).

Pure: :func:`transition` tells what a ``state_command`` does in a given state, with the
dVRK's rule that anything not in the table is refused.
"""

from __future__ import annotations

from typing import Final

DISABLED: Final = "DISABLED"
ENABLED: Final = "ENABLED"
PAUSED: Final = "PAUSED"
FAULT: Final = "FAULT"

STATES: Final = (DISABLED, ENABLED, PAUSED, FAULT)
COMMANDS: Final = ("enable", "disable", "home", "unhome", "pause", "resume")

# dvrk.md 2.4, table "Allowed commands per state" (prmOperatingState.cpp). None = stay.
_TABLE: Final[dict[str, dict[str, str | None]]] = {
    DISABLED: {"enable": ENABLED, "disable": DISABLED, "unhome": None},
    ENABLED: {
        "enable": ENABLED,
        "disable": DISABLED,
        "pause": PAUSED,
        "unhome": None,
        "home": None,
    },
    PAUSED: {"disable": DISABLED, "pause": PAUSED, "resume": ENABLED, "unhome": None},
    FAULT: {"enable": ENABLED, "disable": DISABLED, "unhome": None},
}


def transition(state: str, command: str) -> tuple[str | None, str]:
    """The state after ``command`` in ``state``.

    Returns:
        ``(new_state, "")`` when accepted, or ``(None, message)`` when the dVRK refuses it.
    """
    if command not in COMMANDS:
        return None, f"unknown state command {command!r}; valid commands: {', '.join(COMMANDS)}"
    allowed = _TABLE.get(state, {})
    if command not in allowed:
        return None, f"command {command!r} is not supported in state {state}"
    new = allowed[command]
    return (state if new is None else new), ""
