"""A callback run at a fixed rate in the event loop, on absolute deadlines (no drift)."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable

_log = logging.getLogger("davinci_sim.bridge")


class PeriodicTask:
    """Calls ``fn()`` every ``period`` seconds in the running loop.

    Deadlines are absolute, so the average rate is exact even though the loop's timers
    wake up to a millisecond late; after a stall longer than a period the missed calls are
    skipped, not made up in a burst.
    """

    def __init__(self, period: float, fn: Callable[[], None]) -> None:
        if not period > 0:
            raise ValueError(f"period must be > 0, got {period!r}")
        self.period = period
        self.fn = fn
        self.calls = 0
        self.skipped = 0
        self._handle: asyncio.TimerHandle | None = None
        self._next = 0.0

    def start(self) -> None:
        loop = asyncio.get_running_loop()
        self._loop = loop
        self._next = loop.time() + self.period
        self._handle = loop.call_at(self._next, self._tick)

    def _tick(self) -> None:
        try:
            self.fn()
        except Exception:
            _log.exception("periodic %r failed", self.fn)
        self.calls += 1
        now = self._loop.time()
        self._next += self.period
        if self._next < now - self.period:
            missed = int((now - self._next) / self.period)
            self.skipped += missed
            self._next += missed * self.period
        self._handle = self._loop.call_at(self._next, self._tick)

    async def stop(self) -> None:
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None
