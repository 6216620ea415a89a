"""A training session over the bridge: ``/task/state``, ``/task/results``, ``/task/reset``.

When the simulation has a :class:`~davinci_sim.tasks.session.TaskSession` (component
``task``, ``davinci-sim serve --task``), a trainer's dashboard or a script follows it:

* ``/task/state`` (``std_msgs/String``, latched): the session's state as JSON (task,
  condition, phase, repetition, completed repetitions, distance to the path in m, the last
  repetition's row), published when it changes, checked at ``rate``;
* ``/task/results`` (``std_msgs/String``, latched): each finished repetition's row as JSON
  (task, condition, repetition, then the task's declared metrics in SI units:
  :func:`davinci_sim.tasks.session.session_columns`, the kind's ``METRICS``);
* ``/task/reset`` (``std_msgs/Empty``, subscribed): abandon the current repetition.

Not dVRK topics (the dVRK has no tasks); JSON in strings keeps them readable from any client
without custom message types. NaN (no value yet) is sent as ``null``.
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import logging
from typing import TYPE_CHECKING

from davinci_sim.bridge.rosbridge.codec import finite_json
from davinci_sim.bridge.rosbridge.publisher import PeriodicTask

if TYPE_CHECKING:
    from davinci_sim.bridge.rosbridge.core import Bridge
    from davinci_sim.bridge.rosbridge.session import Session
    from davinci_sim.sim.handle import SimHandle

_log = logging.getLogger("davinci_sim.bridge")

NODE = "/davinci_sim/task"


class TaskNode:
    """Serves the ``task`` component of ``handle``'s simulation, if it has one.

    Args:
        handle: the running simulation.
        rate: how often the session's state is checked for changes, Hz.
        component: the session's component name.
    """

    def __init__(self, handle: SimHandle, *, rate: float = 10.0, component: str = "task"):
        if not 0 < rate <= 1000:
            raise ValueError(f"rate must be in ]0, 1000] Hz, got {rate!r}")
        self.handle = handle
        self.rate = rate
        self.component = component
        self._task: PeriodicTask | None = None
        self._last_state: str | None = None
        self._completed = 0

    def _state(self):
        state = (self.handle.snapshot().extras or {}).get(self.component)
        return state if hasattr(state, "phase") and hasattr(state, "completed") else None

    def attach(self, bridge: Bridge) -> None:
        self.bridge = bridge
        self.loop = asyncio.get_running_loop()
        if self._state() is None:
            _log.info("no task session: no /task topics")
            return
        self._state_topic = bridge.advertise("/task/state", "std_msgs/String", node=NODE,
                                             latch=True)  # fmt: skip
        self._results_topic = bridge.advertise("/task/results", "std_msgs/String", node=NODE,
                                               latch=True)  # fmt: skip
        bridge.listen("/task/reset", "std_msgs/Empty", self._on_reset, node=NODE)
        self._tick()
        self._task = PeriodicTask(1.0 / self.rate, self._tick)
        self._task.start()

    async def detach(self) -> None:
        if self._task is not None:
            await self._task.stop()
        self.bridge.remove_node(NODE)

    def _tick(self) -> None:
        state = self._state()
        if state is None:
            return
        text = json.dumps(finite_json(dataclasses.asdict(state)))
        if text != self._last_state:
            self._last_state = text
            self.bridge.publish(self._state_topic, {"data": text})
        if state.completed > self._completed and state.last:
            self._completed = state.completed
            self.bridge.publish(self._results_topic, {"data": json.dumps(finite_json(state.last))})

    def _on_reset(self, msg: dict, session: Session | None) -> None:
        future = self.handle.call(self.component, "reset")

        def done(f) -> None:
            if f.exception() is not None:
                text = f"/task/reset: {f.exception()}"
                if session is not None:
                    session.report("error", text)
                else:
                    _log.warning("%s", text)

        future.add_done_callback(lambda f: self.loop.call_soon_threadsafe(done, f))
