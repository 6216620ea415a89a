"""Running the tick loop: real time (paced by the wall clock) or as fast as possible.

:class:`Pacer` waits for the next period boundary: it sleeps until shortly before it, then
spins on the clock for the last ``spin`` seconds (a sleep alone overshoots by 50-100 µs on a
virtual machine). A loop that falls behind catches up by running ticks back to back, so sim
time keeps up with wall time; if it falls more than ``max_lag`` behind (a long stall), it
drops the backlog instead (counted as a *resync*).

:class:`LoopRunner` ticks a simulation with a pacer (or none), records the period
statistics (:mod:`~davinci_sim.sim.runtime.stats`) and runs inputs scheduled for given ticks
(:meth:`LoopRunner.call_at`), so a scripted run gives the same results in both modes: the
simulation never reads the wall clock.
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import heapq
import itertools
import math
import sys
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

from davinci_sim.sim.runtime.stats import PeriodRecorder, PeriodStatistics

if TYPE_CHECKING:
    from davinci_sim.sim.simulation import Simulation

#: The most ticks a live runner's pass runs (``Simulation.advance``'s compiled calls): a
#: call from outside waits at most 4 ms of simulated time for the next pass (issue 20).
CHUNK_TICKS = 4
#: Spin on the clock for the last 200 µs before a deadline (sleep overshoot on a VM).
DEFAULT_SPIN = 200e-6
#: Drop the backlog when more than 50 ms behind (a long stall: better to skip than to race).
DEFAULT_MAX_LAG = 0.05
#: The window over which :class:`Pacer` keeps its ``min_idle`` share of sleep, s.
IDLE_WINDOW = 0.01

_PR_SET_TIMERSLACK = 29


def reduce_timer_slack(nanoseconds: int = 1) -> bool:
    """Ask Linux for precise sleeps in this thread (``prctl(PR_SET_TIMERSLACK)``; the default
    slack of 50 µs delays every wake-up). Returns False where unsupported."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_TIMERSLACK, nanoseconds, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


@contextlib.contextmanager
def frozen_heap() -> Iterator[None]:
    """Within: every object alive on entry is out of the garbage collector's reach
    (``gc.freeze``); on exit they are back in it (``gc.unfreeze``).

    For the run of a long-running process, once it has built what it keeps (model, system,
    servers). A full collection scans every tracked object, and while it runs no other
    thread of the process runs: over the start-up heap of ``serve`` one took 170 ms, longer
    than the 40 ms in which the dVRK's scripts give up on a silent ``measured_cp`` (four
    periods at 100 Hz), and in the loop process it is a late tick. Objects made within are
    collected as before, and a full collection scans only them.
    """
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()  # what was frozen and has become garbage since can now be collected


def realtime_idle_share() -> float:
    """The share of wall time a real-time (``SCHED_FIFO``) loop must sleep so that Linux
    never throttles it, with one point of margin; 0 where the kernel sets no such limit.

    Linux lets real-time tasks run ``sched_rt_runtime_us`` of every ``sched_rt_period_us``
    (950 ms of 1 s by default). A FIFO loop that cannot keep up never sleeps, uses it up, and
    is then stopped for the rest of the second at once: one 50 ms period a second (measured:
    ``bench_realtime``'s longest periods were 53-57 ms with FIFO, 5 ms without).
    """
    try:
        with open("/proc/sys/kernel/sched_rt_runtime_us") as f:
            runtime = int(f.read())
        with open("/proc/sys/kernel/sched_rt_period_us") as f:
            period = int(f.read())
    except (OSError, ValueError):
        return 0.0
    if runtime < 0 or period <= 0:  # (-1: no limit)
        return 0.0
    return max(0.0, 1.0 - runtime / period) + 0.01


class Pacer:
    """Wall-clock pacing of a periodic loop; see the module docstring.

    Args:
        period: s.
        spin: busy-wait this long before each deadline, s.
        max_lag: drop the backlog beyond this lag, s.
        clock: monotonic clock in s.
        sleep: how to wait ``s`` seconds (tests pass a virtual clock and sleep).
        min_idle: the share of wall time the loop sleeps at least, kept over each
            :data:`IDLE_WINDOW` (a loop behind real time sleeps the shortfall at the window's
            end): a real-time loop's :func:`realtime_idle_share`, spread in short sleeps
            instead of being taken from it in one long stop. 0: none.
    """

    def __init__(
        self,
        period: float,
        *,
        spin: float = DEFAULT_SPIN,
        max_lag: float = DEFAULT_MAX_LAG,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], None] | None = None,
        min_idle: float = 0.0,
    ) -> None:
        if not (math.isfinite(period) and period > 0):
            raise ValueError(f"period must be > 0 s, got {period!r}")
        if not (spin >= 0 and max_lag > 0):
            raise ValueError(f"spin must be >= 0 and max_lag > 0, got {spin!r}, {max_lag!r}")
        if not 0 <= min_idle < 1:
            raise ValueError(f"min_idle must be in [0, 1), got {min_idle!r}")
        self.period = period
        self.spin = spin
        self.max_lag = max_lag
        self.clock = clock
        self.sleep = sleep
        self.min_idle = min_idle
        self.idle_sleeps = 0
        """Sleeps made to keep ``min_idle`` (the loop was behind)."""
        self._t0 = clock()
        self._n = 0
        self._window = self._t0
        self._slept = 0.0

    def start(self) -> None:
        """The next deadline is one period from now."""
        self._t0 = self.clock()
        self._n = 0
        self._window, self._slept = self._t0, 0.0

    def wait(self) -> bool:
        """Wait for the next deadline; True if the backlog was dropped instead."""
        self._n += 1
        deadline = self._t0 + self._n * self.period
        now = self.clock()
        if now - deadline > self.max_lag:
            self._t0 = now - self._n * self.period
            return True
        remaining = deadline - now - self.spin
        if remaining > 0:
            (self.sleep or time.sleep)(remaining)
            self._slept += remaining
        if self.min_idle > 0:
            self._keep_idle_share()
        while self.clock() < deadline:
            pass
        return False

    def skip(self, periods: int) -> None:
        """The next deadline ``periods`` later than it would be (ticks run ahead)."""
        self._n += periods

    def _keep_idle_share(self) -> None:
        now = self.clock()
        if now - self._window < IDLE_WINDOW:
            return
        # (the sleep itself is wall time too: share = slept / (window + owed))
        owed = (self.min_idle * (now - self._window) - self._slept) / (1.0 - self.min_idle)
        if owed > 0:
            (self.sleep or time.sleep)(owed)
            self.idle_sleeps += 1
            now = self.clock()
        self._window, self._slept = now, 0.0


class LoopRunner:
    """Ticks ``sim`` in this thread; see the module docstring. The one tick loop of both
    runners: :class:`~davinci_sim.sim.handle.ThreadedSimulation` runs it in a thread,
    :class:`~davinci_sim.sim.runtime.process.ProcessSimulation` in its loop process.

    Args:
        sim: the simulation.
        real_time: pace at one tick per ``sim.dt`` of wall time; else as fast as possible.
        speed: with ``real_time``, simulated seconds per wall second (a replay faster or
            slower than real time; 1: real time).
        recorder: where the period statistics go (default: a private recorder).
        spin, max_lag: see :class:`Pacer`.
        clock, sleep: the wall clock (s) and how to wait (tests pass a virtual clock).
        min_idle: see :class:`Pacer` (a real-time loop's :func:`realtime_idle_share`).
        chunk: the most ticks one pass of the loop runs (``Simulation.advance``: the
            simulation's compiled calls where it has them); between passes the loop serves
            its calls and publishes, so a call waits at most ``chunk`` ticks. 1: every tick
            on its own (``Simulation.tick``).
    """

    def __init__(
        self,
        sim: Simulation,
        *,
        real_time: bool = True,
        speed: float = 1.0,
        recorder: PeriodRecorder | None = None,
        spin: float = DEFAULT_SPIN,
        max_lag: float = DEFAULT_MAX_LAG,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], None] | None = None,
        min_idle: float = 0.0,
        chunk: int = 1,
    ) -> None:
        if not (isinstance(chunk, int) and chunk >= 1):
            raise ValueError(f"chunk must be a whole number of ticks >= 1, got {chunk!r}")
        self.sim = sim
        self.chunk = chunk
        self.real_time = real_time
        self.clock = clock
        self.recorder = recorder or PeriodRecorder(sim.dt, real_time=real_time)
        if not (math.isfinite(speed) and speed > 0):
            raise ValueError(f"speed must be > 0, got {speed!r}")
        self.pacer = (
            Pacer(
                sim.dt / speed,
                spin=spin,
                max_lag=max_lag,
                clock=clock,
                sleep=sleep,
                min_idle=min_idle,
            )  # fmt: skip
            if real_time
            else None
        )
        self._scheduled: list[tuple[int, int, Callable[[], object]]] = []
        self._seq = itertools.count()

    def call_at(self, tick: int, fn: Callable, *args, **kwargs) -> None:
        """Run ``fn(*args, **kwargs)`` right before the simulation's tick number ``tick``
        (when ``sim.tick_count == tick``), in either mode. Call it from the loop's thread
        (between ticks) or before :meth:`run`.

        Raises:
            ValueError: if that tick has already run.
        """
        if tick < self.sim.tick_count:
            raise ValueError(f"tick {tick} has already run (now at tick {self.sim.tick_count})")
        heapq.heappush(self._scheduled, (int(tick), next(self._seq), lambda: fn(*args, **kwargs)))

    def pending(self) -> int:
        """Scheduled calls not run yet."""
        return len(self._scheduled)

    def run(
        self,
        *,
        ticks: int | None = None,
        until: Callable[[], bool] | None = None,
        before_tick: Callable[[], None] | None = None,
        after_tick: Callable[[], None] | None = None,
        every: int = 1,
    ) -> PeriodStatistics:
        """Tick ``ticks`` times (or until ``until()``; at least one must be given).

        ``before_tick``/``after_tick`` run around every pass of the loop (one tick, or up to
        :attr:`chunk`), inside the measured compute time (the runners serve their calls and
        publish there); ``before_tick`` returns False when it served nothing (then the
        simulation's chunker may keep its plan). A pass ends at every multiple of ``every``
        ticks (a runner's snapshot period) and before each tick a call is scheduled for; the
        period statistics count each of its ticks, with its share of the pass's period and
        compute time. Between the period's ends the chunker's calls leave their write-back
        into the components until the pass that ends the period, or until a call needs it
        (``Simulation.advance(defer=True)``; a call served through ``execute`` or scheduled
        here flushes it first): ``after_tick`` and ``until`` see the components as the last
        period's end left them, but the physics, the arms' joints and the tick count as
        they are.
        """
        if ticks is None and until is None:
            raise ValueError("run needs ticks or until")
        clock = self.clock
        pacer = self.pacer
        sim = self.sim
        scheduled = self._scheduled
        if pacer is not None:
            pacer.start()
        n = 0
        while (ticks is None or n < ticks) and (until is None or not until()):
            if pacer is not None and pacer.wait():
                self.recorder.resynced()
            start = clock()
            served = True
            if before_tick is not None:
                served = before_tick() is not False  # (may schedule calls for this very tick)
            while scheduled and scheduled[0][0] <= sim.tick_count:
                sim.flush()  # (what the call reads, written back)
                heapq.heappop(scheduled)[2]()
                served = True
            k = 1
            if self.chunk > 1 and sim.chunker is not None:
                k = min(self.chunk, every - sim.tick_count % every)
                if scheduled:
                    k = min(k, max(1, scheduled[0][0] - sim.tick_count))
                if ticks is not None:
                    k = min(k, ticks - n)
            if k == 1:
                sim.tick()
            else:
                # The write-back of the chunker's calls waits for the pass that ends the
                # period (before_tick's calls flush it first; after_tick publishes then).
                sim.advance(k, unchanged=not served, defer=(sim.tick_count + k) % every != 0)
                if pacer is not None:
                    pacer.skip(k - 1)  # (the next pass starts at the next tick's time)
            if after_tick is not None:
                after_tick()
            self.recorder.tick(start, clock(), k)  # (the recorder may be replaced meanwhile)
            n += k
        sim.flush()
        return self.recorder.statistics()
