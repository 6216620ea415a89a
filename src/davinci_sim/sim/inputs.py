"""The log of a running simulation's inputs: every call made through its handle, with the
tick it ran before.

Everything that changes a running simulation from outside goes through one function,
:func:`davinci_sim.sim.handle.execute` (both runners serve ``SimHandle.call`` and
``call_at`` with it): a ROS client's ``servo_cp``, the web console's hand velocity, a
pedal, a condition change. The rest of a tick is a function of the state and the seed. So
the calls and the ticks they ran before are what a recording needs to run the session
again through the physics (``records/replay.py``): the same calls before the same ticks of
a simulation built from the same description give the same states, bit for bit.

:class:`InputLog` is the component that keeps them: ``execute`` tells it each call (see
:func:`log_call`); it emits each as the event ``call`` on its channels (payload: one
:data:`Entry`), which the handle forwards to subscribers as every component's events, and
keeps them in a buffer until the first :meth:`InputLog.drain`, so a recorder that subscribes
after the loop started loses none (entries carry a sequence number to drop the ones seen
twice). Calls addressed to the log itself are not logged.
"""

from __future__ import annotations

from collections import deque
from typing import Any

from davinci_sim.sim.channels import Channels

#: The component's name (``SimHandle.call("inputs", "drain")``).
INPUT_LOG = "inputs"

Entry = tuple[int, int, str, str, tuple, dict]
"""One logged call: (sequence number from 1, tick it ran before, target, method, args,
kwargs)."""


class InputLog:
    """The calls a simulation's handle ran; see the module docstring.

    Args:
        sim: the simulation (its model signature and sizes are told by :meth:`info`).
        maxlen: calls kept until the first :meth:`drain` (older ones are dropped and
            counted in :attr:`dropped`).
    """

    name = INPUT_LOG

    def __init__(self, sim: Any, maxlen: int = 100_000) -> None:
        self.channels = Channels(INPUT_LOG)
        self._buffer: deque[Entry] | None = deque(maxlen=maxlen)
        self._seq = 0
        self.dropped = 0
        """Calls dropped from the buffer before the first drain."""
        self._info = {
            "signature": sim.signature,
            "nq": int(sim.model.nq),
            "dt": float(sim.dt),
            "arms": list(sim.arms),
        }

    def record(self, tick: int, target: str, method: str, args: tuple, kwargs: dict) -> None:
        """Log one call about to run before ``tick`` (called by ``execute``)."""
        if target == INPUT_LOG:
            return
        self._seq += 1
        entry: Entry = (self._seq, int(tick), target, method, tuple(args), dict(kwargs))
        if self._buffer is not None:
            if len(self._buffer) == self._buffer.maxlen:
                self.dropped += 1
            self._buffer.append(entry)
        self.channels.emit("call", entry)

    def drain(self) -> list[Entry]:
        """The calls logged so far that no drain returned, oldest first; after the first
        drain the log keeps nothing more (its events carry the calls)."""
        entries = list(self._buffer or ())
        self._buffer = None
        return entries

    def info(self) -> dict:
        """The simulation's model signature, ``nq``, ``dt`` (s) and arm names."""
        return dict(self._info)

    # ------------------------------------------------------------ component
    def pre_step(self, t: float) -> None:
        pass

    def snapshot(self) -> int:
        """The number of calls logged so far."""
        return self._seq

    def get_state(self) -> None:
        """No simulation state: the log records, it changes nothing."""

    def set_state(self, state: None) -> None:
        pass


def log_call(sim: Any, target: str, method: str, args: tuple, kwargs: dict) -> None:
    """Tell ``sim``'s :class:`InputLog`, if it has one, of a call about to run."""
    log = sim.components.get(INPUT_LOG)
    if isinstance(log, InputLog):
        log.record(sim.tick_count, target, method, args, kwargs)
