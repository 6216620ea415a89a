"""The clocks of ``crtk.ral``: the wall clock, or the simulation's ``/clock`` with ROS's
``use_sim_time`` (see :mod:`davinci_sim.compat.ral`), and the rate that sleeps on either."""

from __future__ import annotations

import logging
import math
import os
import sys
import threading
import time
import weakref
from collections.abc import Callable

from davinci_sim.compat.transport import RosbridgeClient

_log = logging.getLogger("davinci_sim.compat")

ENV_SIM_TIME = "DAVINCI_SIM_USE_SIM_TIME"
CLOCK_TOPIC = "/clock"
_lock = threading.Lock()


def stamp_seconds(stamp: dict) -> float:
    """A ROS time (``sec``/``nanosec``, ROS 1's ``secs``/``nsecs``) in s."""
    sec = stamp.get("sec", stamp.get("secs", 0))
    nsec = stamp.get("nanosec", stamp.get("nsecs", 0))
    return float(sec) + float(nsec) * 1e-9


class SimClock:
    """Simulated time, s, from the server's ``/clock`` (``rosgraph_msgs/Clock``): one per
    client, shared by its ``ral`` objects. 0 until the first message (as ROS's time with
    ``use_sim_time`` before the clock is published)."""

    def __init__(self, client_: RosbridgeClient) -> None:
        self._changed = threading.Condition()
        self.time: float | None = None
        client_.subscribe(CLOCK_TOPIC, "rosgraph_msgs/Clock", self._on_clock)

    def _on_clock(self, d: dict) -> None:
        with self._changed:
            stamp = d.get("clock")
            self.time = stamp_seconds(stamp) if isinstance(stamp, dict) else 0.0
            self._changed.notify_all()

    def now(self) -> float:
        return self.time or 0.0

    def wait_until(self, t: float, stop: Callable[[], bool]) -> float:
        """Block until the clock has started and reads ≥ ``t`` s, or ``stop()``; returns the
        time then. Warns once if no clock comes for 5 s (a server without ``/clock``)."""
        warn_at = time.monotonic() + 5.0
        with self._changed:
            while (self.time is None or self.time < t) and not stop():
                self._changed.wait(0.1)
                if self.time is None and time.monotonic() > warn_at:
                    _log.warning("use_sim_time: no message on %s yet; waiting", CLOCK_TOPIC)
                    warn_at = math.inf
            return self.now()


_clocks: weakref.WeakKeyDictionary[RosbridgeClient, SimClock] = weakref.WeakKeyDictionary()


def sim_clock(client_: RosbridgeClient) -> SimClock:
    """The :class:`SimClock` of ``client_`` (made, and subscribed, on first use)."""
    with _lock:
        clock = _clocks.get(client_)
        if clock is None:
            clock = _clocks[client_] = SimClock(client_)
        return clock


def sim_time_requested(argv: list[str] | None = None) -> bool:
    """Whether this process asks for simulated time: ``$DAVINCI_SIM_USE_SIM_TIME`` set to
    1/true/yes, or a ``use_sim_time:=true`` ROS argument (``--ros-args -p
    use_sim_time:=true``) in ``argv`` (default ``sys.argv``)."""
    yes = ("1", "true", "yes", "on")
    if os.environ.get(ENV_SIM_TIME, "").strip().lower() in yes:
        return True
    args = sys.argv if argv is None else argv
    return any(a.lower().endswith("use_sim_time:=" + y) for a in args for y in yes)


class Rate:
    """``ral.create_rate(hz).sleep()``: sleeps to keep a loop at ``hz`` (catching up after
    a late iteration without sleeping, never sleeping a negative time), on the wall clock
    or, given one, on a :class:`SimClock` (``stop`` ends a wait for it: the ``ral`` shut
    down)."""

    def __init__(self, rate_hz: float, clock: SimClock | None = None,
                 stop: Callable[[], bool] = lambda: False) -> None:  # fmt: skip
        if not rate_hz > 0:
            raise ValueError(f"rate must be > 0 Hz, got {rate_hz!r}")
        self.period = 1.0 / float(rate_hz)
        self._clock, self._stop = clock, stop
        self._next = self._now() + self.period if clock is None or clock.time is not None else None

    def _now(self) -> float:
        return time.monotonic() if self._clock is None else self._clock.now()

    def sleep(self) -> None:
        if self._clock is not None and self._next is None:  # made before the clock came
            self._next = self._clock.wait_until(0.0, self._stop) + self.period
        now = self._now()
        if self._next > now + self.period:  # the clock went back (a reset): from now on
            self._next = now + self.period
        if self._next > now:
            if self._clock is None:
                time.sleep(self._next - now)
            else:
                self._clock.wait_until(self._next, self._stop)
            self._next += self.period
        else:  # late: start again from now
            self._next = now + self.period
