"""An arm's ``error`` / ``warning`` / ``status`` channels (dvrk.md 2.2) and its event hooks."""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable

from davinci_sim.sim.types import ArmMessage

_log = logging.getLogger("davinci_sim")

Callback = Callable[[str, object], None]


class Channels:
    """Keeps the last messages and calls subscribers: ``cb(event_name, payload)``.

    Events: ``error``, ``warning``, ``status`` (payload :class:`ArmMessage`) and
    ``operating_state`` (payload :class:`~davinci_sim.sim.types.OperatingState`).
    """

    def __init__(self, owner: str, maxlen: int = 200) -> None:
        self.owner = owner
        self.messages: deque[ArmMessage] = deque(maxlen=maxlen)
        self._subscribers: list[Callback] = []

    def subscribe(self, callback: Callback) -> Callable[[], None]:
        """Register ``callback``; returns a function that unregisters it."""
        self._subscribers.append(callback)
        return lambda: self._subscribers.remove(callback)

    def emit(self, event: str, payload: object) -> None:
        for cb in list(self._subscribers):
            try:
                cb(event, payload)
            except Exception:  # a faulty subscriber must not stop the simulation
                _log.exception("%s: subscriber of %r failed", self.owner, event)

    def message(self, level: str, text: str, timestamp: float) -> None:
        msg = ArmMessage(level, f"{self.owner}: {text}", timestamp)
        self.messages.append(msg)
        log_level = {"error": logging.ERROR, "warning": logging.WARNING}.get(level, logging.INFO)
        _log.log(log_level, msg.text)
        self.emit(level, msg)

    def last(self, level: str | None = None) -> ArmMessage | None:
        """The most recent message (of ``level`` if given)."""
        for msg in reversed(self.messages):
            if level is None or msg.level == level:
                return msg
        return None
